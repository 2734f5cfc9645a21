"""Table and figure of a notched-beam cohesive study (docs/fracture/cohesive_convergence.md).

    fem-frac study studies/notched_beam_cohesive.yaml          # writes out/notched_beam_cohesive
    python docs/fracture/cohesive_study.py out/notched_beam_cohesive
    fem-frac study studies/notched_beam_ligament.yaml          # writes out/notched_beam_ligament
    python docs/fracture/cohesive_study.py out/notched_beam_ligament \
        -o docs/fracture/ligament_load_displacement.png --xmax 450

reads every run of the study (``runs/<id>/``: summary.json, history.csv, case.resolved.yaml and
the last step of the crack surface series), prints the markdown table of the docs (peak load,
displacement at the peak, the energy the law dissipated and the external work over G_c times
the ligament area, the crack area over the ligament's, where
the crack faces lie, tets, wall time) and the observed order of the peak load, and writes
``docs/fracture/cohesive_load_displacement.png`` (``-o`` to write it elsewhere): the
load-displacement curves of all meshes in one plot, and the crack faces of each mesh seen
along y. Runs that stopped early (exit 3) are shown up to where they stopped.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path

import numpy as np

# meshes/notched_beam_cohesive.geo: the ligament is the rectangle x = XM, z in [0.02, 0.04],
# y in [0, 0.005]
XM = 0.085
LIGAMENT_AREA = 0.02 * 0.005
HERE = Path(__file__).resolve().parent


def read_history(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def load_condition(case: dict) -> tuple[dict, str]:
    """The condition that pushes the beam down (the one with a non-zero ``z``) and its label
    in history.csv (its boundary's name, else ``boundary_conditions[i]``)."""
    i, bc = next((i, b) for i, b in enumerate(case["boundary_conditions"]) if b.get("z"))
    return bc, bc.get("boundary") or f"boundary_conditions[{i}]"


def load_displacement(case: dict, time: np.ndarray) -> np.ndarray:
    """The prescribed downward displacement of the load strip or line at ``time`` (m)."""
    bc, _ = load_condition(case)
    curve = bc.get("curve", "ramp")
    t_end = case["analysis"].get("t_end", 1.0)
    if curve == "ramp":
        factor = time / t_end
    else:
        points = np.array(case["load_curves"][curve]["points"], dtype=float)
        factor = np.interp(time, points[:, 0], points[:, 1])
    return -float(bc["z"]) * factor


def crack_faces(run_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """Corners ``(k, 3, 3)`` and damage ``(k,)`` of the crack faces at the last output step."""
    import meshio

    steps = sorted(run_dir.glob("*_crack_*.vtu"))
    if not steps:
        return np.zeros((0, 3, 3)), np.zeros(0)
    m = meshio.read(steps[-1])
    tri = m.cells_dict.get("triangle")
    if tri is None:
        return np.zeros((0, 3, 3)), np.zeros(0)
    damage = m.cell_data["damage"][[c.type for c in m.cells].index("triangle")]
    return m.points[tri], np.asarray(damage)


def read_run(run_dir: Path) -> dict:
    from ruamel.yaml import YAML

    summary = json.loads((run_dir / "summary.json").read_text())
    case = YAML(typ="safe").load((run_dir / "case.resolved.yaml").read_text())
    hist = read_history(run_dir / "history.csv")
    delta = load_displacement(case, hist["time"])
    load = -hist[f"reaction_{load_condition(case)[1]}_z"]
    peak = int(np.argmax(load))
    gc = float(case["fracture"]["fracture_energy"])
    corners, damage = crack_faces(run_dir)
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                         corners[:, 2] - corners[:, 0]), axis=1)
    on_plane = np.all(np.abs(corners[:, :, 0] - XM) < 1e-9, axis=1)
    record = json.loads((run_dir / "study_run.json").read_text()) \
        if (run_dir / "study_run.json").is_file() else {}
    completed = summary.get("status", "completed") == "completed"
    # a run that stopped early writes a short summary (status, step, message): its tets
    # are counted in its first output step, its time is the process's
    return {
        "dir": run_dir, "h": float(case["mesh"]["element_size"]),
        "tets": summary["counts"]["elements"] if completed else first_step_tets(run_dir),
        "status": summary.get("status", "completed"), "message": summary.get("message", ""),
        "steps": int(hist["step"][-1]),
        "steps_planned": summary["analysis"]["steps"] if completed else summary["steps"],
        "wall_s": (summary["wall_time_s"].get("total") if completed
                   else record.get("process_s", math.nan)),
        "delta": delta, "load": load, "peak_load": float(load[peak]),
        "peak_delta": float(delta[peak]), "end_load": float(load[-1]),
        "end_delta": float(delta[-1]),
        "dissipated": float(hist["cohesive_dissipated"][-1]) / (gc * LIGAMENT_AREA),
        # the area under the load-displacement curve, what an experiment's work of fracture
        # measures (at complete failure: what the law dissipated and the insertions released)
        "work": float(hist["external_work"][-1]) / (gc * LIGAMENT_AREA),
        "crack_area": float(hist["crack_area"][-1]) / LIGAMENT_AREA,
        "on_plane": float(area[on_plane].sum()) / LIGAMENT_AREA,
        "broken_on_plane": float(area[on_plane & (damage >= 1.0 - 1e-9)].sum()) / LIGAMENT_AREA,
        "max_offset": float(np.abs(corners[:, :, 0] - XM).max()) if len(corners) else 0.0,
        "corners": corners, "on_plane_faces": on_plane,
    }


def first_step_tets(run_dir: Path) -> int:
    import meshio

    first = sorted(p for p in run_dir.glob("*_000000.vtu") if "_crack_" not in p.name)[0]
    return sum(len(c.data) for c in meshio.read(first).cells if c.type == "tetra")


def observed_order(h: list[float], q: list[float]) -> float | None:
    """p = log(|q1 - q2| / |q2 - q3|) / log(h1 / h2) for three sizes h1 > h2 > h3 in a
    constant ratio; None when the differences do not shrink."""
    (h1, h2, _), (q1, q2, q3) = h, q
    d1, d2 = abs(q1 - q2), abs(q2 - q3)
    if d2 == 0 or d1 <= d2:
        return None
    return math.log(d1 / d2) / math.log(h1 / h2)


def table(runs: list[dict]) -> str:
    head = ("| element size (l_cz / n) | tets | run | peak load (N) | displacement at peak (um) "
            "| load at end / peak | dissipated by the law / (G_c A) | external work / (G_c A) "
            "| crack area / A | on the ligament "
            "plane / A (broken) | farthest face from the plane (mm) | wall s |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in runs:
        run = ("to the end" if r["status"] == "completed"
               else f"stopped at step {r['steps'] + 1} of {r['steps_planned']}")
        lines.append(
            f"| {r['h'] * 1000:g} mm (l_cz / {0.02 / r['h']:g}) | {r['tets']:,} | {run} "
            f"| {r['peak_load']:.1f} | {r['peak_delta'] * 1e6:.1f} "
            f"| {abs(r['end_load']) / r['peak_load']:.3f} at {r['end_delta'] * 1e6:.0f} um "
            f"| {r['dissipated']:.3f} | {r['work']:.2f} "
            f"| {r['crack_area']:.2f} "
            f"| {r['on_plane']:.2f} ({r['broken_on_plane']:.2f}) | {r['max_offset'] * 1000:.1f} "
            f"| {r['wall_s']:.0f} |")
    return "\n".join(lines)


def figure(runs: list[dict], path: Path, xmax: float | None = None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(12, 7.5), dpi=100)
    grid = fig.add_gridspec(len(runs), 2, width_ratios=[1.35, 1], hspace=0.35, wspace=0.12)
    ax = fig.add_subplot(grid[:, 0])
    colours = [f"C{i}" for i in range(len(runs))]
    for r, c in zip(runs, colours, strict=True):
        label = (f"h = {r['h'] * 1000:g} mm = l_cz/{0.02 / r['h']:g} ({r['tets']:,} tets)"
                 + ("" if r["status"] == "completed" else f", stopped at step {r['steps'] + 1}"))
        ax.plot(r["delta"] * 1e6, r["load"], color=c, lw=1.3, label=label)
        ax.plot(r["peak_delta"] * 1e6, r["peak_load"], "o", color=c, ms=5)
        if r["status"] != "completed":
            ax.plot(r["end_delta"] * 1e6, r["end_load"], "x", color=c, ms=8, mew=2)
    if xmax is not None:
        ax.set_xlim(0.0, xmax)
    ax.set_xlabel("load-point displacement (um)")
    ax.set_ylabel("load (N)")
    ax.set_title("notched beam, cohesive cracks: load against displacement", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    for i, (r, c) in enumerate(zip(runs, colours, strict=True)):
        a = fig.add_subplot(grid[i, 1])
        a.plot([XM * 1000] * 2, [20, 40], color="0.6", lw=0.8, ls="--")  # the ligament
        a.plot([XM * 1000 - 2.5, XM * 1000, XM * 1000 + 2.5], [0, 20, 0], color="k", lw=0.8)
        for tri, on in zip(r["corners"], r["on_plane_faces"], strict=True):
            if on:  # edge-on: a thick stroke over its height
                a.plot([XM * 1000] * 2, [tri[:, 2].min() * 1000, tri[:, 2].max() * 1000],
                       color=c, lw=4, solid_capstyle="butt", alpha=0.6)
            else:
                xz = tri[[0, 1, 2, 0]][:, [0, 2]] * 1000
                a.fill(xz[:, 0], xz[:, 1], color="0.15", alpha=0.45, lw=0.3, ec="k")
        a.set_xlim(XM * 1000 - 25, XM * 1000 + 25)
        a.set_ylim(0, 40)
        a.set_aspect("equal")
        a.tick_params(labelsize=7)
        a.set_ylabel("z (mm)", fontsize=7)
        a.set_title(f"h = {r['h'] * 1000:g} mm: crack faces seen along y\n(colour: on the "
                    "ligament plane, grey: off it)", fontsize=8)
    a.set_xlabel("x (mm)", fontsize=7)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("study_dir", type=Path, nargs="?", default=Path("out/notched_beam_cohesive"))
    p.add_argument("-o", "--figure", type=Path, default=HERE / "cohesive_load_displacement.png")
    p.add_argument("--xmax", type=float, help="the plot's largest displacement (um)")
    args = p.parse_args()
    runs = sorted((read_run(d) for d in (args.study_dir / "runs").iterdir()
                   if (d / "summary.json").is_file()), key=lambda r: -r["h"])
    print(table(runs))
    if len(runs) >= 3:
        h, peaks = [r["h"] for r in runs[-3:]], [r["peak_load"] for r in runs[-3:]]
        p_obs = observed_order(h, peaks)
        diffs = ", ".join(f"{abs(a - b):.2f}" for a, b in zip(peaks, peaks[1:], strict=False))
        print(f"\npeak load, three finest: differences {diffs} N; observed order "
              + (f"{p_obs:.2f}" if p_obs is not None else "none (differences do not shrink)"))
        broken = runs[-3:]
        if all(abs(r["end_load"]) < 1e-3 * r["peak_load"] for r in broken):
            # complete failure: the work of fracture against G_c A
            work = [r["work"] for r in broken]
            w_obs = observed_order(h, work)
            print("external work at complete failure / (G_c A), three finest: "
                  + ", ".join(f"{w:.3f}" for w in work) + "; differences "
                  + ", ".join(f"{abs(a - b):.3f}" for a, b in zip(work, work[1:], strict=False))
                  + "; observed order "
                  + (f"{w_obs:.2f}" if w_obs is not None else "none (differences do not shrink)"))
    figure(runs, args.figure, args.xmax)
    print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
