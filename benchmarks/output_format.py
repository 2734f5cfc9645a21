"""The same output steps written as a .pvd + .vtu series and as one .vtkhdf (``output.format``,
docs/performance.md, "Output format"): the time to write the series, its size on disk, and
the time VTK takes to read every step back.

    python benchmarks/output_format.py [--cells N] [--steps K] [--repeat R]

The frame is the one of benchmarks/output_compression.py (N = 26: 105,456 tets, a run's
fields); each step scales the fields, so no array repeats. Two kinds of series: ``same
mesh`` (the reference points and cells of every step equal, as between cracks: a .vtkhdf
stores them once) and ``new mesh`` (every step a new topology, one point more: a .vtkhdf
stores each step whole). Writes go through fem_frac's writers (SeriesWriter,
VtkhdfSeriesWriter); reads through VTK's readers (vtkXMLUnstructuredGridReader of each .vtu
the .pvd lists, vtkHDFReader stepped with SetStep). Times are the median and the least and
greatest of ``--repeat`` repeats (wall clock), each in a new directory.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
from output_compression import frame

from fem_frac.writers import vtkhdf
from fem_frac.writers.series import SeriesWriter, series_writer


def steps(data, count: int, new_mesh: bool):
    """``count`` steps of ``data``: fields scaled by the step, the mesh the same or with
    one point more each step."""
    points, (kind, cells), point_data, cell_data = data
    for k in range(count):
        s = 1.0 + 0.1 * k
        p = np.vstack([points, points[:k]]) if new_mesh else points
        pd = {n: np.vstack([v, v[:k]]) * s if new_mesh else v * s
              for n, v in point_data.items()}
        cd = {n: v * s if v.dtype.kind == "f" else v for n, v in cell_data.items()}
        yield 0.01 * k, p, (kind, cells), pd, cd


def read_all(path: Path) -> int:
    """Read every step with VTK; the number of cells read."""
    import vtk

    total = 0
    if path.suffix == ".pvd":
        for ds in ElementTree.parse(path).getroot().iter("DataSet"):
            reader = vtk.vtkXMLUnstructuredGridReader()
            reader.SetFileName(str(path.parent / ds.get("file")))
            reader.Update()
            total += reader.GetOutput().GetNumberOfCells()
        return total
    reader = vtk.vtkHDFReader()
    reader.SetFileName(str(path))
    reader.UpdateInformation()
    for k in range(reader.GetNumberOfSteps()):
        reader.SetStep(k)
        reader.Update()
        total += reader.GetOutput().GetNumberOfCells()
    return total


def measure(data, fmt: str, compression: str, count: int, new_mesh: bool, repeat: int):
    writes, reads, size = [], [], 0.0
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            writer = series_writer(Path(tmp), "f", compression=compression, format=fmt)
            start = time.perf_counter()
            for step in steps(data, count, new_mesh):
                writer.write(*step)
            writes.append(time.perf_counter() - start)
            size = sum(p.stat().st_size for p in Path(tmp).iterdir()
                       if not p.name.startswith("."))
            path = writer.pvd_path if isinstance(writer, SeriesWriter) else writer.path
            start = time.perf_counter()
            read_all(path)
            reads.append(time.perf_counter() - start)
    return writes, reads, size / 1e6


def spread(values) -> str:
    return f"{statistics.median(values):.3f} ({min(values):.3f}-{max(values):.3f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=26)
    parser.add_argument("--steps", type=int, default=5)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--levels", type=int, nargs="*", default=[1, 4],
                        help="gzip levels of vtkhdf's zlib to measure")
    args = parser.parse_args()
    for fmt in ("vtu", "vtkhdf"):  # imports (meshio, h5py, vtk) before the clock
        measure(frame(2), fmt, "none", 2, False, 1)
    data = frame(args.cells)
    print(f"{len(data[1][1]):,} tets, {len(data[0]):,} points, {args.steps} steps, "
          f"{args.repeat} repeats")
    print("| mesh | format | compression | write s | read s | MB |\n|---|---|---|---|---|---|")
    runs = [("vtu", "none", None), ("vtu", "zlib", None), ("vtkhdf", "none", None)]
    runs += [("vtkhdf", "zlib", level) for level in args.levels]
    for new_mesh in (False, True):
        for fmt, compression, level in runs:
            if level is not None:
                vtkhdf.GZIP_LEVEL = level
            writes, reads, size = measure(data, fmt, compression, args.steps, new_mesh,
                                          args.repeat)
            codec = compression if level is None else f"gzip {level} + shuffle"
            print(f"| {'new' if new_mesh else 'same'} | {fmt} | {codec} | {spread(writes)} | "
                  f"{spread(reads)} | {size:.1f} |", flush=True)


if __name__ == "__main__":
    main()
