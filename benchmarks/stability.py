"""The stability suite's table (docs/stability.md): every case of cases/stability/, with the
variants listed in tests/test_stability.py, run through the command line.

    python benchmarks/stability.py                 # the tables of docs/stability.md (~15 s)
    python benchmarks/stability.py --write-meshes  # regenerate the committed mesh files

For each run: exit code, maximum displacement (summary.json, else the last committed step of
history.csv), the error against a declared exact reference (summary.json), the largest
energy-ledger error over the committed steps, iterations, the relative residual of the last
committed step, and the one-line message of a refusal or a numerical stop (paths relative
to cases/stability/). Blank: no step was committed. A second table gives the stable step
of central difference (``fem-frac check``) of the dynamic and sliver cases.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent.parent / "tests"))
from test_stability import (  # noqa: E402
    CASES,
    SCENES,
    STABLE_STEP_RUNS,
    run_cli,
    stable_step,
)

# --- the committed mesh files -------------------------------------------------------------

BAR = (1.0, 0.25, 0.25)  # a bar, 8 x 2 x 2 cubes of 6 tets: 81 vertices, 192 tets
CELLS = (8, 2, 2)
# how far a flattened vertex is left from the plane of the face it is pushed onto, as a
# fraction of its initial distance: 0.01 gives two tets of minimum dihedral angle 0.57 deg
SLIVER_FRACTION = 0.01


def regular_bar() -> tuple[np.ndarray, np.ndarray]:
    """Points and positively oriented tets of the structured bar (minimum dihedral 45 deg)."""
    from skfem import MeshTet

    from fem_frac.mesh.mesh import tet_volumes

    axes = [np.linspace(0.0, length, n + 1) for length, n in zip(BAR, CELLS, strict=True)]
    m = MeshTet.init_tensor(*axes)
    points, tets = m.p.T.copy(), m.t.T.copy()
    negative = tet_volumes(points, tets) < 0
    tets[negative] = tets[negative][:, [0, 2, 1, 3]]
    return points, tets


def pushed(points, tets, vertex: int, fraction: float) -> np.ndarray:
    """``points`` with ``vertex`` moved along the normal of the face opposite it in one of
    its tets, to ``fraction`` of its distance from that face's plane (0: onto the plane;
    negative: through it). Of the tets around the vertex, the one chosen keeps the others
    best shaped (largest second-smallest dihedral angle); the two tets that share the face's
    plane flatten together."""
    from fem_frac.mesh.mesh import min_dihedral_angles

    best = None
    for e in np.flatnonzero((tets == vertex).any(axis=1)):
        a, b, c = points[[w for w in tets[e] if w != vertex]]
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n)
        moved = points.copy()
        moved[vertex] -= (1.0 - fraction) * np.dot(points[vertex] - a, n) * n
        key = np.sort(min_dihedral_angles(moved, tets))[2]
        if best is None or key > best[0]:
            best = (key, moved)
    return best[1]


def write_meshes(directory: Path) -> None:
    """regular.vtu, sliver.vtu (six tets below 1 deg), inverted.vtu (two tets pushed
    through their face: mixed orientation), zero_volume.vtu (two tets of zero volume)."""
    import meshio

    from fem_frac.mesh.mesh import min_dihedral_angles, tet_volumes

    points, tets = regular_bar()
    interior = np.flatnonzero(np.all((points > 1e-12) & (points < np.array(BAR) - 1e-12),
                                     axis=1))
    sliver = points
    for vertex in interior[[1, 3, 5]]:
        sliver = pushed(sliver, tets, vertex, SLIVER_FRACTION)
    meshes = {
        "regular": points,
        "sliver": sliver,
        "inverted": pushed(points, tets, interior[3], -0.05),
        "zero_volume": pushed(points, tets, interior[3], 0.0),
    }
    for name, p in meshes.items():
        meshio.write(directory / f"{name}.vtu", meshio.Mesh(p, [("tetra", tets)]))
        v = tet_volumes(p, tets)
        angles = min_dihedral_angles(p, tets)
        print(f"{name}.vtu: {len(tets)} tets, volume min/mean {v.min() / v.mean():+.3g}, "
              f"min dihedral {angles.min():.3g} deg, {np.count_nonzero(angles < 1)} below 1 deg")


# --- the tables ------------------------------------------------------------------------------


def _fmt(value, spec: str) -> str:
    return "" if value is None else format(value, spec)


def row(scene: str, case: Path, label: str, overrides: list[str], out: Path) -> str:
    t = time.perf_counter()
    r = run_cli(case, overrides, out)
    wall = time.perf_counter() - t
    message = r.message.replace(f"{case.parent}/", "").replace("|", "/")
    residual = r.history["residual"][-1] if r.steps > 1 else None
    reference = (r.summary or {}).get("reference")
    exact = reference["relative_error"] if reference else None
    return (f"| {scene} | {case.stem} | {label} | {r.code} | {_fmt(r.max_displacement, '.4g')} "
            f"| {_fmt(exact, '.3f')} | {_fmt(r.energy_error, '.1e')} "
            f"| {_fmt(r.iterations, 'd')} | {_fmt(residual, '.1e')} | {message} "
            f"| {wall:.1f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--write-meshes", action="store_true",
                        help="rewrite the mesh files of cases/stability/ and stop")
    args = parser.parse_args()
    if args.write_meshes:
        write_meshes(CASES)
        return
    print("| scene | case | variant | exit | max abs(u) | error vs exact | energy error (rel.) "
          "| iterations | last residual | message | wall s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    listed = {s.case for s in SCENES}
    extra = sorted(p.stem for p in CASES.glob("*.yaml") if p.stem not in listed)
    with tempfile.TemporaryDirectory() as tmp:
        n = 0
        for s in SCENES:
            for label, overrides in s.variants:
                n += 1
                print(row(s.scene, CASES / f"{s.case}.yaml", label, overrides,
                          Path(tmp) / f"run{n}"), flush=True)
        for stem in extra:  # a case added without variants runs as it is
            n += 1
            print(row("?", CASES / f"{stem}.yaml", "as is", [], Path(tmp) / f"run{n}"),
                  flush=True)
    print("\nStable step of central difference (fem-frac check; Lanczos on the assembled "
          "system, and the element-by-element bound)\n")
    print("| case | variant | stable step (Lanczos) | element bound |")
    print("|---|---|---|---|")
    for stem, label, overrides in STABLE_STEP_RUNS:
        lanczos, bound = stable_step(CASES / f"{stem}.yaml", overrides)
        print(f"| {stem} | {label} | {lanczos:.4g} s | {bound:.4g} s |")


if __name__ == "__main__":
    main()
