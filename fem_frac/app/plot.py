"""``fem-frac plot OUT_DIR``: figures of a run from its ``history.csv`` (and
``summary.json`` when there is one), as PNG files beside them.

- ``plot_energy.png``: the energies and works of the ledger against time, and the energy
  balance error (relative) below;
- ``plot_reactions.png``: the reaction force of every support, and the largest displacement;
- ``plot_fracture.png`` (a run with fracture or fragments): crack faces and area, pieces
  and rigid bodies, sites opened per step;
- ``plot_solver.png``: iterations (substeps of an explicit run) and cutbacks, the relative
  residual, the wall time of every step.

A figure with nothing to show is not drawn (and an earlier one of the same name is
removed, so the figures in a directory always describe its history). No other file is
touched. Needs matplotlib (the ``study`` extra); it is imported only here.
"""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import FemFracError
from ..writers.history import read_history

INSTALL = "pip install 'fem-frac[study]'"
FIGURES = ("energy", "reactions", "fracture", "solver")

# the ledger's columns, in the order they are drawn, with their labels
ENERGIES = (
    ("kinetic_energy", "kinetic"),
    ("strain_energy", "strain"),
    ("plastic_work", "plastic work"),
    ("plastic_dissipation", "plastic dissipation"),
    ("damping_work", "damping work"),
    ("external_work", "external work"),
    ("fracture_energy", "released by cracks"),
    ("handed_off", "handed to rigid bodies"),
    ("rigid_kinetic_energy", "rigid kinetic"),
    ("rigid_potential_energy", "rigid potential"),
    ("vibration_energy_removed", "vibration removed"),
)


class PlotError(FemFracError):
    """A directory that holds no history to draw, or no matplotlib (exit 2)."""


History = dict[str, list[float]]


def plot_run(directory: Path) -> list[Path]:
    """Draw the figures of the run in ``directory``; returns the paths written."""
    history = load_history(directory)
    summary = load_summary(directory)
    figure = _figure_class()
    title = summary.get("title") or directory.resolve().name
    drawers = {"energy": _energy, "reactions": _reactions, "fracture": _fracture,
               "solver": _solver}
    written = []
    for name in FIGURES:
        path = directory / f"plot_{name}.png"
        fig = drawers[name](figure, history, summary)
        if fig is None:
            path.unlink(missing_ok=True)
            continue
        fig.suptitle(f"{title}: {_SUBTITLES[name]}", fontsize=10)
        fig.savefig(path, dpi=90)
        written.append(path)
    return written


_SUBTITLES = {"energy": "energies", "reactions": "reactions and displacement",
              "fracture": "cracks and fragments", "solver": "solver cost per step"}


def load_history(directory: Path) -> History:
    """The columns of ``directory/history.csv``; a :class:`PlotError` when there is no
    such directory or file, or it has no step."""
    if not directory.is_dir():
        raise PlotError(f"{directory}: no such directory (give the output directory of "
                        "`fem-frac run`)")
    path = directory / "history.csv"
    if not path.is_file():
        raise PlotError(f"{directory}: no history.csv (not the output directory of "
                        "`fem-frac run`, or a run stopped before its first step)")
    try:
        history = read_history(path)
    except (ValueError, TypeError) as exc:
        raise PlotError(f"{path}: not a history file of fem-frac ({exc})") from None
    if not history.get("step"):
        raise PlotError(f"{path}: no step written yet")
    if "time" not in history:
        raise PlotError(f"{path}: no time column (not a history file of fem-frac)")
    return history


def load_summary(directory: Path) -> dict:
    """``summary.json`` of the run, or ``{}`` (a run under way or stopped has none, or an
    unfinished one)."""
    try:
        data = json.loads((directory / "summary.json").read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _figure_class():
    """matplotlib's Figure (no pyplot: no window, no global state)."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise PlotError(f"matplotlib is not installed; install it with: {INSTALL}") from None
    return Figure


def _axes(figure, rows: int, height: float = 2.4):
    fig = figure(figsize=(7.0, 0.9 + height * rows), layout="constrained")
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return fig, axes


def _style(history: History) -> dict:
    """Markers on a short history (a static run has two rows)."""
    return {"marker": "o", "ms": 3} if len(history["step"]) <= 30 else {}


def _nonzero(history: History, key: str) -> bool:
    return key in history and any(v != 0.0 for v in history[key])


def _energy(figure, history: History, summary: dict):
    keys = [(k, label) for k, label in ENERGIES if _nonzero(history, k)]
    if not keys and "energy_error_relative" not in history:
        return None
    fig, (top, bottom) = _axes(figure, 2)
    t, style = history["time"], _style(history)
    for key, label in keys:
        top.plot(t, history[key], label=label, **style)
    top.set_ylabel("energy")
    if keys:
        top.legend(fontsize=7, ncol=2)
    error = [abs(v) for v in history.get("energy_error_relative", [])]
    if any(v > 0.0 for v in error):
        bottom.semilogy(t, [v if v > 0.0 else float("nan") for v in error], color="k",
                        **style)
    else:
        bottom.plot(t, error, color="k", **style)
    bottom.set_ylabel("|energy balance error|\n(relative)")
    bottom.set_xlabel("time")
    return fig


def _reactions(figure, history: History, summary: dict):
    keys = [k for k in history if k.startswith("reaction_") and _nonzero(history, k)]
    if not keys and not _nonzero(history, "max_displacement"):
        return None
    fig, (top, bottom) = _axes(figure, 2)
    t, style = history["time"], _style(history)
    for key in keys:
        support, axis = key.removeprefix("reaction_").rsplit("_", 1)
        top.plot(t, history[key], label=f"{support} {axis}", **style)
    top.set_ylabel("reaction force")
    if keys:
        top.legend(fontsize=7, ncol=3)
    else:
        top.text(0.5, 0.5, "no support reacts", ha="center", va="center",
                 transform=top.transAxes, color="0.4")
    bottom.plot(t, history.get("max_displacement", [0.0] * len(t)), color="k", **style)
    bottom.set_ylabel("max |u|")
    bottom.set_xlabel("time")
    return fig


def _fracture(figure, history: History, summary: dict):
    if not any(k in history for k in ("crack_faces", "fragments", "rigid_bodies")):
        return None
    fig, (cracks, pieces, sites) = _axes(figure, 3, height=2.0)
    t = history["time"]
    if "crack_faces" in history:
        cracks.step(t, history["crack_faces"], where="post", color="C3", label="faces")
        cracks.set_ylabel("crack faces", color="C3")
        area = cracks.twinx()
        area.plot(t, history["crack_area"], color="C0", label="area")
        area.set_ylabel("crack area", color="C0")
    for key, label in (("fragments", "pieces of the body"), ("rigid_bodies", "rigid bodies")):
        if key in history:
            pieces.step(t, history[key], where="post", label=label)
    pieces.set_ylabel("count")
    pieces.legend(fontsize=7)
    if "insertions" in history:
        sites.vlines(t, 0, history["insertions"], color="C3", label="sites opened")
        passes = [v if v > 0.0 else float("nan") for v in history.get("fracture_passes", [])]
        if passes:
            sites.plot(t, passes, ls="none", marker=".", ms=4, color="k", label="passes")
        sites.legend(fontsize=7)
    sites.set_ylabel("per step")
    sites.set_xlabel("time")
    return fig


def _solver(figure, history: History, summary: dict):
    if "iterations" not in history:
        return None
    fig, (cost, residual, wall) = _axes(figure, 3, height=2.0)
    steps, style = history["step"], _style(history)
    explicit = "stable_time_step" in summary.get("analysis", {})
    cost.plot(steps, history["iterations"], drawstyle="steps-mid", color="k",
              label="substeps" if explicit else "iterations")
    if _nonzero(history, "cutbacks"):
        cost.plot(steps, history["cutbacks"], drawstyle="steps-mid", color="C3",
                  label="cutbacks")
    cost.set_ylabel("substeps" if explicit else "iterations")
    cost.legend(fontsize=7)
    values = [v if v > 0.0 else float("nan") for v in history.get("residual", [])]
    if any(v == v for v in values):  # a number (NaN != NaN)
        residual.semilogy(steps, values, color="C0", **style)
    residual.set_ylabel("relative residual")
    if "wall_time" in history:
        total = history["wall_time"]
        per_step = [b - a for a, b in zip([total[0], *total[:-1]], total, strict=True)]
        wall.plot(steps, per_step, color="C2", **style)
    wall.set_ylabel("wall time (s)")
    wall.set_xlabel("step")
    return fig
