"""A VTK time series: one ``.vtu`` per output step and a ``.pvd`` index with real times.

Every file is written under a scratch name and renamed into place, so an interrupted run
leaves a valid, viewable series (the ``.pvd`` lists only complete frames) and no write goes
through a symbolic link planted at a frame's name. Each name is recorded in the directory's
manifest (:class:`~fem_frac.writers.directory.Manifest`) before the file is created. Points
hold reference coordinates; all motion goes into the point field ``displacement``
(ParaView: Warp By Vector).

:func:`series_writer` picks the writer of ``output.format``: this one (``vtu``, the default)
or one ``.vtkhdf`` file per series (:mod:`~fem_frac.writers.vtkhdf`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .directory import Manifest, create_plain
from .vtu import write_vtu

# XML's escapes of an attribute value, as xml.sax.saxutils.quoteattr makes them (whose
# module imports urllib.request, and with it http, ssl and email: ~15 ms of every run)
_ESCAPES = str.maketrans({"&": "&amp;", "<": "&lt;", ">": "&gt;", "\n": "&#10;",
                          "\r": "&#13;", "\t": "&#9;"})


def quoteattr(value: str) -> str:
    """``value`` escaped and quoted for an XML attribute, to the character as
    :func:`xml.sax.saxutils.quoteattr` does it (double quotes unless the value holds one
    and no single quote)."""
    value = value.translate(_ESCAPES)
    if '"' not in value:
        return f'"{value}"'
    if "'" not in value:
        return f"'{value}'"
    return '"' + value.replace('"', "&quot;") + '"'


@dataclass
class SeriesWriter:
    """``<name>_%06d.vtu`` and ``<name>.pvd`` in ``directory``; ``manifest`` (default: the
    directory's) records every file written; ``compression`` of the arrays (none by
    default: zlib takes about 6 times as long to write for half the size, docs/performance.md)."""

    directory: Path
    name: str
    entries: list[tuple[float, str]] = field(default_factory=list)
    manifest: Manifest | None = None
    compression: str = "none"  # of the data arrays: "none", "zlib" or "lzma"

    def __post_init__(self):
        self.directory = Path(self.directory)
        if self.manifest is None:
            self.manifest = Manifest(self.directory)

    @property
    def pvd_path(self) -> Path:
        return self.directory / f"{self.name}.pvd"

    @property
    def path(self) -> Path:
        """The file to open in ParaView: the ``.pvd``."""
        return self.pvd_path

    def write(
        self,
        time: float,
        points: np.ndarray,
        cells: tuple[str, np.ndarray],
        point_data: dict[str, np.ndarray],
        cell_data: dict[str, np.ndarray],
    ) -> Path:
        """Write one step. ``cells`` is ``("tetra" | "tetra10", (n_cells, k))``; cell arrays
        are ``(n_cells,)`` or ``(n_cells, m)``."""
        filename = f"{self.name}_{len(self.entries):06d}.vtu"
        scratch = f"{self.name}.vtu.tmp"
        path = self.manifest.add(scratch, filename)
        create_plain(self.directory / scratch)
        write_vtu(self.directory / scratch, points, cells, point_data, cell_data,
                  compression=None if self.compression == "none" else self.compression)
        os.replace(self.directory / scratch, path)
        self.entries.append((float(time), filename))
        self._write_index()
        return path

    def _write_index(self) -> None:
        lines = [
            '<?xml version="1.0"?>',
            '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
            "  <Collection>",
        ]
        for time, filename in self.entries:
            attrs = f'timestep="{time:.17g}" group="" part="0" file={quoteattr(filename)}'
            lines.append(f"    <DataSet {attrs}/>")
        lines += ["  </Collection>", "</VTKFile>", ""]
        tmp = self.pvd_path.with_name(f"{self.name}.pvd.tmp")
        self.manifest.add(tmp.name, self.pvd_path.name)
        create_plain(tmp)
        tmp.write_text("\n".join(lines))
        os.replace(tmp, self.pvd_path)


#: ``output.format``: the file suffix of each series' index (what ParaView opens).
FORMATS = {"vtu": ".pvd", "vtkhdf": ".vtkhdf"}


def series_writer(directory: Path, name: str, manifest: Manifest | None = None,
                  compression: str = "none", format: str = "vtu"):
    """The writer of a series in ``format`` (``output.format``): a :class:`SeriesWriter`
    (``vtu``: ``.pvd`` + ``.vtu`` files) or a
    :class:`~fem_frac.writers.vtkhdf.VtkhdfSeriesWriter` (``vtkhdf``: one ``.vtkhdf``);
    both ``write`` a step and keep ``entries`` and ``path``."""
    if format == "vtkhdf":
        from .vtkhdf import VtkhdfSeriesWriter

        return VtkhdfSeriesWriter(directory, name, manifest=manifest, compression=compression)
    if format != "vtu":
        raise ValueError(f"unknown output format {format!r}")
    return SeriesWriter(directory, name, manifest=manifest, compression=compression)
