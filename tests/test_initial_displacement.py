"""Dynamic runs that start displaced (``analysis.initial_displacement``): a cantilever
deflected by a static tip load and released vibrates in its own modes with the amplitudes
the static deflection has, none injected; started from its first mode it stays in it.

Why the tolerances hold. The modes phi_k (K phi = omega^2 M phi, M-normalized, on the free
dofs of the same mesh) decouple the undamped linear system, and Newmark's average
acceleration is the trapezoidal rule, which conserves v.M v + u.K u exactly for each mode
once the initial acceleration balances the initial state (M a0 = -K u0). So the modal
amplitude A_k = sqrt(q_k^2 + (q'_k / omega_k)^2), q_k = phi_k.M u, q'_k = phi_k.M v, stays
at its value at t = 0 to round-off (and the linear solve's), and q_k(t_n) = q_k(0) cos(n
theta_k) with tan(theta_k / 2) = omega_k dt / 2 (the scheme's period elongation). An
initial acceleration left at zero breaks this in the first step (checked below: the test
can fail). The static deflection under a tip force f is K^-1 f, whose modal coordinates are
q_k = phi_k.f / omega_k^2: its second-mode content A_2 / A_1 at the tip is
(omega_1 / omega_2)^2 |phi_2(tip) / phi_1(tip)|, for an Euler-Bernoulli cantilever
(1.8751 / 4.6941)^4 = 0.0255 (|phi_k(L)| = 2 for every mode normalized over the span);
the 3D beam of depth L / 20 here has omega_2 / omega_1 = 6.2 against 6.27, so 0.026: it
stays below 0.03 for the whole run.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg as sla

from fem_frac.app.cli import main
from fem_frac.config.schema import Traction
from fem_frac.solve.initial import preload_problem
from solve import run, write_case

LENGTH, DEPTH, TIP_LOAD, DT, STEPS = 1.0, 0.05, 1e5, 1e-4, 250
# the second-mode content of a static tip-load deflection: Euler-Bernoulli (1.8751/4.6941)^4
EULER_BERNOULLI_CONTENT = (1.8751 / 4.6941) ** 4
CONTENT_BOUND = 0.03
# conserved modal amplitudes, relative to the first mode's: round-off of ~250 solves
ROUND_OFF = 1e-9

TIP_FORCE = {"type": "traction", "boundary": "xmax", "traction": [0.0, 0.0, -TIP_LOAD]}


def cantilever(start: dict, order: int = 2, steps: int = STEPS) -> dict:
    """A steel cantilever 1 x 0.1 x 0.05, fixed at x = 0, free, started by ``start``."""
    return {
        "mesh": {"geometry": {"type": "box", "lengths": [LENGTH, 0.1, DEPTH]},
                 "element_size": 0.05, "order": order},
        "material": {"youngs_modulus": 2e11, "poissons_ratio": 0.3, "density": 7800},
        "boundary_conditions": [{"type": "fixed", "boundary": "xmin"}],
        "analysis": {"type": "dynamic", "dt": DT, "steps": steps,
                     "initial_displacement": start},
    }


def history(case: dict, case_dir=None):
    """``(setup, u (steps + 1, n_dofs), v)`` of a run of ``case``."""
    seen = []
    kwargs = {"case_dir": case_dir} if case_dir is not None else {}
    setup, _, _, _ = run(case, observe=lambda n, s, ledger, info: seen.append(
        (s.u.copy(), s.v.copy())), **kwargs)
    return setup, np.array([u for u, _ in seen]), np.array([v for _, v in seen])


class Modes:
    """The two lowest bending modes in z of a discretization (M-normalized, free dofs)."""

    def __init__(self, disc):
        self.free = free = disc.constrained.free
        k = disc.ops.stiffness[free][:, free]
        self.mass = disc.ops.mass[free][:, free]
        w2, phi = sla.eigsh(k, k=8, M=self.mass, sigma=0.0, which="LM")
        x = disc.space.node_points
        tip = np.flatnonzero(np.isclose(x[:, 0], LENGTH))
        full = np.zeros((disc.space.n_dofs, phi.shape[1]))
        full[free] = phi
        tips = np.abs(full[3 * tip[:, None] + np.arange(3)].mean(axis=0))  # (3, 8)
        bending = np.flatnonzero(tips[2] > tips[:2].max(axis=0))[:2]  # in frequency order
        self.omega = np.sqrt(w2[bending])
        self.phi = phi[:, bending]
        self.tip = full[3 * tip + 2][:, bending].mean(axis=0)  # phi_k's tip deflection

    def coordinates(self, u: np.ndarray) -> np.ndarray:
        """``q`` (..., 2) of displacements (or velocities) ``(..., n_dofs)``."""
        return u[..., self.free] @ (self.mass @ self.phi)

    def amplitudes(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.hypot(self.coordinates(u), self.coordinates(v) / self.omega)


@pytest.fixture(scope="module")
def released():
    """The cantilever deflected by its static tip load, released at t = 0 (P2)."""
    setup, u, v = history(cantilever({"preload": {"boundary_conditions": [TIP_FORCE]}}))
    return setup, Modes(setup.disc), u, v


def test_a_released_deflected_cantilever_vibrates_in_its_first_mode(released):
    setup, modes, u, v = released
    d = setup.disc
    force = preload_problem(d.space, [Traction.model_validate(TIP_FORCE)],
                            d.materials.density, d.problem, True).external_force(1.0)
    # the initial state is the static deflection: q_k = phi_k.f / omega_k^2, no more
    static = (modes.phi.T @ force[modes.free]) / modes.omega**2
    np.testing.assert_allclose(modes.coordinates(u[0]), static, rtol=1e-8)
    assert not np.any(v[0])
    amplitude = modes.amplitudes(u, v)
    # conserved by the trapezoidal rule, mode by mode: nothing injected at release
    drift = np.abs(amplitude - amplitude[0]).max(axis=0) / amplitude[0, 0]
    assert np.all(drift < ROUND_OFF), drift
    content = amplitude[:, 1] * abs(modes.tip[1]) / (amplitude[:, 0] * abs(modes.tip[0]))
    # (w1/w2)^2 |phi2.f / phi1.f| |phi2(tip) / phi1(tip)|: Euler-Bernoulli's 0.0255 for
    # a point force at the tip, here a traction spread over the end face
    assert content[0] == pytest.approx(abs(static[1] * modes.tip[1])
                                       / abs(static[0] * modes.tip[0]), rel=1e-8)
    assert content[0] == pytest.approx(EULER_BERNOULLI_CONTENT, rel=0.05)
    assert content.max() < CONTENT_BOUND
    # the first mode swings at the scheme's frequency: q1(t_n) = q1(0) cos(n theta_1)
    theta = 2.0 * np.arctan(modes.omega[0] * DT / 2.0)
    q1 = modes.coordinates(u)[:, 0]
    expected = q1[0] * np.cos(theta * np.arange(len(q1)))
    assert np.abs(q1 - expected).max() < ROUND_OFF * abs(q1[0])
    # half a period later the tip is at the opposite extreme
    assert np.argmin(q1 / q1[0]) == pytest.approx(np.pi / theta, abs=1)


def test_a_zero_initial_acceleration_would_inject_the_second_mode(released):
    """The control: the same step from the same displacement with a0 = 0 moves the second
    mode's amplitude by far more than the tolerance above."""
    from dataclasses import replace

    setup, modes, u, _ = released
    d = setup.disc
    first, _ = d.stepper.step(replace(_state0(setup), a=np.zeros_like(u[0])), DT, 1)
    amplitude = modes.amplitudes(first.u, first.v)
    start = modes.amplitudes(u[0], np.zeros_like(u[0]))
    assert abs(amplitude[1] - start[1]) / start[0] > 1e3 * ROUND_OFF


def _state0(setup):
    from fem_frac.app.initial import first_state

    return first_state(setup.case, setup.disc, setup.case_dir)


def test_started_in_the_first_mode_it_stays_there(released, tmp_path):
    """An earlier run's last frame holding the first mode (from_run): its second-mode
    content stays at round-off."""
    import meshio

    setup, modes, _, _ = released
    d = setup.disc
    shape = np.zeros(d.space.n_dofs)
    shape[modes.free] = modes.phi[:, 0] * 1e-3 / modes.tip[0]  # 1 mm at the tip
    earlier = tmp_path / "earlier"
    earlier.mkdir()
    points = d.space.node_points
    meshio.write(earlier / "beam_000001.vtu", meshio.Mesh(
        points, [("vertex", np.arange(len(points))[:, None])],
        point_data={"displacement": shape.reshape(-1, 3)}))
    (earlier / "beam.pvd").write_text(
        '<?xml version="1.0"?>\n<VTKFile type="Collection"><Collection>\n'
        '<DataSet timestep="0.5" file="beam_000001.vtu"/>\n</Collection></VTKFile>\n')
    _, u, v = history(cantilever({"from_run": {"directory": "earlier"}}, steps=60), tmp_path)
    np.testing.assert_allclose(u[0], shape, rtol=0, atol=1e-15)
    amplitude = modes.amplitudes(u, v)
    assert amplitude[:, 1].max() < ROUND_OFF * amplitude[0, 0]
    assert np.abs(amplitude[:, 0] - amplitude[0, 0]).max() < ROUND_OFF * amplitude[0, 0]


def test_a_field_of_expressions_is_evaluated_at_every_node(tmp_path):
    """The Euler-Bernoulli first mode as a field: its values at the nodes (mid-side nodes
    of P2 included), its modal amplitudes conserved like any initial state's."""
    beta = 1.8751040687  # beta L of the first mode
    sigma = (np.cosh(beta) + np.cos(beta)) / (np.sinh(beta) + np.sin(beta))
    start = {"field": {"constants": {"b": beta, "s": sigma, "a": 5e-4},
                       "z": "a * (cosh(b * x) - cos(b * x) - s * (sinh(b * x) - sin(b * x)))"}}
    setup, u, v = history(cantilever(start, steps=40))
    x = setup.disc.space.node_points[:, 0]
    expected = 5e-4 * (np.cosh(beta * x) - np.cos(beta * x)
                       - sigma * (np.sinh(beta * x) - np.sin(beta * x)))
    np.testing.assert_allclose(u[0].reshape(-1, 3)[:, 2], expected, rtol=1e-12, atol=1e-18)
    assert not np.any(u[0].reshape(-1, 3)[:, :2])
    modes = Modes(setup.disc)
    amplitude = modes.amplitudes(u, v)
    assert np.abs(amplitude - amplitude[0]).max() < ROUND_OFF * amplitude[0, 0]


def test_the_initial_acceleration_balances_a_plastic_preload():
    """A preload past yield: the body starts with the preload's plastic strain, and
    M a0 = f_ext(0) - f_int(u0) on the free dofs (no preload force left)."""
    from fem_frac.app.initial import first_state

    case = cantilever({"preload": {"boundary_conditions": [dict(TIP_FORCE, traction=[
        0.0, 0.0, -2e7])], "steps": 2}}, order=1, steps=1)
    case["plasticity"] = {"yield_stress": 250e6, "hardening": 2e9}
    setup, _, _ = history(case)
    d = setup.disc
    state = first_state(setup.case, d, setup.case_dir)
    assert state.plastic.equivalent_plastic_strain.max() > 0.0
    free = d.constrained.free
    unbalanced = (d.ops.mass @ state.a + state.internal_force)[free]
    assert np.abs(unbalanced).max() < 1e-10 * np.abs(state.internal_force[free]).max()


def test_an_earlier_runs_last_frame_is_the_next_runs_start(tmp_path, capsys):
    """Run, then start a second run from its output directory: the first run's last
    displacement and velocity, node by node."""
    import meshio

    first = cantilever({"preload": {"boundary_conditions": [TIP_FORCE]}}, order=1, steps=3)
    path = write_case(tmp_path / "first.yaml", first)
    assert main(["run", str(path), "-o", str(tmp_path / "first"), "-q"]) == 0
    last = meshio.read(sorted((tmp_path / "first").glob("first_*.vtu"))[-1])
    second = cantilever({"from_run": {"directory": "first", "velocity": True}}, order=1,
                        steps=1)
    setup, u, v = history(second, tmp_path)
    np.testing.assert_array_equal(u[0], last.point_data["displacement"].ravel())
    np.testing.assert_array_equal(v[0], last.point_data["velocity"].ravel())
    assert np.any(v[0])


SUPPORTED = [{"type": "fixed", "boundary": "xmin"}]


@pytest.mark.parametrize(("start", "key", "message"), [
    ({"field": {"z": "x + __import__('os')"}}, "initial_displacement.field.z",
     "'__import__' is not a function"),
    ({"field": {"z": "x.real"}}, "initial_displacement.field.z", "is not allowed"),
    ({"field": {"z": "L * x"}}, "initial_displacement.field.z", "unknown name 'L'"),
    ({"field": {"z": "1 / x"}}, "initial_displacement.field.z", "not finite at"),
    ({"field": {"z": "1" + "0" * 400 + " * x"}}, "initial_displacement.field.z",
     "must be a finite float"),
    ({"field": {"z": "0.01"}}, "initial_displacement.field",
     "does not meet the supports: uz = 0.01"),
    ({"field": {"constants": {"x": 1.0}}}, "initial_displacement.field.constants",
     "cannot name a constant"),
    ({"preload": {"boundary_conditions": [dict(TIP_FORCE, curve="ramp")]}},
     "initial_displacement.preload.boundary_conditions", "no 'curve'"),
    ({"preload": {"boundary_conditions": [dict(TIP_FORCE, boundary="top")]}},
     "initial_displacement.preload.boundary_conditions[0].boundary", "top"),
    ({"preload": {"boundary_conditions": []}},
     "initial_displacement.preload.boundary_conditions", "got []"),
    ({"field": {"z": "0"}, "from_run": {"directory": "x"}}, "initial_displacement",
     "exactly one of"),
    ({"from_run": {"directory": "nowhere"}}, "initial_displacement.from_run.directory",
     "is no directory"),
])
def test_bad_initial_displacements_are_located_errors(tmp_path, capsys, start, key, message):
    case = cantilever(start, order=1, steps=1)
    case["boundary_conditions"] = SUPPORTED
    path = write_case(tmp_path / "bad.yaml", case)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {path}:") and f"analysis.{key}: " in err, err
    assert message in err and len(err.splitlines()) == 1, err


def test_a_preload_on_a_body_held_by_nothing_is_a_located_error(tmp_path, capsys):
    case = cantilever({"preload": {"boundary_conditions": [TIP_FORCE]}}, order=1, steps=1)
    case["boundary_conditions"] = []
    path = write_case(tmp_path / "free.yaml", case)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "analysis.initial_displacement.preload: " in err and "translation x" in err
    case["analysis"]["initial_displacement"] = {"from_run": {"directory": "."}}
    case["plasticity"] = {"yield_stress": 250e6}
    path = write_case(tmp_path / "plastic.yaml", case)
    assert main(["check", str(path)]) == 2
    assert "initial_displacement.from_run: " in capsys.readouterr().err
