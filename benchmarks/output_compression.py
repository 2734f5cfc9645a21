"""Writing one output frame with each compression of ``output.compression`` (docs/performance.md,
"Output"): the time to write and read a .vtu and its size.

    python benchmarks/output_compression.py [--cells N] [--repeat K]

The frame: a structured box of tets (6 per cube, N cubes a side; N = 26 gives 105,456 tets)
with the fields a run writes (displacement and velocity at the points; stress, von Mises,
largest principal stress, its smoothed value, fragment id per cell), smooth fields with
their last digits perturbed, as a solver's doubles are. Times are the least and greatest of
``--repeat`` writes (wall clock), written through fem_frac's SeriesWriter.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from fem_frac.writers.series import SeriesWriter

KUHN = np.array([[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6],
                 [0, 5, 1, 6]])


def frame(n: int):
    axis = np.linspace(0.0, 1.0, n + 1)
    points = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    i = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    hexes = np.stack([i[:-1, :-1, :-1], i[1:, :-1, :-1], i[1:, 1:, :-1], i[:-1, 1:, :-1],
                      i[:-1, :-1, 1:], i[1:, :-1, 1:], i[1:, 1:, 1:], i[:-1, 1:, 1:]],
                     -1).reshape(-1, 8)
    tets = hexes[:, KUHN].reshape(-1, 4)
    rng = np.random.default_rng(0)
    x, c = points, points[tets].mean(axis=1)
    u = 1e-3 * np.stack([np.sin(3 * x[:, 0]) * x[:, 1], 0.01 * x[:, 2] ** 2,
                         np.cos(x[:, 0] * x[:, 1])], -1)
    u *= 1.0 + 1e-6 * rng.standard_normal(u.shape)
    stress = 1e6 * np.stack([np.sin(k * c[:, 0] + c[:, 1]) for k in range(6)], -1)
    stress *= 1.0 + 1e-7 * rng.standard_normal(stress.shape)
    cells = {"stress": stress, "von_mises": np.linalg.norm(stress, axis=1),
             "max_principal_stress": stress[:, 0].copy(),
             "smoothed_max_principal_stress": stress[:, 1].copy(),
             "fragment_id": np.zeros(len(tets), dtype=np.int32)}
    return points, ("tetra", tets), {"displacement": u, "velocity": 3.0 * u}, cells


def main() -> None:
    import meshio

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=26)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    data = frame(args.cells)
    print(f"{len(data[1][1]):,} tets, {len(data[0]):,} points")
    print("| compression | write s (min-max) | read s (min-max) | MB |\n|---|---|---|---|")
    for compression in ("none", "zlib", "lzma"):
        with tempfile.TemporaryDirectory() as tmp:
            writes, reads = [], []
            for _ in range(args.repeat):
                series = SeriesWriter(Path(tmp), "f", compression=compression)
                start = time.perf_counter()
                path = series.write(0.0, *data)
                writes.append(time.perf_counter() - start)
                start = time.perf_counter()
                meshio.read(path)
                reads.append(time.perf_counter() - start)
            size = path.stat().st_size / 1e6
        print(f"| {compression} | {min(writes):.3f}-{max(writes):.3f} | "
              f"{min(reads):.3f}-{max(reads):.3f} | {size:.1f} |")


if __name__ == "__main__":
    main()
