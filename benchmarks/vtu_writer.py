"""The .vtu frame writer against meshio's: the CPU time of one frame, and of importing meshio.

    python benchmarks/vtu_writer.py [--repeats 7]

Writes the same frame (random points, tets and the cell and point arrays of a brittle run:
displacement; stress, von Mises, max principal stress, fragment id, smoothed max principal
stress) at three sizes with ``fem_frac.writers.vtu.write_vtu`` and with
``meshio.vtu.write`` (binary, uncompressed: the same bytes but for the comment line,
tests/test_vtu_writer.py), alternately, and prints min and median CPU time of each. The
import of meshio, which a run that writes with fem_frac's writer no longer pays, is timed
first, in a fresh process (``python -c "import numpy, scipy.sparse; import meshio"``, its
CPU time less that of the same without meshio, min of 5 each).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

SIZES = ((579, 1_938), (3_000, 14_638), (20_000, 94_187))  # (points, tets)


def _process_cpu(code: str) -> float:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    subprocess.run([sys.executable, "-c", code], check=True, env=env)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def import_cost(repeats: int = 5) -> float:
    """CPU seconds of ``import meshio`` after numpy and scipy.sparse (min of each)."""
    base = "import numpy, scipy.sparse"
    with_meshio = min(_process_cpu(base + "; import meshio") for _ in range(repeats))
    without = min(_process_cpu(base) for _ in range(repeats))
    return with_meshio - without


def frame(n: int, m: int, rng):
    points = rng.random((n, 3))
    tets = rng.integers(0, n, (m, 4)).astype(np.int32)
    point_data = {"displacement": rng.random((n, 3))}
    cell_data = {"stress": rng.random((m, 6)), "von_mises": rng.random(m),
                 "max_principal_stress": rng.random(m),
                 "fragment_id": np.zeros(m, np.int32),
                 "smoothed_max_principal_stress": rng.random(m)}
    return points, ("tetra", tets), point_data, cell_data


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=7)
    args = p.parse_args()
    print(f"import meshio: {1e3 * import_cost():.0f} ms of CPU time")
    import meshio

    from fem_frac.writers.vtu import write_vtu

    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as out:

        def ours(points, cells, point_data, cell_data):
            write_vtu(os.path.join(out, "a.vtu"), points, cells, point_data, cell_data)

        def theirs(points, cells, point_data, cell_data):
            mesh = meshio.Mesh(points, [cells], point_data=dict(point_data),
                               cell_data={k: [v] for k, v in cell_data.items()})
            meshio.vtu.write(os.path.join(out, "b.vtu"), mesh, binary=True, compression=None)

        for n, m in SIZES:
            data = frame(n, m, rng)
            times = {"fem_frac": [], "meshio": []}
            for _ in range(args.repeats):
                for name, fn in (("meshio", theirs), ("fem_frac", ours)):
                    t = time.process_time()
                    fn(*data)
                    times[name].append(time.process_time() - t)
            cells_ = ", ".join(f"{k} {1e3 * min(v):.2f} / {1e3 * float(np.median(v)):.2f} ms"
                               for k, v in times.items())
            print(f"{m:,} tets: {cells_} (min / median of {args.repeats})")


if __name__ == "__main__":
    main()
