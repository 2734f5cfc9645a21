"""A VTK time series in one file: ``<name>.vtkhdf``, a VTKHDF 2.0 ``UnstructuredGrid`` with
a ``Steps`` group (``output.format: vtkhdf``; the default is ``.pvd`` + ``.vtu``,
:mod:`~fem_frac.writers.series`).

Layout (the VTKHDF file format, *temporal data*): under ``/VTKHDF`` the resizable datasets
``NumberOfPoints``, ``NumberOfCells``, ``NumberOfConnectivityIds`` (one row per part),
``Points``, ``Types``, ``Connectivity``, ``Offsets`` (each part's ``n_cells + 1``
offsets, from 0), ``PointData/<name>``, ``CellData/<name>``; under ``/VTKHDF/Steps`` one row
per step: ``Values`` (the time), ``PartOffsets``, ``NumberOfParts`` (1), ``PointOffsets``,
``CellOffsets``, ``ConnectivityIdOffsets``, ``PointDataOffsets/<name>``,
``CellDataOffsets/<name>``, and the attribute ``NSteps``.

Each step is one part, appended to the end of every dataset, except what equals the step
before: the same points and cells (the points are reference coordinates, so a mesh keeps
them until a crack or a piece leaving changes it) point at the previous step's part, and an
array equal to the previous step's (the fixed obstacles' fields) at its rows. A step whose
topology changed stores its own points and cells, so a crack (duplicated vertices, new
cells, other cell types) is one more part.

The file is opened for each step and closed after it: between steps it is a complete,
closed HDF5 file that VTK reads, with every step written so far (``NSteps`` and the step
tables are written last, so a step is listed only once its data are in). A run killed
while a step is being appended (a few milliseconds of the step) may leave the file
unreadable: HDF5 has no journal. The file is entered in the manifest before it is created,
never written through a symbolic link (:func:`~fem_frac.writers.directory.create_plain`),
and opened without HDF5's file locks, so a viewer holding it open cannot stop the run.

``compression``: ``none``, or ``zlib`` as HDF5's gzip filter at level :data:`GZIP_LEVEL`
with the shuffle filter (docs/performance.md, *Output format*); HDF5 has no lzma filter.
h5py is optional (``pip install h5py``): :func:`check_format` refuses the case before any
work when it is missing.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import CaseError, FemFracError
from .directory import Manifest, create_plain
from .vtu import VTK_TYPES

#: The VTKHDF version written: temporal unstructured grids are 2.0.
VERSION = (2, 0)
#: gzip level of ``compression: zlib`` (docs/performance.md, *Output format*).
GZIP_LEVEL = 1
# a dataset's chunk holds at least this many rows and at most about this many bytes
_MIN_ROWS, _CHUNK_BYTES = 64, 1 << 20
_GEOMETRY = ("Points", "Types", "Connectivity", "Offsets")
_STEP_TABLES = ("Values", "PartOffsets", "NumberOfParts", "PointOffsets", "CellOffsets",
                "ConnectivityIdOffsets")


def check_format(output, key: tuple = ("output",)) -> None:
    """Raise :class:`CaseError` at ``output.format`` when it asks for vtkhdf and h5py is
    missing, and at ``output.compression`` for a codec HDF5 lacks (lzma)."""
    if getattr(output, "format", "vtu") != "vtkhdf":
        return
    if output.compression == "lzma":
        raise CaseError(key + ("compression",), "lzma is not available with format vtkhdf "
                        "(HDF5 has no lzma filter): use zlib (gzip) or none")
    try:
        import h5py  # noqa: F401
    except ImportError:
        raise CaseError(key + ("format",), "vtkhdf needs h5py, which is not installed: "
                        "pip install h5py (or pip install 'fem-frac[vtkhdf]'), or use "
                        "format vtu") from None


@dataclass
class VtkhdfSeriesWriter:
    """``<name>.vtkhdf`` in ``directory``: the interface of
    :class:`~fem_frac.writers.series.SeriesWriter` (``write``, ``entries``, ``path``);
    ``manifest`` (default: the directory's) records the file."""

    directory: Path
    name: str
    entries: list[tuple[float, str]] = field(default_factory=list)
    manifest: Manifest | None = None
    compression: str = "none"  # "none" or "zlib"

    def __post_init__(self):
        self.directory = Path(self.directory)
        if self.manifest is None:
            self.manifest = Manifest(self.directory)
        if self.compression not in ("none", "zlib"):
            raise FemFracError(f"{self.path}: compression {self.compression!r} is not "
                               "available in VTKHDF (none or zlib)")
        self._last: tuple | None = None  # the previous step's geometry and arrays
        self._arrays: dict | None = None  # (group, name) -> (dtype, row shape)

    @property
    def path(self) -> Path:
        return self.directory / f"{self.name}.vtkhdf"

    def write(self, time: float, points: np.ndarray, cells: tuple[str, np.ndarray],
              point_data: dict[str, np.ndarray], cell_data: dict[str, np.ndarray]) -> Path:
        """Append one step (the arguments of ``SeriesWriter.write``); the file is closed
        when it returns."""
        import h5py

        kind, conn = cells
        if kind not in VTK_TYPES:
            raise FemFracError(f"{self.path}: cells of type {kind!r} have no VTK type here")
        points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        conn = np.ascontiguousarray(conn, dtype=np.int64)
        conn = conn.reshape(len(conn), -1)
        arrays = {("PointData", k): np.asarray(v) for k, v in point_data.items()}
        arrays.update({("CellData", k): np.asarray(v) for k, v in cell_data.items()})
        first = not self.entries
        if first:
            self.manifest.add(self.path.name)
            create_plain(self.path)
        self._check_arrays(arrays)
        with h5py.File(self.path, "w" if first else "r+", locking=False) as f:
            root = f["VTKHDF"] if not first else self._create(f, points, conn, arrays)
            self._append(root, float(time), kind, points, conn, arrays)
        self.entries.append((float(time), f"{self.path.name}#{len(self.entries)}"))
        return self.path

    # --- the file's structure -----------------------------------------------------------

    def _create(self, f, points, conn, arrays):
        root = f.create_group("VTKHDF")
        root.attrs["Version"] = np.array(VERSION, dtype=np.int64)
        root.attrs.create("Type", np.bytes_("UnstructuredGrid"))
        for name in ("NumberOfPoints", "NumberOfCells", "NumberOfConnectivityIds"):
            self._dataset(root, name, np.int64, (), 1, False)
        self._dataset(root, "Points", np.float64, (3,), len(points))
        self._dataset(root, "Types", np.uint8, (), len(conn))
        self._dataset(root, "Connectivity", np.int64, (), conn.size)
        self._dataset(root, "Offsets", np.int64, (), len(conn) + 1)
        steps = root.create_group("Steps")
        steps.attrs["NSteps"] = np.int64(0)
        for name in _STEP_TABLES:
            self._dataset(steps, name, np.float64 if name == "Values" else np.int64, (), 1,
                          False)
        for (group, name), values in arrays.items():
            self._dataset(root.require_group(group), name, values.dtype, values.shape[1:],
                          len(values))
            self._dataset(steps.require_group(f"{group}Offsets"), name, np.int64, (), 1,
                          False)
        return root

    def _dataset(self, group, name, dtype, row, rows, compress=True):
        """A resizable dataset of 0 rows, chunked to about a step's rows (at least
        ``_MIN_ROWS``, at most about ``_CHUNK_BYTES``)."""
        row_bytes = max(1, int(np.prod(row, dtype=np.int64)) * np.dtype(dtype).itemsize)
        chunk = max(1, min(max(int(rows), _MIN_ROWS), _CHUNK_BYTES // row_bytes))
        options = {}
        if compress and self.compression == "zlib":
            options = {"compression": "gzip", "compression_opts": GZIP_LEVEL, "shuffle": True}
        return group.create_dataset(name, shape=(0, *row), maxshape=(None, *row), dtype=dtype,
                                    chunks=(chunk, *row), **options)

    def _check_arrays(self, arrays: dict) -> None:
        """Every step holds the arrays of the first, with the same types and components
        (the step tables index every array at every step)."""
        found = {key: (v.dtype, v.shape[1:]) for key, v in arrays.items()}
        if self._arrays is None:
            self._arrays = found
        elif found != self._arrays:
            changed = sorted(set(found.items()) ^ set(self._arrays.items()))
            raise FemFracError(f"{self.path}: step {len(self.entries)} changes the array "
                               f"{changed[0][0][1]!r}; a VTKHDF series keeps the arrays of "
                               "its first step (write format vtu)")

    # --- one step --------------------------------------------------------------------------

    def _append(self, root, time, kind, points, conn, arrays) -> None:
        steps = root["Steps"]
        last = self._last
        same = (last is not None and last[0] == kind and _equal(last[1], points)
                and _equal(last[2], conn))
        if same:
            row = {n: int(steps[n][-1]) for n in _STEP_TABLES[1:]}
        else:
            row = {"PartOffsets": len(root["NumberOfPoints"]), "NumberOfParts": 1,
                   "PointOffsets": len(root["Points"]), "CellOffsets": len(root["Types"]),
                   "ConnectivityIdOffsets": len(root["Connectivity"])}
            n, k = conn.shape
            _extend(root["NumberOfPoints"], np.array([len(points)]))
            _extend(root["NumberOfCells"], np.array([n]))
            _extend(root["NumberOfConnectivityIds"], np.array([conn.size]))
            _extend(root["Points"], points)
            _extend(root["Types"], np.full(n, VTK_TYPES[kind], dtype=np.uint8))
            _extend(root["Connectivity"], conn.ravel())
            _extend(root["Offsets"], np.arange(0, n * k + 1, max(k, 1), dtype=np.int64)
                    if k else np.zeros(n + 1, dtype=np.int64))
        kept = {}
        for key, values in arrays.items():
            group, name = key
            table = steps[f"{group}Offsets"][name]
            if last is not None and key in last[3] and _equal(last[3][key], values):
                offset = int(table[-1])
            else:
                offset = len(root[group][name])
                _extend(root[group][name], values)
            _extend(table, np.array([offset]))
            kept[key] = values.copy()
        _extend(steps["Values"], np.array([time]))
        for name, value in row.items():
            _extend(steps[name], np.array([value]))
        steps.attrs["NSteps"] = np.int64(len(steps["Values"]))
        self._last = (kind, points.copy(), conn.copy(), kept)


def _extend(dataset, values: np.ndarray) -> None:
    """Append ``values`` (rows) to the resizable ``dataset``."""
    start = dataset.shape[0]
    dataset.resize(start + len(values), axis=0)
    if len(values):
        dataset[start:] = values


def _equal(a: np.ndarray, b: np.ndarray) -> bool:
    """The same shape and values (NaN equal to NaN: an unchanged array that holds NaN)."""
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    if a.dtype.kind == "f":
        return bool(np.array_equal(a, b, equal_nan=True))
    return bool(np.array_equal(a, b))


def read_step(path: Path, step: int = -1) -> dict:
    """One step of a ``.vtkhdf`` this module wrote, with h5py: ``time``, ``points``
    ``(n, 3)``, ``types`` ``(m,)``, ``connectivity`` and ``offsets`` (the part's),
    ``point_data`` and ``cell_data`` (dicts of arrays). ``step`` counts from the end when
    negative."""
    import h5py

    with h5py.File(path, "r", locking=False) as f:
        root = f["VTKHDF"]
        steps = root["Steps"]
        count = int(steps.attrs["NSteps"])
        k = step + count if step < 0 else step
        if not 0 <= k < count:
            raise IndexError(f"{path}: no step {step} (it holds {count})")
        part = int(steps["PartOffsets"][k])
        n_points = int(root["NumberOfPoints"][part])
        n_cells = int(root["NumberOfCells"][part])
        n_ids = int(root["NumberOfConnectivityIds"][part])
        p0, c0 = int(steps["PointOffsets"][k]), int(steps["CellOffsets"][k])
        i0 = int(steps["ConnectivityIdOffsets"][k])
        out = {"time": float(steps["Values"][k]),
               "points": root["Points"][p0:p0 + n_points],
               "types": root["Types"][c0:c0 + n_cells],
               "connectivity": root["Connectivity"][i0:i0 + n_ids],
               "offsets": root["Offsets"][c0 + part:c0 + part + n_cells + 1]}
        for group, count_ in (("PointData", n_points), ("CellData", n_cells)):
            data = {}
            for name in root[group] if group in root else ():
                at = int(steps[f"{group}Offsets"][name][k])
                data[name] = root[group][name][at:at + count_]
            out["point_data" if group == "PointData" else "cell_data"] = data
    return out
