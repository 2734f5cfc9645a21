"""One VTK XML unstructured grid (``.vtu``) with its arrays inline in base64.

The layout is meshio's ``vtu`` writer's (binary, version 0.1, ``UInt32`` block headers,
the ``vtkZLibDataCompressor`` or ``vtkLZMADataCompressor`` in blocks of 32 KiB), byte for
byte but for its comment line (``tests/test_vtu_writer.py`` compares the two), written
here in one pass over the arrays: importing meshio, which loads every format it knows and
rich, took 60-100 ms of CPU time in each run that wrote a frame (docs/performance.md,
"Start-up"). The cells are of one kind: ``vertex``, ``triangle``, ``quad``, ``tetra`` or
``tetra10`` (VTK's node order is meshio's for each).
"""

from __future__ import annotations

import base64
import sys
from pathlib import Path

import numpy as np

#: VTK cell types (vtkCellType.h) of the cells a run writes.
VTK_TYPES = {"vertex": 1, "triangle": 5, "quad": 9, "tetra": 10, "tetra10": 24}

_VTU_TYPES = {np.dtype(t): name for t, name in [
    (np.float32, "Float32"), (np.float64, "Float64"), (np.int8, "Int8"),
    (np.int16, "Int16"), (np.int32, "Int32"), (np.int64, "Int64"), (np.uint8, "UInt8"),
    (np.uint16, "UInt16"), (np.uint32, "UInt32"), (np.uint64, "UInt64")]}
_COMPRESSORS = {"zlib": "vtkZLibDataCompressor", "lzma": "vtkLZMADataCompressor"}
_BLOCK = 32768  # bytes of one compressed block before compression


def write_vtu(path: str | Path, points: np.ndarray, cells: tuple[str, np.ndarray],
              point_data: dict[str, np.ndarray], cell_data: dict[str, np.ndarray],
              compression: str | None = None) -> None:
    """Write ``path``: ``points (n, 3)``, ``cells = (kind, (m, k))`` (kind in
    :data:`VTK_TYPES`), point arrays ``(n,)`` or ``(n, c)``, cell arrays ``(m,)`` or
    ``(m, c)``; ``compression`` ``None``, ``"zlib"`` or ``"lzma"``."""
    kind, connectivity = cells
    connectivity = np.asarray(connectivity)
    points = np.asarray(points)
    m = connectivity.shape[0]
    for name, values in point_data.items():
        if len(values) != len(points):
            raise ValueError(f"point array {name!r} has {len(values)} rows for "
                             f"{len(points)} points")
    for name, values in cell_data.items():
        if len(values) != m:
            raise ValueError(f"cell array {name!r} has {len(values)} rows for {m} cells")
    order = "LittleEndian" if sys.byteorder == "little" else "BigEndian"
    head = f'<VTKFile type="UnstructuredGrid" version="0.1" byte_order="{order}"'
    if compression:
        head += f' compressor="{_COMPRESSORS[compression]}"'
    parts = ['<?xml version="1.0"?>\n', head + ">\n",
             "<!--This file was created by fem_frac-->\n", "<UnstructuredGrid>\n",
             f'<Piece NumberOfPoints="{len(points)}" NumberOfCells="{m}">\n', "<Points>\n"]
    parts += _array("Points", points, compression)
    parts.append("</Points>\n<Cells>\n")
    offsets = connectivity.shape[1] * np.arange(1, m + 1, dtype=connectivity.dtype)
    parts += _array("connectivity", connectivity.ravel(), compression)
    parts += _array("offsets", offsets, compression)
    parts += _array("types", np.full(m, VTK_TYPES[kind]), compression)
    parts.append("</Cells>\n")
    for tag, data in (("PointData", point_data), ("CellData", cell_data)):
        if data:
            parts.append(f"<{tag}>\n")
            for name, values in data.items():
                parts += _array(name, np.asarray(values), compression)
            parts.append(f"</{tag}>\n")
    parts.append("</Piece>\n</UnstructuredGrid>\n</VTKFile>\n")
    with open(path, "wb") as f:
        f.writelines(p if isinstance(p, bytes) else p.encode() for p in parts)


def _array(name: str, data: np.ndarray, compression: str | None) -> list[str | bytes]:
    """The ``DataArray`` element of ``data`` (in native byte order), in parts."""
    data = data.astype(data.dtype.newbyteorder("="), copy=False)
    attrs = f'type="{_VTU_TYPES[data.dtype]}" Name="{name}"'
    if data.ndim == 2:
        attrs += f' NumberOfComponents="{data.shape[1]}"'
    raw = data.tobytes()
    if compression:
        text = _compressed(raw, compression)
    else:
        text = base64.b64encode(np.uint32(len(raw)).tobytes() + raw)
    return [f'<DataArray {attrs} format="binary">\n', text, "\n</DataArray>\n"]


def _compressed(raw: bytes, compression: str) -> bytes:
    """VTK's compressed layout: a header (blocks, block size, last block's size, each
    block's compressed size) then the blocks, each part base64-encoded on its own."""
    if compression == "zlib":
        import zlib as codec
    else:
        import lzma as codec
    n = -(-len(raw) // _BLOCK)
    blocks = [codec.compress(raw[i:i + _BLOCK]) for i in range(0, len(raw), _BLOCK)]
    header = np.array([n, _BLOCK, len(raw) - (n - 1) * _BLOCK] + [len(b) for b in blocks],
                      dtype=np.uint32)
    return base64.b64encode(header.tobytes()) + base64.b64encode(b"".join(blocks))
