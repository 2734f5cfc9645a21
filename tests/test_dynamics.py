"""Time integration: energy of Newmark, stability of central difference, HHT damping, the
energy balance of a plastic dynamic run (DESIGN §6, dynamics)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fem_frac.app.driver import prepare
from fem_frac.config.schema import Case
from fem_frac.errors import CaseError
from fem_frac.solve.state import initial_state
from fem_frac.solve.stepping import ExplicitStepper
from fem_frac.timing import StageTimer
from solve import run

E, NU, RHO = 200e9, 0.3, 7800.0


def beam(analysis: dict, plasticity: dict | None = None, v0: float = 1.0) -> dict:
    """A clamped 1 x 0.1 x 0.1 steel beam set swinging by a uniform initial velocity."""
    case = {
        "mesh": {"geometry": {"type": "box", "lengths": [1.0, 0.1, 0.1]},
                 "element_size": 0.05},
        "material": {"youngs_modulus": E, "poissons_ratio": NU, "density": RHO},
        "boundary_conditions": [{"type": "fixed", "boundary": "xmin"}],
        "analysis": {"type": "dynamic", "initial_velocity": {"uniform": [0, 0, v0]},
                     **analysis},
    }
    if plasticity is not None:
        case["plasticity"] = plasticity
    return case


def energies(case: dict):
    rows = []

    def observe(n, state, ledger, info):
        rows.append((ledger.kinetic, ledger.elastic, ledger.relative_error, ledger.error))

    setup, state, ledger, counters = run(case, observe=observe)
    return setup, np.array(rows), counters


def test_newmark_average_acceleration_conserves_energy_in_free_vibration():
    """Average acceleration conserves the discrete energy of a linear system exactly (its
    amplification matrix is orthogonal in the energy norm); only round-off remains, so
    1e-6 over 1000 steps is a loose bound that still fails for any damping scheme (HHT with
    alpha = -0.05 loses ~3 % over the same run, below)."""
    _, rows, _ = energies(beam({"integrator": "newmark", "dt": 1e-5, "steps": 1000}))
    kinetic, elastic = rows[:, 0], rows[:, 1]
    total = kinetic + elastic
    assert np.max(np.abs(total - total[0])) / total[0] < 1e-6
    # energy really moves between the two forms: a vibration, not a body at rest
    assert kinetic.min() < 0.5 * total[0] and elastic.max() > 0.5 * total[0]


def test_hht_dissipates_and_the_ledger_says_so():
    _, rows, _ = energies(beam({"integrator": "hht", "alpha": -0.05, "dt": 1e-5,
                                "steps": 300}))
    total = rows[:, 0] + rows[:, 1]
    assert total[-1] < 0.995 * total[0]
    # HHT conserves no energy exactly, but it never gains any over the initial state
    assert total.max() <= total[0] * (1 + 1e-9)


def _explicit_setup(factor: float, **analysis):
    """A central-difference setup whose dt is ``factor`` times the estimated stable step."""
    probe = Case.model_validate(beam({"integrator": "central_difference", "dt": 1e-12,
                                      "steps": 1}))
    probe_dir = Path(".")
    limit = prepare(probe, probe_dir, StageTimer()).disc.limit
    case = beam({"integrator": "central_difference", "dt": factor * limit.dt, **analysis})
    return Case.model_validate(case), probe_dir, limit


def test_central_difference_at_0_9_of_the_stable_step_stays_bounded_for_10000_steps():
    case, where, limit = _explicit_setup(0.9, steps=10_000)
    assert limit.method == "lanczos"
    rows = []
    setup, state, ledger, _ = run(case.model_dump(), where,
                                  observe=lambda n, s, led, i: rows.append(
                                      led.kinetic + led.elastic))
    total = np.array(rows)
    # central difference conserves a modified energy: the plain one oscillates by O(dt^2),
    # well inside 10 % at 0.9 of the limit, and does not drift
    assert np.all(np.isfinite(total))
    assert np.max(np.abs(total - total[0])) / total[0] < 0.1
    assert abs(np.mean(total[-1000:]) - np.mean(total[:1000])) / total[0] < 0.01


def test_central_difference_above_the_stable_step_is_refused_and_the_limit_is_sharp():
    with pytest.raises(CaseError) as err:
        _ = run(_explicit_setup(1.1, steps=10)[0].model_dump())
    assert err.value.path == ("analysis", "dt")
    assert "stable step" in err.value.message
    # the estimate is the true limit, not a bound far below it: forced past the refusal,
    # 1.02 x the step diverges (the highest mode grows by ~|lambda| per step)
    case, where, limit = _explicit_setup(0.5, steps=1)
    setup = prepare(case, where, StageTimer())
    d = setup.disc
    stepper = ExplicitStepper(d.problem, d.law, d.ops, 1.02 * limit.dt, 1, d.constrained)
    state = initial_state(d.problem, d.law, d.ops, np.tile([0, 0, 1.0], d.space.n_nodes),
                          d.constrained)
    start = np.abs(state.v).max()
    for n in range(1, 3000):
        state = stepper.step(state, n * 1.02 * limit.dt, n)[0]
        if np.abs(state.v).max() > 1e6 * start:
            break
    assert np.abs(state.v).max() > 1e6 * start


def test_substeps_take_a_step_above_the_limit_in_stable_pieces():
    case, where, limit = _explicit_setup(2.5, steps=200, substeps=True)
    setup, state, ledger, counters = run(case.model_dump(), where)
    assert setup.disc.stepper.substeps == 3
    assert counters.iterations == 3 * 200
    assert ledger.relative_error < 0.1


def test_plastic_impact_balances_energy_to_the_equilibrium_tolerance():
    """With average acceleration and trapezoidal works, kinetic + elastic + plastic work -
    external work is conserved exactly at converged equilibrium (for any material law), so
    the balance error is bounded by the residual left in each step: relative 1e-8 per step
    over 200 steps gives < 1e-6."""
    case = beam({"integrator": "newmark", "dt": 1e-5, "steps": 200,
                 "equilibrium": {"tolerance": 1e-8}},
                plasticity={"yield_stress": 300e6, "hardening": 2e9}, v0=20.0)
    setup, rows, counters = energies(case)
    assert counters.iterations > 200  # plastic steps took iterations
    assert np.max(rows[:, 2]) < 1e-6
    # and the plastic work is a sizeable part of the budget: dissipation really happened
    _, state, ledger, _ = run(case)
    assert ledger.plastic_work > 0.2 * rows[0, 0]


def test_dynamic_analysis_needs_a_density():
    case = beam({"integrator": "newmark", "dt": 1e-5, "steps": 1})
    del case["material"]["density"]
    with pytest.raises(CaseError) as err:
        run(case)
    assert err.value.path == ("material", "density")


def test_consistent_and_lumped_mass_agree_on_the_first_bending_period():
    """Both masses converge to the same frequency; on this mesh they bracket it (consistent
    mass overestimates frequencies, lumped underestimates) and differ by a few percent."""
    periods = {}
    for mass in ("consistent", "lumped"):
        rows = []
        run(beam({"integrator": "newmark", "mass": mass, "dt": 5e-5, "steps": 800}),
            observe=lambda n, s, led, i, rows=rows: rows.append(s.u[2::3].max()))
        tip = np.array(rows)
        crossings = np.flatnonzero((tip[:-1] < 0.5 * tip.max()) & (tip[1:] >= 0.5 * tip.max()))
        periods[mass] = np.diff(crossings).mean() * 5e-5 if len(crossings) > 1 else np.nan
    assert np.isfinite(periods["consistent"]) and np.isfinite(periods["lumped"])
    assert periods["lumped"] >= periods["consistent"]
    assert abs(periods["lumped"] / periods["consistent"] - 1) < 0.1



def test_rayleigh_damping_dissipates_and_the_ledger_accounts_for_it():
    """Average acceleration with trapezoidal damping work balances exactly: the energy the
    beam loses is the damping work, to round-off."""
    case = beam({"integrator": "newmark", "dt": 1e-5, "steps": 300,
                 "rayleigh": {"mass": 50.0, "stiffness": 1e-5}})
    setup, rows, _ = energies(case)
    total = rows[:, 0] + rows[:, 1]
    assert total[-1] < 0.9 * total[0]
    assert np.max(rows[:, 2]) < 1e-9
    _, state, ledger, _ = run(case)
    assert ledger.damping_work == pytest.approx(total[0] - total[-1], rel=1e-9)


def test_damping_shrinks_the_stable_step_of_central_difference():
    from fem_frac.solve.integrators import central_difference_limit

    assert central_difference_limit(1e3) == pytest.approx(2e-3)
    limits = [central_difference_limit(1e3, stiffness_damping=a1) for a1 in (0, 1e-4, 1e-3)]
    assert limits[0] > limits[1] > limits[2] > 0
    # xi = 1 (critical damping of the top mode): (2 / omega)(sqrt 2 - 1)
    assert central_difference_limit(1e3, stiffness_damping=2e-3) == pytest.approx(
        2e-3 * (np.sqrt(2) - 1))
