"""The state a case starts from: at rest, moving with ``analysis.initial_velocity``, and
displaced by ``analysis.initial_displacement`` (a static preload released at t = 0+, a
field of expressions, or the last state of an earlier run)."""

from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from ..config.schema import Case, DynamicAnalysis
from ..errors import CaseError
from ..solve.initial import (
    check_supports,
    displaced_state,
    field_displacement,
    preload_problem,
    preloaded,
)
from ..solve.problem import free_rigid_modes
from ..solve.state import State, initial_state

KEY = ("analysis", "initial_displacement")
# Nodes of the case and points of an earlier run's output are the same point when closer
# than this fraction of the mesh's bounding-box diagonal (both are written in float64).
MATCH_TOLERANCE = 1e-9


def initial_velocity(space, spec) -> np.ndarray | None:
    """Nodal velocity ``(n_dofs,)`` of a uniform motion plus a rigid rotation."""
    if spec is None:
        return None
    x = space.node_points
    center = np.asarray(spec.center) if spec.center is not None else x.mean(axis=0)
    v = np.asarray(spec.uniform) + np.cross(np.asarray(spec.angular_velocity), x - center)
    return v.ravel()


def displacement_spec(case: Case):
    """The case's ``initial_displacement``, ``None`` when it starts undeformed."""
    analysis = case.analysis
    return analysis.initial_displacement if isinstance(analysis, DynamicAnalysis) else None


def check_initial(case: Case, case_dir: Path) -> None:
    """What an initial displacement needs of the rest of the case (located errors), before
    meshing."""
    spec = displacement_spec(case)
    if spec is None:
        return
    if case.fragments is not None and case.fragments.whole_body:
        raise CaseError(KEY, "fragments.whole_body makes the body rigid from the start: it "
                        "has no deformation to start from (drop one of the two)")
    if spec.from_run is not None:
        if case.plasticity is not None:
            raise CaseError(KEY + ("from_run",), "an earlier run's plastic state is not "
                            "carried over (only displacement and velocity): not with "
                            "plasticity")
        run_series(case_dir, spec.from_run)


def first_state(case: Case, disc, case_dir: Path) -> State:
    """The state at t = 0 of a dynamic case on ``disc`` (with inertia)."""
    analysis, d = case.analysis, disc
    spec = displacement_spec(case)
    v0 = initial_velocity(d.space, analysis.initial_velocity)
    if spec is None:
        return initial_state(d.problem, d.law, d.ops, v0, d.constrained)
    if spec.preload is not None:
        return _released(case, d, v0)
    if spec.field is not None:
        u0 = field_displacement(d.space, spec.field, KEY + ("field",))
        check_supports(u0, d.problem, KEY + ("field",))
    else:
        u0, v_run = run_state(case_dir, spec.from_run, d.space)
        check_supports(u0, d.problem, KEY + ("from_run",))
        v0 = v_run if v_run is not None else v0
    return displaced_state(d.problem, d.law, d.ops, d.constrained, u0, v0)


def describe_initial(case: Case, space, problem, case_dir: Path) -> str | None:
    """The initial displacement in words (``None``: undeformed), after the checks a run
    makes of it before its first step (the field meets the supports, the earlier run's
    frame matches the mesh; the preload's supports hold the body)."""
    spec = displacement_spec(case)
    if spec is None:
        return None
    if spec.preload is not None:
        pre = spec.preload
        own = _preload(space, pre, None, problem)
        _held(space, own)
        what = "; ".join(d.replace(", curve ramp", "") for d in own.descriptions)
        loads = " with the case's loads at t = 0" if pre.case_loads else ""
        return (f"static preload ({what}){loads} in {pre.steps} load step(s), removed at "
                "t = 0+")
    if spec.field is not None:
        u0 = field_displacement(space, spec.field, KEY + ("field",))
        check_supports(u0, problem, KEY + ("field",))
        text = f"field u = ({spec.field.x}, {spec.field.y}, {spec.field.z})"
    else:
        u0, _ = run_state(case_dir, spec.from_run, space)
        check_supports(u0, problem, KEY + ("from_run",))
        text = f"last frame of {run_series(case_dir, spec.from_run)}" + (
            " with its velocity" if spec.from_run.velocity else "")
    largest = float(np.abs(u0.reshape(-1, 3)).max(initial=0.0))
    return f"{text}: largest displacement component {largest:.4g}"


def _preload(space, pre, density, problem):
    """The static problem of the preload ``pre``; its conditions' errors located inside
    it."""
    try:
        return preload_problem(space, list(pre.boundary_conditions), density, problem,
                               pre.case_loads)
    except CaseError as exc:
        raise CaseError(KEY + ("preload",) + exc.path, exc.message) from None


def _held(space, problem) -> None:
    free = free_rigid_modes(space, problem.constraints.dofs)
    if free:
        raise CaseError(KEY + ("preload",), "the supports of the case and of the preload "
                        f"leave rigid-body motions free ({', '.join(free)}): the static "
                        "preload is singular; add supports to the preload's "
                        "boundary_conditions")


def _released(case: Case, d, v0) -> State:
    """The equilibrium under the preload, its loads and supports removed at t = 0+."""
    pre = case.analysis.initial_displacement.preload
    problem = _preload(d.space, pre, d.materials.density, d.problem)
    _held(d.space, problem)
    analysis = case.analysis
    start = preloaded(problem, d.law, d.ops, analysis.linear_solver, analysis.equilibrium,
                      pre.steps)
    return displaced_state(d.problem, d.law, d.ops, d.constrained, start.u, v0, start)


def run_series(case_dir: Path, spec) -> Path:
    """The last ``.vtu`` of the series in ``spec.directory`` (relative to the case file),
    or its ``.vtkhdf`` (``output.format: vtkhdf``: the last step is read from it);
    located errors when there is none to read."""
    key = KEY + ("from_run", "directory")
    directory = case_dir / spec.directory
    if not directory.is_dir():
        raise CaseError(key, f"{directory} is no directory (the output directory of an "
                        "earlier run)")
    series = sorted(p for p in directory.glob("*.pvd") if not p.stem.endswith("_crack"))
    hdf = sorted(p for p in directory.glob("*.vtkhdf")
                 if not p.stem.endswith(("_crack", "_obstacles")))
    if not series and len(hdf) == 1:
        return hdf[0]
    if len(series) != 1:
        found = ", ".join(p.name for p in series) or "none"
        raise CaseError(key, f"{directory} holds {len(series)} series (.pvd: {found}); "
                        "one is needed: the output of one run")
    try:
        sets = ElementTree.parse(series[0]).getroot().iter("DataSet")
        last = max(((float(s.get("timestep", "nan")), s.get("file", "")) for s in sets),
                   default=None)
    except (ElementTree.ParseError, ValueError, OSError) as exc:
        raise CaseError(key, f"{series[0]}: unreadable ({exc})") from None
    if last is None or not last[1]:
        raise CaseError(key, f"{series[0]}: lists no frame")
    name = Path(last[1])
    if name.is_absolute() or ".." in name.parts:
        raise CaseError(key, f"{series[0]}: frame {name} lies outside its directory")
    return directory / name


def run_state(case_dir: Path, spec, space) -> tuple[np.ndarray, np.ndarray | None]:
    """Nodal displacement (and velocity, with ``spec.velocity``) ``(n_dofs,)`` of the last
    frame of an earlier run, matched to the nodes of ``space`` by reference coordinates."""
    import meshio

    key = KEY + ("from_run",)
    path = run_series(case_dir, spec)
    try:
        frame = meshio.read(path) if path.suffix != ".vtkhdf" else _last_step(path)
    except Exception as exc:  # noqa: BLE001 (meshio and h5py raise many kinds)
        raise CaseError(key + ("directory",), f"{path}: unreadable ({exc})") from None
    index = _matched(frame.points, space.node_points, key, path)
    fields = ["displacement"] + (["velocity"] if spec.velocity else [])
    out = []
    for name in fields:
        values = frame.point_data.get(name)
        if values is None or np.shape(values) != (len(frame.points), 3):
            raise CaseError(key + (("velocity",) if name == "velocity" else ("directory",)),
                            f"{path} has no point field '{name}' of 3 components")
        values = np.asarray(values, dtype=float)[index].ravel()
        if not np.all(np.isfinite(values)):
            raise CaseError(key + ("directory",), f"{path}: '{name}' is not finite")
        out.append(values)
    return out[0], (out[1] if spec.velocity else None)


def _last_step(path: Path):
    """The last step of a ``.vtkhdf`` series: ``points`` and ``point_data``."""
    from types import SimpleNamespace

    from ..writers.vtkhdf import read_step

    step = read_step(path, -1)
    return SimpleNamespace(points=step["points"], point_data=step["point_data"])


def _matched(points: np.ndarray, nodes: np.ndarray, key: tuple, path: Path) -> np.ndarray:
    """For every node, the one point of ``points`` at its place (refused where there is
    none, or two: a crack's duplicated vertices)."""
    from scipy.spatial import cKDTree

    tolerance = MATCH_TOLERANCE * float(np.linalg.norm(np.ptp(nodes, axis=0)))
    distance, index = cKDTree(points).query(nodes, k=min(2, len(points)))
    distance, index = np.atleast_2d(distance.T).T, np.atleast_2d(index.T).T
    missing = distance[:, 0] > tolerance
    if np.any(missing):
        i = int(np.argmax(missing))
        raise CaseError(key + ("directory",), f"{path}: {np.count_nonzero(missing)} of "
                        f"{len(nodes)} nodes of this mesh have no point there (the first at "
                        f"{np.array2string(nodes[i], precision=6)}): the earlier run's mesh "
                        "and order must be this case's")
    if distance.shape[1] > 1 and np.any(distance[:, 1] <= tolerance):
        raise CaseError(key + ("directory",), f"{path}: two points at one node (a cracked "
                        "body's duplicated vertices): not an initial state of this mesh")
    return index[:, 0]
