"""Text for people: the ``check`` report and the resolved copy of a case."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from .. import __version__
from ..cohesive.interface import least_stiffness
from ..cohesive.law import M as EXPONENTIAL_M
from ..config.loader import Source
from ..config.schema import Case, DynamicAnalysis
from ..fem.loads import facet_basis
from ..mesh.build import build_mesh, mesh_file_path
from ..mesh.mesh import min_dihedral_angles
from ..mesh.selection import boundary_names, box_face_area, box_facets, in_box, named_facets
from ..rigid.obstacle_output import describe
from ..rigid.obstacles import build_obstacles
from ..solve.discretization import check_model, model_on
from ..solve.loading import time_grid
from ..solve.problem import outer_facets
from ..timing import StageTimer
from .driver import check_stages, interface_recipe, recipe_of
from .initial import check_initial, describe_initial
from .locking import element_notes, locking_warnings
from .plan import format_plan, make_plan

# Tets with a smaller minimum dihedral angle than this are reported as poorly shaped.
POOR_DIHEDRAL_DEG = 10.0


def _area(space, triples: np.ndarray) -> float:
    """Area of boundary faces, curved ones included (quadrature on the facet basis)."""
    return float(facet_basis(space, space.facet_indices(triples)).dx.sum())


def check_report(case: Case, source: Source) -> str:
    """Validate, mesh and resolve supports and loads; describe the result. No solve."""
    timer = StageTimer()
    check_stages(case)
    check_initial(case, source.path.parent)
    with timer("mesh"):
        mesh = build_mesh(case.mesh, source.path.parent)
    recipe = recipe_of(case, time_grid(case.analysis).dt)
    space, materials, problem = model_on(recipe, mesh, timer)
    check_model(recipe, space, materials, problem)
    angles = min_dihedral_angles(mesh.points, mesh.tets)
    lo, hi = mesh.points.min(axis=0), mesh.points.max(axis=0)
    volume = float(space.basis.dx.sum())
    lines = [
        f"case        {source.path}: valid" + (f" ({case.title})" if case.title else ""),
        f"units       {case.units}",
        f"mesh        {mesh.n_tets:,} tets, {mesh.n_points:,} vertices, "
        f"{space.n_nodes:,} nodes (P{space.order}), {space.n_dofs:,} dofs "
        f"({timer.seconds['mesh']:.2f} s)",
        f"            volume {volume:.6g}, bounding box {np.array2string(lo, precision=4)} "
        f"to {np.array2string(hi, precision=4)}",
        f"quality     minimum dihedral angle {angles.min():.2f} deg "
        f"(median {np.median(angles):.1f}); "
        f"{np.count_nonzero(angles < POOR_DIHEDRAL_DEG)} tets below {POOR_DIHEDRAL_DEG:g} deg",
        "boundaries",
    ]
    for name in boundary_names(mesh):
        triples = named_facets(mesh, name)
        area = _area(space, triples)
        lines.append(f"  {name:<18} {len(triples):>8,} faces   area {area:.6g}")
    if case.regions:
        lines.append("regions")
        for i, (region, count) in enumerate(zip(case.regions, materials.counts,
                                                strict=True)):
            where = (f"subdomain {region.subdomain}" if region.subdomain is not None
                     else f"box {list(region.box.min)} to {list(region.box.max)}")
            values = ", ".join(f"{k} {v:g}" for k, v in region.model_dump(
                include={"youngs_modulus", "poissons_ratio", "density"}).items()
                if v is not None)
            lines.append(f"  [{i}] {where}: {count:,} tets; {values}")
    lines += _material_lines(case, space, materials)
    lines.append("supports and loads")
    lines += [f"  {d}" for d in problem.descriptions] or ["  (none)"]
    lines += _selection_lines(case, mesh, space)
    lines += _load_lines(case, space, materials, problem)
    initial = describe_initial(case, space, problem, source.path.parent)
    if initial is not None:
        lines.append(f"initial     {initial}")
    lines += _element_lines(case, mesh, materials, problem)
    if case.fracture is not None:
        lines += _fracture_lines(case, mesh, materials)
    if isinstance(case.analysis, DynamicAnalysis):
        lines += _time_step_lines(recipe, space, materials, problem)
    lines += _obstacle_lines(case, source.path.parent) + ["plan"]
    lines.append(format_plan(make_plan(case)))
    return "\n".join(lines)


def _element_lines(case: Case, mesh, materials, problem) -> list[str]:
    """Warnings of elements that will be too stiff, and notes where another element is the
    better buy (:mod:`~fem_frac.app.locking`)."""
    warnings = locking_warnings(case, mesh, materials, problem)
    notes = element_notes(case, materials)
    if not warnings and not notes:
        return []
    return (["locking" if warnings else "elements"] + [f"  warning: {t}" for t in warnings]
            + [f"  note: {t}" for t in notes])


def _obstacle_lines(case: Case, case_dir: Path) -> list[str]:
    """The obstacles, one a line: kind, size, centre, mass and initial motion."""
    obstacles = build_obstacles(case.obstacles, case_dir, case.fragments is not None)
    return ["obstacles", *(f"  {describe(o)}" for o in obstacles)] if obstacles else []


def _material_lines(case: Case, space, materials) -> list[str]:
    """The material's constants (and plasticity's), and the mass they give the mesh."""
    m = case.material
    values = f"E {m.youngs_modulus:.6g}, nu {m.poissons_ratio:g}"
    if m.density is not None:
        values += f", density {m.density:.6g}"
    lines = ["material", f"  {values}"]
    if materials.has_density():
        rho = np.asarray(materials.density, dtype=float)
        mass = float(np.sum(space.basis.dx.sum(axis=1) * rho)) if rho.ndim else float(
            rho * space.basis.dx.sum())
        lines.append(f"  mass {mass:.6g}" + (" (with regions)" if case.regions else ""))
    p = case.plasticity
    if p is not None:
        lines.append(f"  plasticity {p.model}: yield stress {p.yield_stress:.6g}, "
                     f"hardening {p.hardening:.6g}, kinematic hardening "
                     f"{p.kinematic_hardening:.6g}")
    return lines


def _selection_lines(case: Case, mesh, space) -> list[str]:
    """The faces each box of a support or load selects (by centroid) and their area; for
    a flat box, the area of the box's own face beside it."""
    boxes = [(i, bc) for i, bc in enumerate(case.boundary_conditions) if bc.box is not None]
    nodal = [(i, bc) for i, bc in enumerate(case.boundary_conditions)
             if getattr(bc, "vertices", None) is not None]
    lines = []
    for i, bc in nodal:
        count = int(in_box(mesh, space.node_points, bc.vertices.min, bc.vertices.max).sum())
        lines.append(f"  boundary_conditions[{i}] {bc.type}: {count:,} nodes in the box "
                     "'vertices'")
    if lines:
        lines.insert(0, "vertex selections (nodes in the box)")
    if not boxes:
        return lines
    exterior = outer_facets(mesh)
    lines.append("box selections (faces whose centroid lies in the box)")
    for i, bc in boxes:
        lo, hi = bc.box.min, bc.box.max
        triples = box_facets(mesh, lo, hi, exterior)
        area = _area(space, triples) if len(triples) else 0.0
        line = (f"  boundary_conditions[{i}] {bc.type}: {len(triples):,} faces   "
                f"area {area:.6g}")
        own = box_face_area(mesh, lo, hi)
        if own:
            line += f"; the box's face {own:.6g} ({100.0 * area / own:.0f} % of it)"
        lines.append(line)
    return lines


def _load_lines(case: Case, space, materials, problem) -> list[str]:
    """The total force of every surface load at the peak of its curve, and gravity's."""
    from ..config.schema import Pressure, Traction
    from ..fem.loads import surface_load
    from ..solve.loading import default_curve

    grid = time_grid(case.analysis)
    exterior = outer_facets(space.mesh)
    lines = []
    for i, bc in enumerate(case.boundary_conditions):
        if not isinstance(bc, Traction | Pressure):
            continue
        triples = (box_facets(space.mesh, bc.box.min, bc.box.max, exterior)
                   if bc.box is not None else named_facets(space.mesh, bc.boundary, exterior))
        facets = space.facet_indices(triples)
        value = ({"traction": bc.traction} if isinstance(bc, Traction)
                 else {"pressure": bc.pressure})
        total = surface_load(space, facets, **value).reshape(-1, 3).sum(axis=0)
        name = bc.curve or default_curve(case.analysis)
        factor, when = _peak(case, problem, name, grid)
        label = bc.boundary if bc.boundary is not None else f"boundary_conditions[{i}]"
        lines.append(f"  {bc.type} on {label}: total force {_vector(factor * total)} at the "
                     f"peak of curve {name} (factor {factor:g} at t = {when:.6g})")
    if case.body_force is not None and materials.has_density():
        rho = np.asarray(materials.density, dtype=float)
        cells = space.basis.dx.sum(axis=1)
        mass = float(np.sum(cells * rho)) if rho.ndim else float(rho * cells.sum())
        g = np.asarray(case.body_force.gravity, dtype=float)
        name = case.body_force.curve or default_curve(case.analysis)
        factor, when = _peak(case, problem, name, grid)
        lines.append(f"  gravity {_vector(g)}: weight {_vector(factor * mass * g)} at the "
                     f"peak of curve {name} (factor {factor:g} at t = {when:.6g})")
    return ["load magnitudes"] + lines if lines else []


def _peak(case: Case, problem, name: str, grid) -> tuple[float, float]:
    """The factor of curve ``name`` largest in size over the run, and when: at the steps'
    times and a table's own points within the run."""
    curve = problem.curves[problem.curve_names.index(name)]
    times = [grid.time(n) for n in range(grid.steps + 1)]
    table = case.load_curves.get(name)
    if table is not None and table.type == "table":
        times += [t for t, _ in table.points if 0.0 <= t <= grid.t_end]
    values = np.array([float(curve(t)) for t in times])
    k = int(np.argmax(np.abs(values)))
    return float(values[k]), float(times[k])


def _vector(v) -> str:
    """``(x, y, z)`` to 4 digits, round-off below 1e-9 of the largest component as 0."""
    v = np.asarray(v, dtype=float)
    v = np.where(np.abs(v) < 1e-9 * np.abs(v).max(initial=0.0), 0.0, v)
    return "(" + ", ".join(f"{x:.4g}" for x in v) + ")"


def _time_step_lines(recipe, space, materials, problem) -> list[str]:
    """Explicit: the stable step of central difference and how the case's dt compares.
    Implicit: its stability, then that step as a note for comparison only (it does not limit
    the run)."""
    from ..fem.mass import lumped_mass
    from ..plasticity.law import material_law
    from ..solve.constrained import Constrained
    from ..solve.discretization import build_operators, explicit_substeps
    from ..solve.stable_step import stable_limit

    analysis = recipe.analysis
    ops = build_operators(recipe, space, materials, material_law(materials, None),
                          StageTimer())
    limit = stable_limit(space, ops.stiffness, lumped_mass(space, materials.density),
                         Constrained(problem, "auto").free, materials, analysis.rayleigh)
    dt = recipe.dt
    step = (f"stable step of central difference {limit.dt:.4g} "
            f"({limit.method}; element bound {limit.element_bound_dt:.4g})")
    if analysis.integrator != "central_difference":
        return [f"time step   dt {dt:.4g}: {_implicit_note(analysis)}",
                f"            note, for comparison only (it does not limit this implicit "
                f"run): {step}; dt is {dt / limit.dt:.3g} times it"]
    substeps = explicit_substeps(limit, dt, analysis.substeps)  # refuses as run does
    verdict = (f"; dt {dt:.4g} is {dt / limit.dt:.3g} of it" if substeps == 1
               else f"; dt {dt:.4g} runs as {substeps} substeps")
    return [f"time step   {step}{verdict}"]


def _implicit_note(analysis) -> str:
    """Whether an implicit integrator has a stable-step limit."""
    if analysis.integrator == "hht":
        return (f"implicit hht (alpha {analysis.alpha:g}), unconditionally stable: no "
                "step limit, dt is chosen for accuracy")
    beta, gamma = analysis.newmark_beta, analysis.newmark_gamma
    if 2.0 * beta >= gamma:
        return (f"implicit newmark (beta {beta:g}, gamma {gamma:g}), unconditionally "
                "stable: no step limit, dt is chosen for accuracy")
    return (f"implicit newmark (beta {beta:g}, gamma {gamma:g}), only conditionally "
            "stable (2 beta < gamma): its own step limit is not computed")


def resolved_case(case: Case, source: Source, directory: Path, name: str) -> Case:
    """``case`` made self-contained: absolute mesh file paths (the mesh's, the obstacles')
    and the actual output place."""
    mesh = case.mesh
    if mesh.file is not None:
        path = mesh_file_path(mesh, source.path.parent).resolve()
        mesh = mesh.model_copy(update={"file": str(path)})
    obstacles = [o.model_copy(update={"file": str((source.path.parent / Path(o.file)
                                                   .expanduser()).resolve())})
                 if o.type == "mesh" else o for o in case.obstacles]
    output = case.output.model_copy(update={"directory": str(directory), "name": name})
    return case.model_copy(update={"mesh": mesh, "output": output, "obstacles": obstacles})


def resolved_yaml(case: Case, source: Source) -> str:
    """The case with every default filled in, as YAML, headed by where it came from."""
    from ruamel.yaml import YAML

    yaml = YAML(typ="rt")
    yaml.default_flow_style = None
    buffer = io.StringIO()
    yaml.dump(case.model_dump(mode="json", exclude_none=True), buffer)
    header = [f"# resolved by fem-frac {__version__} from {source.path}"]
    header += [f"# --set {text}" for text in source.overrides.values()]
    return "\n".join(header) + "\n" + buffer.getvalue()


def _fracture_lines(case: Case, mesh, materials) -> list[str]:
    """The protected vertices (names and boxes checked here) and the smoothing size; with a
    fracture energy, the cohesive law and how the mesh resolves its length."""
    from ..fracture.smoothing import mean_edge_length
    from ..fracture.stage import protected_vertices

    f = case.fracture
    protected = protected_vertices(f, mesh)
    edge = mean_edge_length(mesh.points, mesh.tets)
    s = f.smoothing
    size = (f"length {s.length:g} = {s.length / edge:.2f} mean edge lengths"
            if s.length is not None else f"{s.rings} ring(s) of neighbours")
    lines = ["fracture",
             f"  tensile strength {f.tensile_strength:g}; smoothing {s.method}, {size} "
             f"(mean edge {edge:.4g})",
             f"  {np.count_nonzero(protected):,} of {mesh.n_points:,} vertices protected"
             + (" or off the crack planes" if f.planes else "")]
    if f.planes:
        lines += _plane_lines(f, mesh)
    if f.fracture_energy is not None:
        lines += _cohesive_lines(case, mesh, materials, protected)
    return lines


def _plane_lines(f, mesh) -> list[str]:
    """How many vertices of each prescribed crack plane may split, and how many elements
    cross it (where a plane is no mesh surface no crack can follow it)."""
    from ..fracture.planes import plane_sites

    lines = []
    for i, plane in enumerate(f.planes):
        sites = plane_sites(mesh.points, mesh.tets, [plane])
        lines.append(f"  crack plane {i} through {list(plane.point)}, normal "
                     f"{list(plane.normal)}: {np.count_nonzero(sites.usable):,} vertices "
                     f"may split, {np.count_nonzero(sites.crossing):,} elements cross it")
        if not sites.usable.any():
            lines.append(f"  warning: crack plane {i} holds no vertex that may split: no "
                         "crack can open in it (is it a mesh surface?)")
    return lines


# Units of the fracture energy and of lengths, by the case's ``units``.
_UNITS = {"SI": ("J/m^2", "m"), "mm-N-s": ("N/mm", "mm")}


def _element_sizes(mesh) -> np.ndarray:
    """``(n_tets,)`` mean length of each tet's six edges."""
    from ..mesh.mesh import TET_EDGES

    x = mesh.points[mesh.tets[:, TET_EDGES]]  # (n_tets, 6, 2, 3)
    return np.linalg.norm(x[:, :, 1] - x[:, :, 0], axis=2).mean(axis=1)


def _critical_opening(law, k0: float) -> str:
    """Where the law's traction reaches zero (``law``: a TractionSeparation), at the
    initial stiffness ``k0`` for the exponential law, whose end depends on it."""
    linear = 2.0 * law.energy / law.strength
    if law.kind == "linear":
        return f"critical opening 2 G_c / sigma_t = {linear:.4g}"
    return (f"critical opening lambda_0 + {EXPONENTIAL_M:g} ell = "
            f"{float(law.critical_opening(k0)):.4g} for the median "
            f"k0 {k0:.4g} (2 G_c / sigma_t = {linear:.4g})")


def _cohesive_lines(case: Case, mesh, materials, protected: np.ndarray) -> list[str]:
    """The cohesive law; its length l_cz = E G_c / sigma_t^2 (smallest E of the body) and
    the size of the elements where cracks can run (a vertex that may split) beside it."""
    f, law = case.fracture, case.fracture.cohesive_law
    energy_unit, length_unit = _UNITS[case.units]
    sigma, gc = f.tensile_strength, f.fracture_energy
    e = np.broadcast_to(np.asarray(materials.youngs_modulus, dtype=float), (mesh.n_tets,))
    free = ~protected[mesh.tets].all(axis=1)  # a site splits one unprotected vertex
    sizes = _element_sizes(mesh)
    h, e_free = (sizes[free], e[free]) if free.any() else (sizes, e)
    median, largest = float(np.median(h)), float(h.max())
    # the median of k0 as the interface sets it (penalty E / h, floored)
    faces = interface_recipe(f).law
    k0 = max(float(np.median(law.penalty * e_free / h)), least_stiffness(faces))
    uniform = bool(np.all(e == e[0]))
    lcz = float(e.min()) * gc / sigma**2
    lines = [f"  cohesive   {law.law} law, G_c = {gc:.4g} {energy_unit}, "
             f"{_critical_opening(faces, k0)}, shear weight {law.shear_weight:g}, "
             f"initial stiffness {law.penalty:g} x E / h",
             "  crack fronts checked against " + (
                 "each element's own stress (front_stress: element)"
                 if law.front_stress == "element" else "the smoothed stress"),
             f"  cohesive length l_cz = E G_c / sigma_t^2 = {lcz:.4g} {length_unit}"
             + ("" if uniform else " (with the smallest E of the regions)")]
    if not free.any():
        return lines + ["  every vertex is protected: no crack can run"]
    lines.append(f"  where cracks can run ({np.count_nonzero(free):,} elements with a "
                 f"vertex free to split): element size median {median:.4g}, max {largest:.4g} "
                 f"{length_unit}; l_cz / h = {lcz / median:.3g} and {lcz / largest:.3g}")
    # each material apart, by its own E (one group when the body is uniform)
    worst = None
    for value in np.unique(e_free):
        mine = h[e_free == value]
        own, size = value * gc / sigma**2, float(np.median(mine))
        if not uniform:
            lines.append(f"  E {value:.4g}: l_cz {own:.4g} {length_unit}, {len(mine):,} "
                         f"elements, size median {size:.4g}, l_cz / h = {own / size:.3g}")
        if worst is None or own / size < worst[0] / worst[1]:
            worst = own, size, value
    own, size, value = worst
    if size > own / 2.0:
        which = "" if uniform else f", E {value:.4g}"
        lines.append(f"  warning: the mesh cannot resolve the cohesive zone (median element "
                     f"size {size:.4g} > l_cz / 2 = {own / 2:.4g} {length_unit}{which}): the "
                     f"peak load and the crack path will depend on the mesh; use elements of "
                     f"size <= {own / 2:.4g} (l_cz / 2), better {own / 4:.4g} (l_cz / 4), "
                     f"where cracks run")
    return lines
