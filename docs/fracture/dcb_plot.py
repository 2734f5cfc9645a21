"""The double cantilever beam (cases/dcb.yaml) at three element sizes on the crack path
against beam theory: writes docs/fracture/dcb.png (load and crack length against the
load-point opening) and prints the table of docs/fracture/dcb.md.

    python docs/fracture/dcb_plot.py OUT

runs into OUT/s1, OUT/s05, OUT/s025 whatever OUT lacks (about 0.5, 1.5 and 6 minutes on 2
cores, one run at a time): the shipped case (s = 1 mm), and s = 0.5 mm and s = 0.25 mm
(meshes/dcb.geo with s changed, the crack opened further in finer steps; the 0.5 mm run is
the slow test's). The runs and their measurements are tests/test_dcb.py's.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(ROOT / "tests"))

import test_dcb as t  # noqa: E402

from fem_frac.verify import dcb  # noqa: E402

OPEN = ("boundary_conditions.1.z=1.8e-4", "boundary_conditions.2.z=-1.8e-4")
RUNS = {  # name: (s in m, .geo changes, --set options)
    "s1": (0.001, {}, ()),
    "s05": (0.0005, {"s": 0.0005}, OPEN + (
        "load_curves.opening.points=[[0, 0], [0.025, 0.1], [0.05, 0.3], [1, 1]]",
        "analysis.steps=40")),
    "s025": (0.00025, {"s": 0.00025}, OPEN + (
        "load_curves.opening.points=[[0, 0], [0.0125, 0.1], [0.025, 0.3], [1, 1]]",
        "analysis.steps=80")),
}


def get(out: Path, name: str) -> t.Run:
    _, changes, sets = RUNS[name]
    target = out / name
    geo = t.geo_numbers(t.GEO.read_text())
    geo.update(changes)
    if (target / "summary.json").is_file():
        return t.measure(target, geo)
    return t.run_dcb(target, changes, sets)


def row(name: str, r: t.Run) -> str:
    g = r.geo
    c = r.delta[1] / r.load[1]
    chi = (dcb.length_from_compliance(c, r.E, g["b"], g["h"]) - g["a0"]) / g["h"]
    c_ratio = c / dcb.compliance(g["a0"], r.E, g["b"], g["h"], dcb.CHI_PLANE)
    error, tolerance = t.load_errors(r)
    k = t.growth_steps(r)
    theory = dcb.crack_length(r.delta[k], r.E, r.gc, g["h"], dcb.CHI_PLANE)
    zone = (r.a_inserted[k] - r.a_broken[k]).mean()
    counts, wall = r.summary["counts"], r.summary["wall_time_s"]["total"]
    return (f"| {g['s'] * 1e3:g} | {counts['elements']:,} / {counts['dofs']:,} | "
            f"{len(r.delta) - 1} | {wall:.0f} | {c_ratio:.4f} | {chi:.3f} | {len(k)} | "
            f"{error.mean():+.3f} | {np.abs(error).max():.3f} | {tolerance.min():.3f} | "
            f"{(r.a_broken[k] - theory).min() * 1e3:+.2f} / "
            f"{(r.a_inserted[k] - theory).max() * 1e3:+.2f} | {zone * 1e3:.2f} | "
            f"{(r.a_broken[-1] - g['a0']) * 1e3:.1f} |")


def plot(runs: dict[str, t.Run], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r0 = runs["s1"]
    g, e, gc = r0.geo, r0.E, r0.gc
    b, h, a0 = g["b"], g["h"], g["a0"]
    d = np.linspace(1e-6, 3.7e-4, 400)
    d0 = dcb.initiation_opening(a0, e, gc, b, h, dcb.CHI_PLANE)
    branch = d[d >= d0]
    fig, (left, middle, right) = plt.subplots(1, 3, figsize=(15, 4.4))
    left.plot(d * 1e6, d / dcb.compliance(a0, e, b, h, dcb.CHI_PLANE), "k:", lw=1,
              label="elastic line, a = a0 (chi = 0.673)")
    left.plot(branch * 1e6, dcb.propagation_load(branch, e, gc, b, h), "k-", lw=1.5,
              label="beam theory, G = G_c")
    right.plot(branch * 1e6, dcb.crack_length(branch, e, gc, h, dcb.CHI_PLANE) * 1e3, "k-",
               lw=1.5, label="beam theory (chi = 0.673)")
    middle.axhline(0.0, color="k", lw=1.5)
    style = {"s1": ("tab:red", "o", 3.5), "s05": ("tab:blue", "s", 2.5),
             "s025": ("tab:green", ".", 2.0)}
    for name, r in runs.items():
        s = r.geo["s"] * 1e3
        colour, marker, size = style[name]
        left.plot(r.delta * 1e6, r.load, marker + "-", ms=size, lw=0.8, color=colour,
                  label=f"s = {s:g} mm")
        k = t.growth_steps(r)
        error, tolerance = t.load_errors(r)
        middle.plot(r.delta[k] * 1e6, error * 100, marker + "-", ms=size, lw=0.8,
                    color=colour, label=f"s = {s:g} mm")
        middle.plot(r.delta[k] * 1e6, tolerance * 100, "--", lw=0.8, color=colour)
        middle.plot(r.delta[k] * 1e6, -tolerance * 100, "--", lw=0.8, color=colour)
        right.fill_between(r.delta * 1e6, r.a_broken * 1e3, r.a_inserted * 1e3,
                           color=colour, alpha=0.25, lw=0,
                           label=f"s = {s:g} mm: broken to inserted faces")
        right.plot(r.delta * 1e6, r.a_dissipated * 1e3, "-", lw=0.8, color=colour)
    left.set_xlabel("load-point opening delta (um)")
    left.set_ylabel("load P (N)")
    left.set_ylim(0, 3.2)
    left.legend(fontsize=8, loc="lower right")
    middle.set_xlabel("load-point opening delta (um)")
    middle.set_ylabel("P / P_theory - 1 (%) while the crack grows")
    middle.set_title("dashed: tolerance +- 6 s / a_e", fontsize=8)
    middle.legend(fontsize=8, loc="lower right")
    right.set_xlabel("load-point opening delta (um)")
    right.set_ylabel("crack length from the load line (mm)")
    right.set_ylim(38, 56)
    right.legend(fontsize=8, loc="upper left")
    right.set_title("line: a0 + dissipated energy / (G_c b)", fontsize=8)
    fig.suptitle("DCB, h = 10 mm, b = 1 mm, a0 = 40 mm, G_c = 18 J/m^2, sigma_t = 6 MPa "
                 "(l_cz = 5 mm)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main(out: Path) -> None:
    runs = {name: get(out, name) for name in RUNS}
    print("| s (mm) | tets / dofs | steps | wall (s) | C / C(a0) | chi | growth steps | "
          "P / P_th - 1, mean | max abs | 6 s / a_e, least | a_broken - a_th / "
          "a_inserted - a_th (mm) | process zone (mm) | grown (mm) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, r in runs.items():
        print(row(name, r))
    plot(runs, HERE / "dcb.png")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
