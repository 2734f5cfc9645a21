"""Load curves and the time grid."""

from __future__ import annotations

import numpy as np
import pytest

from fem_frac.config import schema
from fem_frac.errors import CaseError
from fem_frac.fem.space import build_space
from fem_frac.mesh import Mesh
from fem_frac.solve.loading import make_curve, resolve_curves, time_grid
from fem_frac.solve.problem import build_problem
from meshes import structured_box


def quasi(**kw):
    return schema.QuasiStaticAnalysis(type="quasi_static", **kw)


def test_ramp_table_and_constant_curves():
    ramp = make_curve(schema.RampCurve(type="ramp", t_start=1.0, t_end=3.0, value=2.0), 10.0)
    assert [ramp(t) for t in (0.0, 1.0, 2.0, 3.0, 5.0)] == [0.0, 0.0, 1.0, 2.0, 2.0]
    default_end = make_curve(schema.RampCurve(type="ramp"), 4.0)
    assert default_end(1.0) == 0.25 and default_end(8.0) == 1.0
    table = make_curve(schema.TableCurve(type="table", points=[(1, 2), (2, -2)]), 1.0)
    assert [table(t) for t in (0.0, 1.5, 3.0)] == [2.0, 0.0, -2.0]
    assert make_curve(schema.ConstantCurve(type="constant", value=3.0), 1.0)(7.0) == 3.0


def test_time_grid_shortens_dt_to_divide_the_end_time():
    g = time_grid(quasi(t_end=1.0, dt=0.3))
    assert g.steps == 4 and g.dt == pytest.approx(0.25) and g.time(4) == 1.0
    assert time_grid(quasi(steps=5)).t_end == 1.0
    assert time_grid(quasi(dt=0.1, steps=3)).t_end == pytest.approx(0.3)
    exact = time_grid(quasi(t_end=1.0, dt=0.1))
    assert exact.steps == 10  # 1.0 / 0.1 is 10.000000000000002 in floating point
    assert time_grid(schema.StaticAnalysis()).steps == 1


def test_unknown_curve_is_a_located_error_and_defaults_follow_the_analysis():
    with pytest.raises(CaseError) as err:
        resolve_curves([(("boundary_conditions", 2, "curve"), "pulse")], {}, quasi(steps=2))
    assert err.value.path == ("boundary_conditions", 2, "curve")
    names, _, index = resolve_curves([(("a",), None), (("b",), "constant")], {}, quasi(steps=2))
    assert names == ["ramp", "constant"] and index.tolist() == [0, 1]
    dynamic = schema.DynamicAnalysis(type="dynamic", dt=1.0, steps=2)
    assert resolve_curves([(("a",), None)], {}, dynamic)[0] == ["constant"]


def test_loads_and_prescribed_values_scale_with_their_own_curves():
    """Two loads on two curves and a prescribed displacement on a third; the last condition
    on a dof wins, with its curve."""
    mesh: Mesh = structured_box((2, 2, 2))
    mesh = Mesh(mesh.points, mesh.tets, boundaries={
        "xmin": _faces(mesh, 0, 0.0), "xmax": _faces(mesh, 0, 1.0)})
    space = build_space(mesh, 1)
    conditions = [
        schema.Fixed(type="fixed", boundary="xmin"),
        schema.Displacement(type="displacement", boundary="xmin", x=0.01, curve="half"),
        schema.Traction(type="traction", boundary="xmax", traction=(0, 0, -1.0)),
        schema.Pressure(type="pressure", boundary="xmax", pressure=2.0, curve="constant"),
    ]
    curves = {"half": schema.ConstantCurve(type="constant", value=0.5)}
    problem = build_problem(space, conditions, None, None, quasi(t_end=2.0, steps=4), curves)
    x_dofs = problem.constraints.dofs % 3 == 0
    assert np.allclose(problem.prescribed(1.0)[x_dofs], 0.005)
    assert np.allclose(problem.prescribed(1.0)[~x_dofs], 0.0)
    total = problem.external_force(1.0).reshape(-1, 3).sum(axis=0)
    # traction ramps (half of -1 on a unit face at t = 1 of 2), pressure is constant (-x
    # push on the xmax face: force -2 in x)
    np.testing.assert_allclose(total, [-2.0, 0.0, -0.5], atol=1e-12)


def _faces(mesh: Mesh, axis: int, value: float) -> np.ndarray:
    from fem_frac.mesh.mesh import exterior_facets

    faces = exterior_facets(mesh.tets)
    on = np.all(np.isclose(mesh.points[faces][:, :, axis], value), axis=1)
    return faces[on]


@pytest.mark.parametrize(
    "kw,key,words",
    [
        (dict(t_end=1e100, dt=1e-100), "dt", "more than"),
        (dict(dt=1e-320, steps=2), "dt", "outside"),
        (dict(t_end=1e-200, steps=2), "t_end", "outside"),
    ],
)
def test_time_grid_refuses_steps_no_arithmetic_survives(kw, key, words):
    with pytest.raises(CaseError, match=words) as err:
        time_grid(quasi(**kw))
    assert err.value.path == ("analysis", key)


def test_a_ramp_that_never_starts_is_refused_and_never_divides_by_zero():
    late = schema.RampCurve(type="ramp", t_start=1.0)
    with pytest.raises(CaseError, match="never act") as err:
        resolve_curves([(("boundary_conditions", 0, "curve"), "late")], {"late": late},
                       quasi(steps=2))
    assert err.value.path == ("load_curves", "late", "t_start")
    step = make_curve(late, 1.0)  # its own end is the analysis's: no span
    assert [step(t) for t in (0.5, 1.0)] == [0.0, 1.0]
