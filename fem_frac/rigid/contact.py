"""Contact of a rigid body with fixed planes by impulses (DESIGN §2, "Fragments and rigid bodies").

:func:`step`, one time step: kick (``P += m g dt``); find the vertices inside a plane or
reaching it within the step; impulses (:func:`resolve`); drift (torque-free free flight of
``motion.py`` with the new momenta); projection (a body left inside a plane is moved out
along the normal, velocities kept, so no kinetic energy is added: no Baumgarte bias). A step
with no contact is the exact parabola of ``free_flight``. Vertices whose rebound ``e v`` is
faster than ``v_rest = 2 |g| dt`` (twice what gravity adds in a step) bounce
(:func:`bouncing`): the step is then cut at their linearly predicted time of impact, so the
rebound starts on the plane (bounce heights right to O(g dt^2), where bouncing at the step
boundary is off by O(|v| dt) and lets micro-bounces pump energy). The others rest: e = 0 and
the target ``v_n >= -gap / dt`` (speculative contact), so a body settles exactly onto the
plane, without jitter; a hop shorter than two steps is not resolved (with ``v > v_rest``
alone, a piece hopped every other step for ever).

:func:`resolve` uses Poisson's restitution in two phases, not Gauss-Seidel aimed at Newton's
``v_n+ = -e v_n-``:

- compression: sequential impulses (block Gauss-Seidel over the vertices, accumulated and
  clamped per vertex as in Catto's: normal >= 0, friction in the Coulomb disc
  ``|lambda_t| <= mu lambda_n``) with the body's effective mass ``J M^-1 J^T``, rows
  ``[d, r x d]``, until the normal velocities reach their targets;
- restitution: e times the compression impulse is applied again.

Why: with one e the kinetic energy cannot rise for any e <= 1, friction and several contacts
included. Compression lowers it by at least ``lambda.A.lambda / 2`` (each friction impulse
opposes the sliding it leaves, and ``lambda_n v_n = 0``), restitution adds back ``e^2`` of
that. Newton's law at several vertices can gain energy. A guard scales down a restitution
that would (only round-off with one e; mixed e, resting and bouncing vertices, need it), and
a last inelastic pass stops vertices that another's rebound drives into the plane.

Contact between bodies (and with fixed obstacles) uses the same solver:
:mod:`~fem_frac.rigid.pairs`; with the finite elements: :mod:`~fem_frac.rigid.deformable`.
Not handled: rolling and spinning resistance, distinct static and kinetic friction,
friction in the last inelastic pass.
A body touches a plane only at its ``points``; for the vertices of a convex hull that is
complete, since a convex body first meets a plane at a vertex.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .active_set import exact_on_active_set as _polish
from .body import RigidBody, inverse_inertia_world, rotation_matrix
from .motion import free_flight
from .vectors import cross, length, lengths

# Gauss-Seidel: stop when a sweep changes no contact velocity by more than this fraction of
# the largest velocity before the impulses.
_TOLERANCE = 1e-13
_ITERATIONS = 200
# Sweeps between tries of the exact solution on the active set (:func:`_polish`).
_POLISH_EVERY = 5
# A point out of contact is skipped in a sweep (:func:`_sweep`) only while its slack exceeds
# the bound on its velocity's change by this fraction of the impulses' total movement: over
# the round-off of the products (n eps of it, n the 3c entries) and of the running sum
# (eps for each of up to 1e6 updates), with room to spare.
_ROUNDING = 1e-9


@dataclass(frozen=True, eq=False)
class Plane:
    """A fixed half-space boundary ``(x - point) . normal >= 0``.

    point: (3,) on the plane; normal: (3,) unit, pointing out of the obstacle;
    restitution: e in [0, 1]; friction: Coulomb mu >= 0.
    """

    point: np.ndarray
    normal: np.ndarray
    restitution: float = 0.0
    friction: float = 0.0

    def __post_init__(self):
        n = np.asarray(self.normal, dtype=float)
        if not (np.isclose(n @ n, 1.0, rtol=1e-9) and 0.0 <= self.restitution <= 1.0
                and self.friction >= 0.0):
            raise ValueError(f"need a unit normal, restitution in [0, 1], friction >= 0: {self}")
        object.__setattr__(self, "normal", n)
        object.__setattr__(self, "point", np.asarray(self.point, dtype=float))


def signed_distance(plane: Plane, x) -> np.ndarray:
    """(k,) signed distance of points ``x`` (k, 3) from the plane, negative inside."""
    return (np.asarray(x, dtype=float) - plane.point) @ plane.normal


def contact_frame(n: np.ndarray) -> np.ndarray:
    """(3, 3) rows n, t1, t2: an orthonormal frame with the normal first."""
    helper = np.eye(3)[int(np.argmin(np.abs(n)))]
    t1 = cross(n, helper)
    t1 /= length(t1)
    return np.array([n, t1, cross(n, t1)])


def frames(normals: np.ndarray) -> np.ndarray:
    """(c, 3, 3) rows n, t1, t2: :func:`contact_frame` of each of ``normals (c, 3)``."""
    helper = np.eye(3)[np.argmin(np.abs(normals), axis=1)]
    t1 = cross(normals, helper)
    t1 /= lengths(t1)[:, None]
    return np.stack([normals, t1, cross(normals, t1)], axis=1)


@dataclass(frozen=True, eq=False)
class Contacts:
    """The active contact points of one body (c of them) at the start of a step.

    arm: (c, 3) world offset from the centre; frame: (c, 3, 3) rows n, t1, t2;
    gap: (c,) signed distance; approach: (c,) normal speed towards the plane (< 0: leaving);
    restitution, friction: (c,) of the plane touched.
    """

    arm: np.ndarray
    frame: np.ndarray
    gap: np.ndarray
    approach: np.ndarray
    restitution: np.ndarray
    friction: np.ndarray


def find_contacts(body: RigidBody, planes, horizon: float) -> Contacts:
    """Vertices inside a plane, or approaching and within ``horizon`` (time) of it at their
    present velocity (a vertex touching and approaching counts even for a zero horizon)."""
    arm = body.points @ rotation_matrix(body.orientation).T
    x = body.position + arm
    vel = body.momentum / body.mass + cross(inverse_inertia_world(body)
                                             @ body.angular_momentum, arm)
    rows = []
    for plane in planes:
        gap, vn = signed_distance(plane, x), vel @ plane.normal
        hit = np.flatnonzero((gap < 0.0) | ((gap + horizon * vn <= 0.0) & (vn < 0.0)))
        frame = contact_frame(plane.normal)
        rows += [(arm[i], frame, gap[i], -vn[i], plane.restitution, plane.friction)
                 for i in hit]
    if not rows:
        none = np.zeros(0)
        return Contacts(np.zeros((0, 3)), np.zeros((0, 3, 3)), none, none, none, none)
    return Contacts(*(np.array(column) for column in zip(*rows, strict=True)))


def _jacobian(contacts: Contacts) -> np.ndarray:
    """(3c, 6): row (i, d) maps (v, omega) to the velocity of point i along direction d."""
    d = contacts.frame.reshape(-1, 3)
    arm = np.repeat(contacts.arm, 3, axis=0)
    return np.hstack([d, cross(arm, d)])


def _friction_impulse(entries, eigen, f, radius):
    """The tangential impulse ``x`` (two numbers) minimizing ``x.k.x / 2 + f.x`` over
    ``|x| <= radius``.

    k: (2, 2) tangential effective mass (inverse), SPD, given as ``entries = k.tolist()``;
    f: (2,) tangential velocity without this friction: the kinetic energy over the Coulomb
    disc. Inside, the point sticks; on the rim it slides, ``k x + f = -sigma x``: friction
    opposes the sliding after the impulse (maximum dissipation). A radial clamp of the
    sticking impulse, or friction along ``-f``, misses this minimum when ``k`` is
    anisotropic and stalls Gauss-Seidel short of sticking. eigen: a list that keeps
    :func:`_eigen2` of ``k`` once made (Gauss-Seidel calls this with the same ``k`` every
    sweep). All in Python floats: numpy's per-call overhead on two numbers is most of a
    contact step otherwise.
    """
    (k00, k01), (k10, k11) = entries
    f0, f1 = float(f[0]), float(f[1])
    det = k00 * k11 - k01 * k10
    x0, x1 = (k01 * f1 - k11 * f0) / det, (k10 * f0 - k00 * f1) / det
    if x0 * x0 + x1 * x1 <= radius * radius:
        return x0, x1
    if radius <= 0.0:
        return 0.0, 0.0
    # secular equation |(k + sigma)^-1 f| = radius; Newton on 1/|x(sigma)| - 1/radius, which
    # is nearly linear in sigma, converges from sigma = 0 monotonically (More & Sorensen 1983)
    if not eigen:
        eigen.append(_eigen2(entries))
    w0, w1, q00, q01, q10, q11 = eigen[0]
    g0, g1 = q00 * f0 + q10 * f1, q01 * f0 + q11 * f1  # q^T f
    sigma = 0.0
    for _ in range(50):
        d0, d1 = w0 + sigma, w1 + sigma
        y0, y1 = g0 / d0, g1 / d1
        norm = math.sqrt(y0 * y0 + y1 * y1)
        step = (1.0 / radius - 1.0 / norm) * norm**3 / (y0 * y0 / d0 + y1 * y1 / d1)
        sigma = max(sigma + step, 0.0)
        if abs(step) <= 1e-15 * (sigma + w1):
            break
    y0, y1 = g0 / (w0 + sigma), g1 / (w1 + sigma)
    return -(q00 * y0 + q01 * y1), -(q10 * y0 + q11 * y1)


def _eigen2(entries):
    """``(w0, w1, q00, q01, q10, q11)``: the eigenvalues ``w0 <= w1`` of the symmetric 2 x 2
    matrix ``entries`` (its lower triangle, as LAPACK's ``eigh``) and the orthonormal
    eigenvectors, the columns of ``q``; in closed form (Python floats)."""
    (p, _), (s, r) = entries
    half = 0.5 * (p - r)
    d = math.hypot(half, s)
    w1 = 0.5 * (p + r) + d
    w0 = 0.5 * (p + r) - d
    if d == 0.0:
        return w0, w1, 1.0, 0.0, 0.0, 1.0
    # the eigenvector of w1 from the better conditioned of the two rows of (k - w1)
    u, v = (half + d, s) if half >= 0.0 else (s, d - half)
    n = math.hypot(u, v)
    u, v = u / n, v / n
    return w0, w1, -v, u, u, v


def _sequential_impulses(a, b, target, friction, iterations=_ITERATIONS, polish=False,
                         scale=None):
    """(3c,) accumulated impulses: normal velocity ``>= target``, friction in the disc
    (:func:`_gauss_seidel`'s)."""
    return _gauss_seidel(a, b, target, friction, iterations, polish, scale)[0]


def _gauss_seidel(a, b, target, friction, iterations=_ITERATIONS, polish=False, scale=None):
    """``(lam (3c,), sweeps, exact)``: the accumulated impulses (normal velocity ``>=
    target``, friction in the disc), the sweeps made and whether the exact solution on
    the active set (:func:`_polish`) ended them.

    a: (3c, 3c) Delassus matrix ``J M^-1 J^T``; b: (3c,) velocities before; target: (c,).
    Each update minimizes the kinetic energy over one point's impulses (block Gauss-Seidel),
    so with the normal impulses fixed the friction sweeps converge to the exact minimum.
    polish: every ``_POLISH_EVERY`` sweeps, try the exact solution on the sweeps' active set
    (:func:`_polish`) and stop if it holds (Gauss-Seidel converges slowly through a stack
    of bodies). scale: of the velocities, for the stopping test (default ``max |b|``).
    """
    lam = np.zeros_like(b)
    scale = (float(np.abs(b).max()) if scale is None else scale) + 1e-300
    before = b.copy()
    points = _sweep_terms(a, b, target, friction, lam)
    watch, moved = [None] * len(points), 0.0
    failed = [None]  # the last system _polish tried in vain
    sweep = 0
    for sweep in range(1, iterations + 1):
        moved = _sweep(points, lam, watch, moved)
        # stop on the contact velocities, not the impulses: with more points than the body
        # has freedoms the impulses are not unique and may wander in that null space
        velocities = b + a @ lam
        if np.abs(velocities - before).max() <= _TOLERANCE * scale:
            break
        before = velocities
        if polish and sweep % _POLISH_EVERY == 0:
            exact = _polish(a, b, lam, target, friction, scale, failed)
            if exact is not None:
                return exact, sweep, True
    return lam, sweep, False


def _sweep(points, lam, watch, moved: float) -> float:
    """One Gauss-Seidel sweep over ``points`` (:func:`_sweep_terms`), in place on ``lam``;
    returns ``moved``, the sum of ``|change|`` of every entry of ``lam`` so far.

    A point whose update left it out of contact (no normal impulse, its normal velocity
    above its target by a slack) is skipped while the impulses moved since then cannot
    have closed that slack: its normal velocity changes by at most its row's largest
    entry times ``moved``'s growth. Its update would give zero impulses again, so the
    skip changes no bit (``watch``: each point's ``(slack, moved then)``, or ``None``; the
    bound has ``_ROUNDING`` of ``moved`` more for the round-off of the products). The
    scalar work is in Python floats: the same operations as on numpy's scalars, so the
    same bits, without their overhead."""
    item = lam.item
    for k, (j, row, pivot, rest, sliding, reach) in enumerate(points):
        w = watch[k]
        if w is not None:
            if w[0] > reach * (moved - w[1] + _ROUNDING * moved):
                continue
            watch[k] = None
        old = item(j)
        r = (row @ lam).item()
        new = old + (rest - r) / pivot
        if 0.0 > new:  # max(new, 0.0), as Python's max picks
            new = 0.0
        lam[j] = new
        if new == 0.0:  # no normal impulse, no friction
            if old != 0.0:
                moved += old
            elif r > rest:
                watch[k] = (r - rest, moved)
            if sliding is not None:
                if old != 0.0:
                    l0, l1 = sliding[4].tolist()
                    moved += abs(l0) + abs(l1)
                sliding[4][:] = 0.0
            continue
        moved += new - old if new > old else old - new
        if sliding is None:
            continue
        mu, rows, entries, b_t, lam_t, eigen = sliding
        radius = mu * new
        (l0, l1) = lam_t.tolist()
        if radius <= 0.0:  # mu times a subnormal impulse
            lam_t[:] = 0.0
            moved += abs(l0) + abs(l1)
            continue
        # the tangential velocity without this point's friction
        (k00, k01), (k10, k11) = entries
        r0, r1 = (rows @ lam).tolist()
        free = (b_t[0] + r0 - (k00 * l0 + k01 * l1), b_t[1] + r1 - (k10 * l0 + k11 * l1))
        x0, x1 = _friction_impulse(entries, eigen, free, radius)
        lam_t[0], lam_t[1] = x0, x1
        moved += abs(x0 - l0) + abs(x1 - l1)
    return moved


def _sweep_terms(a, b, target, friction, lam):
    """What a Gauss-Seidel sweep reads of each point i (row j = 3 i), computed once: ``(j,
    a[j], a[j, j], target[i] - b[j], friction terms or None, max |a[j]|)``, the friction
    terms ``(mu, a[t], a[t, t].tolist(), b[t].tolist(), lam[t], a cache for
    _eigen2(a[t, t]))`` with ``t`` its two tangential rows (``lam[t]`` a view: the sweep
    writes through it). The scalars as Python floats."""
    terms = []
    for i in range(len(target)):
        j = 3 * i
        sliding = None
        if friction[i] > 0.0:
            t = slice(j + 1, j + 3)
            sliding = (float(friction[i]), a[t], a[t, t].tolist(), b[t].tolist(), lam[t], [])
        terms.append((j, a[j], float(a[j, j]), float(target[i] - b[j]), sliding,
                      float(np.abs(a[j]).max())))
    return terms


def _apply(body: RigidBody, jac: np.ndarray, lam: np.ndarray) -> RigidBody:
    """The body after the impulses ``lam`` (3c,) along the rows of ``jac`` (3c, 6)."""
    delta = jac.T @ lam  # (linear impulse, angular impulse about the centre)
    return replace(body, momentum=body.momentum + delta[:3],
                   angular_momentum=body.angular_momentum + delta[3:])


def _restitution_scale(a, b, lam, rebound) -> float:
    """Largest s in [0, 1] with the kinetic energy after ``lam + s rebound`` not above before.

    The change of kinetic energy by an impulse x (3c,) is ``x.b + x.a.x / 2``, exactly.
    """
    loss = -(lam @ b + 0.5 * lam @ a @ lam)  # >= 0: the compression phase dissipates
    g, h = rebound @ (b + a @ lam), 0.5 * rebound @ a @ rebound
    if g + h <= loss:
        return 1.0
    if loss <= 0.0 or h <= 0.0:
        return 0.0
    return float(min(max((-g + np.sqrt(g * g + 4.0 * h * loss)) / (2.0 * h), 0.0), 1.0))


def poisson_impulses(a, b, target, friction, restitution, polish=False,
                     scale=None) -> np.ndarray:
    """(3c,) contact impulses (normal, t1, t2 per point) of Poisson's restitution.

    a: (3c, 3c) Delassus matrix ``J M^-1 J^T`` of any number of bodies (a fixed body has
    ``M^-1 = 0``); b: (3c,) contact velocities before; target: (c,) least normal velocity of
    the compression phase; friction: (c,) mu; restitution: (c,) e of each point (0 where it
    rests). Compression, then e times its impulse again, scaled down only if that would add
    energy (round-off with one e), then an inelastic frictionless pass for the points another
    point's rebound drives in. Each phase cannot add kinetic energy (module docstring).
    polish, scale: of :func:`_sequential_impulses` (exact solutions for stacks of bodies).
    """
    lam = _sequential_impulses(a, b, target, friction, polish=polish, scale=scale)
    e = np.repeat(restitution, 3)
    if not np.any(e):
        return lam
    # guard: with a uniform e the scale is 1 to round-off (the proof in the module docstring)
    lam = lam + _restitution_scale(a, b, lam, e * lam) * e * lam
    # restitution at one point can drive another into the plane (Poisson's law at several
    # points); a last inelastic, frictionless pass stops that. Each of its updates minimizes
    # the kinetic energy over one impulse, so it cannot add energy
    return lam + _sequential_impulses(a, b + a @ lam, target, np.zeros_like(target),
                                      polish=polish, scale=scale)


def targets(gap, approach, restitution, dt: float, v_rest: float):
    """``(target (c,), e (c,))`` of contact points: those that bounce (:func:`bouncing`) get
    target 0 and their e, the others rest (e = 0) with the speculative target
    ``v_n >= -gap / dt`` (a point may close its gap within the step, no more)."""
    bounce = bouncing(gap, approach, restitution, dt, v_rest)
    target = np.where(bounce, 0.0, -np.maximum(gap, 0.0) / dt)
    return target, np.where(bounce, restitution, 0.0)


def bouncing(gap, approach, restitution, dt: float, v_rest: float) -> np.ndarray:
    """(c,) the points that bounce: their rebound ``e v`` is faster than ``v_rest``, and they
    touch (their gap closes within ``dt / 4`` at their approach ``v``).

    Rebound: a hop of ``2 e v / g`` must last more than two steps (``v_rest = 2 g dt``) to be
    resolved; shorter hops ended in a limit cycle, a face of a piece hopping every other step
    with ``v* = 2 g dt / (1 - e)``, above the former threshold ``v > v_rest`` for any e > 0,
    fed by the projection and the bounces from above the plane (the breaking beam's pieces
    rocked so for ever). Such a point rests instead: its approach decays as ``e^k`` in the
    exact motion, and the last hops are below the step. Touching: after the step is cut at
    the first bounce's linearly predicted time of impact, that point's gap is the
    prediction's error, at most ``g dt^2 / 2``, so it closes within
    ``g dt^2 / (2 v_rest) = dt / 4``; a point farther away must not bounce now, from a
    distance above the plane: it rests this step (inelastic) and lands."""
    return (restitution * approach > v_rest) & (gap <= 0.25 * dt * approach)


def resolve(body: RigidBody, contacts: Contacts, dt: float, v_rest: float) -> RigidBody:
    """The body with contact impulses applied to its momenta; position and orientation kept.

    dt: the step (for the speculative target); v_rest: approach speed below which a point
    rests (no bounce).
    """
    if len(contacts.gap) == 0:
        return body
    jac = _jacobian(contacts)
    inv_mass = np.zeros((6, 6))
    inv_mass[:3, :3] = np.eye(3) / body.mass
    inv_mass[3:, 3:] = inverse_inertia_world(body)
    omega = inv_mass[3:, 3:] @ body.angular_momentum
    b = jac @ np.concatenate([body.momentum / body.mass, omega])
    a = jac @ inv_mass @ jac.T
    target, e = targets(contacts.gap, contacts.approach, contacts.restitution, dt, v_rest)
    return _apply(body, jac, poisson_impulses(a, b, target, contacts.friction, e, polish=True))


def project(body: RigidBody, planes, sweeps: int = 2) -> RigidBody:
    """The body moved out of every plane it penetrates, along the normal (velocities kept)."""
    for _ in range(sweeps if len(planes) > 1 else 1):
        for plane in planes:
            x = body.position + body.points @ rotation_matrix(body.orientation).T
            depth = -float(signed_distance(plane, x).min(initial=0.0))
            if depth > 0.0:
                body = replace(body, position=body.position + depth * plane.normal)
    return body


def step(body: RigidBody, dt: float, gravity, planes) -> RigidBody:
    """One time step ``dt`` of a body under ``gravity`` (3,) with contact ``planes``."""
    g = np.asarray(gravity, dtype=float)
    kicked = replace(body, momentum=body.momentum + body.mass * dt * g)
    contacts = find_contacts(kicked, planes, dt)
    if len(contacts.gap) == 0:
        return project(free_flight(body, dt, g), planes)
    v_rest = 2.0 * float(np.linalg.norm(g)) * dt
    fast = contacts.restitution * contacts.approach > v_rest
    if not np.any(fast):
        # resting contact: kick, impulses, drift; the impulses cancel this step's gravity, so
        # a body at rest stays exactly at rest
        moved = free_flight(resolve(kicked, contacts, dt, v_rest), dt, np.zeros(3))
        return project(moved, planes)
    # an impact: fly to the first bouncing vertex's time of impact (linear prediction), apply
    # the impulses there, fly on; the rebound starts on the plane, not up to |v| dt above it,
    # which keeps bounce heights right to O(g dt^2) and stops micro-bounces from pumping
    tau = float(np.clip(np.min(np.maximum(contacts.gap[fast], 0.0) / contacts.approach[fast]),
                        0.0, dt))
    at_impact = project(free_flight(body, tau, g), planes)
    rest = dt - tau
    # the threshold as seen before this step's gravity has all acted
    threshold = v_rest - float(np.linalg.norm(g)) * rest
    hit = resolve(at_impact, find_contacts(at_impact, planes, rest), dt, threshold)
    return project(free_flight(hit, rest, g), planes)
