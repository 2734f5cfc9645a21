"""What a study writes: ``study.csv``, ``study.json`` and ``study.png``."""

from __future__ import annotations

import csv
import io
import itertools
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

from ...writers.directory import replace_file
from .analysis import evaluate, methods, pareto_front, plottable, rates
from .runs import Result
from .spec import Study, value_text

MATPLOTLIB_HINT = (
    "matplotlib is not installed, so study.png was not written (study.csv was); "
    "install it with: pip install 'fem-frac[study]'  (or: pip install matplotlib)"
)


def write_csv(study: Study, results: list[Result], path: Path) -> None:
    stages = list(dict.fromkeys(
        s for r in results if r.ok for s in r.summary["wall_time_s"] if s != "total"))
    cols = (["run_id", *study.keys, "method", "status", "exit_code", "dofs", "elements", "h",
             "wall_time_s", *(f"time_{s.replace(' ', '_')}_s" for s in stages), "peak_mib",
             "quantity", "value", "reference_value", "error", "last_step", "message"])
    quantity = study.quantity or "reference"
    f = io.StringIO(newline="")
    w = csv.writer(f)
    w.writerow(cols)
    for r in results:
        s = r.summary or r.partial or {}
        wt = s.get("wall_time_s", {})
        if r.ok and study.quantity is None and "reference" in s:
            quantity = s["reference"]["quantity"]
        w.writerow([
            r.run.run_id, *(value_text(r.run.settings[k]).strip('"') for k in study.keys),
            r.run.method, "ok" if r.ok else "failed", r.exit_code,
            r.dofs, s.get("counts", {}).get("elements"), _fmt(r.h),
            _fmt(wt.get("total")), *(_fmt(wt.get(st)) for st in stages), _fmt(r.peak_mib),
            quantity if r.ok else "", _fmt(r.value), _fmt(r.reference), _fmt(r.error),
            _fmt(r.last_step), r.message,
        ])
    replace_file(path, f.getvalue())


def _fmt(x) -> str:
    if x is None:
        return ""
    return f"{x:.10g}" if isinstance(x, float) else str(x)


def study_json(study: Study, results: list[Result]) -> dict:
    refs = evaluate(study, results)
    return {
        "title": study.spec.title,
        "case": os.path.normpath(study.case_path),
        "error": study.quantity or "reference",
        "runs": len(results),
        "failed": [r.run.run_id for r in results if not r.ok],
        "rates": rates(results),
        "rate_against": (study.spec.refinement if study.spec.refinement in study.keys
                         else "dofs^(-1/3)"),
        "extrapolation": {m: {"value": e.value, "method": e.method, "order": e.order,
                              "ratio": e.ratio, "note": e.note} for m, e in refs.items()},
        "pareto_front": [r.run.run_id for r in pareto_front(results)],
    }


def plot(study: Study, results: list[Result], path: Path) -> None:
    """Log-log error against wall time, one line per method; raises ImportError without
    matplotlib."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n_lines = len(methods(results)) + 1
    fig, ax = plt.subplots(figsize=(7.5, 5.0 + 0.2 * n_lines), dpi=120)
    against = (("dt" if study.spec.refinement == "analysis.dt" else "h")
               if study.spec.refinement in study.keys else "dofs^(-1/3)")
    _plot_methods(ax, results, against)
    front = pareto_front(results)
    if front:
        ax.plot([r.wall_s for r in front], [r.error for r in front], ls="none", marker="o",
                ms=13, mfc="none", mec="k", mew=1.2, label="Pareto front (nothing faster "
                "and more accurate)", drawstyle="steps-post")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time of the run (s)")
    ax.set_ylabel(_error_label(study, results))
    ax.set_title(study.spec.title or study.name, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    if ax.get_legend_handles_labels()[0]:  # nothing to name when every run failed
        ax.legend(fontsize=7.5, loc="upper center", bbox_to_anchor=(0.5, -0.13),
                  frameon=False, title=f"fitted rate: slope of log error against log {against}",
                  title_fontsize=7.5)
    png = io.BytesIO()
    fig.savefig(png, format="png", bbox_inches="tight")
    plt.close(fig)
    replace_file(path, png.getvalue())


def _plot_methods(ax, results: list[Result], against: str) -> None:
    """One line per method, coarse to fine, each point labelled with its size."""
    rate = rates(results)
    markers = itertools.cycle("osD^v<>ph*")
    for m in methods(results):
        group = sorted((r for r in results if r.run.method == m and plottable(r)),
                       key=lambda r: -r.h)
        if not group:
            continue
        k = rate.get(m)
        label = f"{m}: rate {k:.2f}" if k is not None else f"{m}: rate -"
        ax.plot([r.wall_s for r in group], [r.error for r in group], marker=next(markers),
                label=label)
        for r in group:
            text = f"{against}={r.run.size:g}" if r.run.size is not None else f"{r.dofs:,} dofs"
            ax.annotate(text, (r.wall_s, r.error), textcoords="offset points", xytext=(5, 4),
                        fontsize=7, color="0.3")


def _error_label(study: Study, results: list[Result]) -> str:
    if study.quantity is not None:
        return f"relative error of {study.quantity}\n(against Richardson extrapolation)"
    q = next((r.summary["reference"]["quantity"] for r in results
              if r.ok and "reference" in r.summary), "reference")
    return f"error against the exact solution\n({q})"


@dataclass
class Outcome:
    results: list[Result]
    csv: Path
    json: Path
    png: Path | None
    warnings: list[str] = field(default_factory=list)


def write_outputs(study: Study, results: list[Result], out_dir: Path) -> Outcome:
    csv_path, json_path = out_dir / "study.csv", out_dir / "study.json"
    write_csv(study, results, csv_path)
    replace_file(json_path, json.dumps(study_json(study, results), indent=2) + "\n")
    png: Path | None = out_dir / "study.png"
    warnings = []
    try:
        plot(study, results, png)
    except ImportError:
        png = None
        warnings.append(MATPLOTLIB_HINT)
    return Outcome(results, csv_path, json_path, png, warnings)
