"""history.csv carries what the case applies: the factor of every load curve, the total
force of every load (its curve's factor times its resultant) and every prescribed
displacement (its curve's factor times its value), at every step.

The nominal resultants are computed here from the geometry, not from the solver: a uniform
traction ``t`` on a flat face of area ``A`` has the resultant ``t A``, a pressure ``p`` on
it ``-p A n`` (``n`` the outward normal), gravity ``rho g V``. The consistent nodal forces
sum to these exactly (the shape functions sum to one on every face and element), so the
only differences are the round-off of the sums (about ``n eps`` relative, far below 1e-12)
and the 10 significant digits history.csv writes (half a unit in the 10th digit: 5e-10
relative).
"""

from __future__ import annotations

import numpy as np
import pytest

from fem_frac.app.cli import main
from fem_frac.writers.history import read_history
from solve import write_case

L, B, H = 1.0, 0.2, 0.2  # the box
TRACTION = (0.0, 3.0e4, -1.0e5)  # on xmax, area B H
PRESSURE = 2.0e4  # on ymax, area L H, outward normal +y
RHO, G = 7850.0, (0.0, 0.0, -9.81)
PRESCRIBED = -1.0e-6  # z on zmin
CYCLE = [[0.0, 0.0], [1.0, 1.0], [2.0, -0.5]]
T_END = 2.0

CASE = {
    "mesh": {"geometry": {"type": "box", "lengths": [L, B, H]}, "element_size": 0.1,
             "order": 1},
    "material": {"youngs_modulus": 210e9, "poissons_ratio": 0.3, "density": RHO},
    "boundary_conditions": [
        {"type": "fixed", "boundary": "xmin"},
        {"type": "traction", "boundary": "xmax", "traction": list(TRACTION),
         "curve": "cycle"},
        {"type": "pressure", "boundary": "ymax", "pressure": PRESSURE},  # default: ramp
        {"type": "displacement", "boundary": "zmin", "z": PRESCRIBED, "curve": "cycle"},
    ],
    "body_force": {"gravity": list(G), "curve": "constant"},
    "load_curves": {"cycle": {"type": "table", "points": CYCLE}},
    "analysis": {"type": "quasi_static", "t_end": T_END, "steps": 4},
}

# 10 significant digits: half a unit in the last one, relative
CSV = 5e-10


def cycle(t: float) -> float:
    times, factors = np.array(CYCLE).T
    return float(np.interp(t, times, factors))


def ramp(t: float) -> float:
    return min(max(t / T_END, 0.0), 1.0)


@pytest.fixture(scope="module")
def history(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("loads")
    path = write_case(tmp / "case.yaml", CASE)
    assert main(["run", str(path), "-o", str(tmp / "out"), "-q"]) == 0
    return read_history(tmp / "out" / "history.csv")


def close(column: list[float], expected: np.ndarray, scale: float) -> None:
    """Equal to the 10 digits written, and to ``1e-12 scale`` where the value is zero."""
    column = np.asarray(column)
    assert np.all(np.abs(column - expected) <= CSV * np.abs(expected) + 1e-12 * scale), \
        (column, expected)


def test_every_curve_has_a_column_with_its_factor(history):
    t = np.array(history["time"])
    assert len(t) == 5 and t[-1] == T_END
    close(history["curve_cycle"], np.array([cycle(s) for s in t]), 1.0)
    close(history["curve_ramp"], np.array([ramp(s) for s in t]), 1.0)
    close(history["curve_constant"], np.ones_like(t), 1.0)


def test_the_applied_load_column_equals_the_curve_times_the_load_at_every_step(history):
    """Traction, pressure and gravity: curve(t) times the nominal resultant."""
    t = np.array(history["time"])
    nominal = {
        "xmax": (np.array(TRACTION) * B * H, cycle),
        "ymax": (-PRESSURE * L * H * np.array([0.0, 1.0, 0.0]), ramp),
        "body_force": (RHO * np.array(G) * L * B * H, lambda s: 1.0),
    }
    for label, (force, curve) in nominal.items():
        factor = np.array([curve(s) for s in t])
        scale = np.abs(force).max()
        for k, axis in enumerate("xyz"):
            close(history[f"load_{label}_{axis}"], factor * force[k], scale)


def test_a_prescribed_displacement_column_is_the_curve_times_its_value(history):
    t = np.array(history["time"])
    close(history["prescribed_zmin_z"], PRESCRIBED * np.array([cycle(s) for s in t]),
          abs(PRESCRIBED))
    assert "prescribed_zmin_x" not in history  # x and y of zmin are free
    assert not any(k.startswith("prescribed_xmin") for k in history)  # fixed: zero


def test_two_loads_on_one_boundary_get_a_column_each(tmp_path):
    case = {**CASE, "boundary_conditions": [
        *CASE["boundary_conditions"],
        {"type": "traction", "boundary": "xmax", "traction": [1e3, 0.0, 0.0]}],
        "analysis": {"type": "quasi_static", "t_end": T_END, "steps": 1}}
    path = write_case(tmp_path / "case.yaml", case)
    assert main(["run", str(path), "-o", str(tmp_path / "out"), "-q"]) == 0
    h = read_history(tmp_path / "out" / "history.csv")
    close(h["load_boundary_conditions[4]_x"], np.array([0.0, 1e3 * B * H]), 1e3 * B * H)
    close(h["load_xmax_z"], np.array([0.0, TRACTION[2] * B * H * cycle(T_END)]),
          abs(TRACTION[2]) * B * H)
