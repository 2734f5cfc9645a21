"""Cut-back steps and the limit-load rule of the equilibrium iteration.

- ``advance`` halves a step that does not converge, down to ``cutbacks`` levels; its
  failure says how many levels, halvings and sub-steps it tried, the smallest dt and the
  last converged time, and carries that state.
- The sub-steps a cut-back step converged before its end are rows of history.csv
  (``substep`` k >= 1); when the step then fails, the last converged sub-state is also the
  last frame of the series.
- Near a limit load modified Newton switches to full Newton when the residual's
  contraction predicts more iterations than the cap (docs/solvers.md, "Near a limit
  load"): the Hill sphere a fraction of a percent below its mesh's limit load converges in
  a few tens of iterations where modified Newton alone spends 5 x 500 and fails.
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import pytest
from test_cli_errors import BASE

import fem_frac.solve.convergence as convergence
import fem_frac.solve.stepping as stepping
from fem_frac.app.cli import main
from fem_frac.solve.convergence import contraction, iterations_left
from fem_frac.solve.state import StepInfo
from fem_frac.solve.stepping import ImplicitStepper, NotConverged, advance
from fem_frac.writers.history import read_history
from solve import simulate_dict

# --- advance on a stepper that converges only on short steps --------------------------------


@dataclass(frozen=True)
class _State:
    t: float


class _Stepper:
    """Converges a step no longer than ``longest`` and not beyond ``wall``."""

    substeps, problem, law, ops = 1, None, None, None

    def __init__(self, cutbacks: int, longest: float, wall: float = math.inf):
        self.cutbacks, self.longest, self.wall = cutbacks, longest, wall
        self.tried: list[float] = []

    def step(self, old, t, n):
        self.tried.append(t)
        if t - old.t > self.longest * (1 + 1e-12) or t > self.wall:
            raise NotConverged(f"step {n} (t = {t:g}): no")
        return _State(t), StepInfo(1, 0.0)


@pytest.fixture
def no_ledger(monkeypatch):
    monkeypatch.setattr(stepping, "account", lambda ledger, *args: ledger)


def test_cut_back_counts_halvings_not_levels(no_ledger):
    """Two levels (dt down to 1/4) take three halvings here: 1 -> 1/2 -> 1/4, then 1/2 ->
    1/4 again for the second half. Each converged sub-step but the last is reported."""
    stepper, seen = _Stepper(cutbacks=2, longest=0.25), []
    state, _, info = advance(stepper, _State(0.0), 1.0, None, 1,
                             lambda s, ledger, i: seen.append(s.t))
    assert state.t == 1.0 and info.cutbacks == 3 and info.iterations == 4
    assert stepper.tried == [1.0, 0.5, 0.25, 0.5, 1.0, 0.75, 1.0]
    assert seen == [0.25, 0.5, 0.75]


def test_a_cut_back_failure_says_what_it_tried(no_ledger):
    stepper = _Stepper(cutbacks=2, longest=0.25, wall=0.6)
    with pytest.raises(NotConverged) as err:
        advance(stepper, _State(0.0), 1.0, "ledger", 3)
    message = str(err.value)
    assert message == ("step 3 (t = 0.75): no (after 2 levels of cut-back: 3 halvings, 6 "
                       "sub-steps tried down to dt = 0.25; the last converged at t = 0.5; "
                       "the load may exceed what the structure carries)"), message
    assert err.value.converged == (_State(0.5), "ledger")


def test_a_step_that_converges_no_sub_step_carries_none(no_ledger):
    with pytest.raises(NotConverged) as err:
        advance(_Stepper(cutbacks=1, longest=0.1), _State(0.0), 1.0, None, 1)
    assert "after 1 levels of cut-back: 1 halvings, 2 sub-steps tried down to dt = 0.5; " \
        "none converged" in str(err.value)
    assert err.value.converged is None


def test_contraction_rate_and_iterations_left():
    """A residual that falls by 1/2 an iteration needs log2(best / tolerance) more."""
    residuals = [0.5**k for k in range(20)]
    assert contraction(residuals[:19]) is None  # 2 windows needed
    assert contraction(residuals) == pytest.approx(0.5, rel=1e-12)
    assert iterations_left(residuals, 0.5**30) == pytest.approx(11, rel=1e-12)
    assert iterations_left([1.0] * 20, 1e-8) == math.inf  # no progress at all
    assert iterations_left(residuals + [1e-9], 1e-8, 10) == 0.0


# --- sub-steps in the output -----------------------------------------------------------------

# a bar pulled past yield with a stiff hardening: the plastic step needs more iterations of
# plain modified Newton than the cap of 20 allows, its quarters and eighths fewer
PULLED = BASE.replace("[0, 0, -1e5]", "[400e6, 0, 0]") + (
    "plasticity: {yield_stress: 250e6, hardening: 300e9}\n"
    "analysis:\n  type: quasi_static\n  steps: 2\n"
    "  equilibrium: {acceleration: none, max_iterations: MAX}\n")


def _run(tmp_path, text: str, code: int):
    case = tmp_path / "bar.yaml"
    case.write_text(text)
    out = tmp_path / "out"
    assert main(["run", str(case), "-o", str(out), "-q"]) == code
    times = [float(d.get("timestep")) for d in ET.parse(out / "bar.pvd").getroot()
             .iter("DataSet")]
    return read_history(out / "history.csv"), times, json.loads(
        (out / "summary.json").read_text())


def test_converged_sub_steps_are_rows_of_the_history(tmp_path):
    history, times, summary = _run(tmp_path, PULLED.replace("MAX", "20"), 0)
    sub = [k for k, s in enumerate(history["substep"]) if s > 0]
    assert sub, history["substep"]
    assert history["step"][-1] == 2 and history["substep"][-1] == 0  # the step's own row
    assert all(history["step"][k] == 2 for k in sub)
    assert history["substep"][sub[0]:sub[-1] + 1] == list(range(1, len(sub) + 1))
    t = [history["time"][k] for k in sub]
    assert 0.5 < t[0] and all(a < b for a, b in zip(t, t[1:], strict=False)) and t[-1] < 1.0
    assert all(history["iterations"][k] <= 20 for k in sub)
    # the step's row adds up its sub-steps' costs; its cut-backs are halvings
    assert history["iterations"][-1] >= sum(history["iterations"][k] for k in sub)
    assert history["cutbacks"][-1] >= 1 and summary["analysis"]["cutbacks"] >= 1
    assert times == [0.0, 0.5, 1.0]  # the series holds the steps only


def test_a_step_that_fails_after_sub_steps_keeps_the_last_converged_state(tmp_path):
    history, times, summary = _run(tmp_path, PULLED.replace("MAX", "16"), 3)
    last = float(summary["message"].split("the last converged at t = ")[1].split(";")[0])
    assert 0.5 < last < 1.0
    assert history["step"][-1] == 2 and history["substep"][-1] >= 1
    assert history["time"][-1] == pytest.approx(last, rel=1e-6)
    assert times[-1] == pytest.approx(last, rel=1e-6)  # written as the series' last frame
    assert summary["status"] == "failed" and summary["step"] == 1
    assert summary["stopped_at"] == {"step": 2, "stage": "equilibrium"}


# --- near a limit load ------------------------------------------------------------------------

A, B, SIGMA_Y = 1.0, 2.0, 240.0
P_LIMIT = 2.0 * SIGMA_Y * math.log(B / A)  # Hill: the whole wall flows


def sphere(fraction: float) -> dict:
    """The octant of Hill's thick sphere (P2, coarse), its inner pressure ramped to
    ``fraction`` of the exact limit load over 5 steps, default equilibrium settings."""
    return {
        "units": "mm-N-s",
        "mesh": {"geometry": {"type": "hollow_sphere", "inner_radius": A, "outer_radius": B,
                              "sector": "octant"}, "element_size": 0.5, "order": 2},
        "material": {"youngs_modulus": 210e3, "poissons_ratio": 0.3},
        "plasticity": {"yield_stress": SIGMA_Y},
        "boundary_conditions": [{"type": "symmetry", "boundary": f"symmetry_{a}"}
                                for a in "xyz"]
        + [{"type": "pressure", "boundary": "inner", "pressure": fraction * P_LIMIT}],
        "analysis": {"type": "quasi_static", "steps": 5},
    }


@pytest.fixture
def counted(monkeypatch):
    """Every equilibrium iteration of every attempt, cut-back or not."""
    calls = []
    converged = ImplicitStepper._converged

    def count(self, *args):
        calls.append(1)
        return converged(self, *args)

    monkeypatch.setattr(ImplicitStepper, "_converged", count)
    return calls


# A displacement-based mesh overestimates the collapse load: this one carries 1.006 p_L and
# not 1.008 p_L (full Newton: a singular tangent, i.e. a mechanism, at 1.008), so 1.006 p_L
# is within 0.2 % of its own limit load.
NEAR = 1.006


def test_near_the_limit_load_modified_newton_switches_to_full_newton(counted):
    steps = []
    setup, world, tally = simulate_dict(
        sphere(NEAR), observe=lambda n, s, ledger, seen: steps.append(seen))
    last = steps[-1]
    assert last.cutbacks == 0 and last.factorizations >= 1  # full Newton's tangents
    assert last.iterations <= 2 * convergence.RATE_WINDOW + 20, last
    assert len(counted) == tally.iterations  # nothing tried in vain
    assert tally.iterations < 120 and tally.max_residual <= 1e-8


def test_without_the_rule_modified_newton_spends_its_cap_and_fails(counted, monkeypatch):
    monkeypatch.setattr(convergence, "RATE_WINDOW", 10**9)
    with pytest.raises(NotConverged) as err:
        simulate_dict(sphere(NEAR))
    assert "500 iterations of modified_newton" in str(err.value)
    assert "after 4 levels of cut-back" in str(err.value)
    assert len(counted) > 5 * 500


def test_beyond_the_limit_load_the_rule_gives_up_early(counted):
    """No equilibrium at 1.02 p_L: every attempt stops within a few tens of iterations
    (full Newton finds the mechanism) instead of 500."""
    with pytest.raises(NotConverged) as err:
        simulate_dict(sphere(1.02))
    message = str(err.value)
    assert "full Newton from iteration" in message and "after 4 levels of cut-back" in message
    attempts = int(message.split(" sub-steps tried")[0].rsplit(" ", 1)[1])
    assert len(counted) < attempts * 4 * convergence.RATE_WINDOW + 100, (len(counted), attempts)
