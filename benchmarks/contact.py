"""What contact between rigid bodies costs a step (docs/fragments.md, "Contact between
bodies"), and the narrow-phase library it uses.

``scene``: N cubes (edge 0.2 m, 1 kg) at rest on a ground plane (e = 0.3, mu = 0.5) under
gravity, one on each cell of a square grid of pitch 0.22 m (so the area grows with N), moved
by up to 5 mm at random (seeded), turned about z by up to 0.02 rad; on every third cell a
second cube rests on the first (a pair in resting contact). Each bounding sphere's box meets
its neighbours', so the broad phase hands the narrow phase about four pairs a body. Timed,
``--steps`` steps of dt = 1 ms after one warm-up step, each N ``--repeat`` times:

- contact: :func:`fem_frac.rigid.pairs.step_all` (broad phase, narrow phase, islands, the
  impulses with the ground and between bodies);
- free flight: the same bodies flown without any contact (:func:`~fem_frac.rigid.motion.
  free_flight`, the least a step costs);

the cost of contact is their difference per step; the growth exponent is the least-squares
slope of log(cost) against log(N).

``library``: coal against python-fcl (if installed) on two convex hulls of 50 vertices
(random points on an ellipsoid, seeded): microseconds per distance query apart (distance
0.34) and overlapping (penetration 0.24: coal's signed distance, fcl's collide with one
contact), best of 5 runs of 5,000 queries; and both against the exact distance, normal and
witness points of two unit cubes face to face and corner to face, apart and overlapping.

    python benchmarks/contact.py scene [--sizes 10 100 1000] [--steps 5] [--repeat 3]
    python benchmarks/contact.py library
"""

from __future__ import annotations

import argparse
import itertools
import time
from dataclasses import replace

import numpy as np

from fem_frac.rigid.body import exp_map, make_body
from fem_frac.rigid.contact import Plane
from fem_frac.rigid.motion import free_flight
from fem_frac.rigid.pairs import PairLaw, step_all

GRAVITY = np.array([0.0, 0.0, -9.81])
CORNERS = np.array(list(itertools.product([-0.1, 0.1], repeat=3)))


def scene(n: int, seed: int = 0) -> list:
    """``n`` cubes: on the ground, one per cell, and on every third of them a second one."""
    rng = np.random.default_rng(seed)
    ground = int(np.ceil(n * 3 / 4))  # 3 ground cubes carry one
    side = int(np.ceil(np.sqrt(ground)))
    inertia = np.full(3, 0.2 * 0.2 / 6.0)
    bodies = []
    for k in range(ground):
        x, y = 0.22 * (k % side), 0.22 * (k // side)
        dx, dy = rng.uniform(-0.005, 0.005, 2)
        turn = exp_map([0.0, 0.0, rng.uniform(-0.02, 0.02)])
        bodies.append(make_body(1.0, inertia, CORNERS, position=[x + dx, y + dy, 0.1],
                                orientation=turn))
    for k in range(n - ground):
        below = bodies[3 * k]  # exactly on it, shifted by up to 2 cm
        shift = np.append(rng.uniform(-0.02, 0.02, 2), 0.2)
        bodies.append(replace(below, position=below.position + shift))
    return bodies


def time_steps(bodies, steps: int, contact: bool) -> float:
    ground = [Plane(np.zeros(3), np.array([0.0, 0.0, 1.0]), 0.3, 0.5)]
    n = len(bodies)
    asleep, moving = np.zeros(n, dtype=bool), np.ones(n, dtype=bool)

    def one(bs):
        if contact:
            return step_all(bs, asleep, moving, 1e-3, GRAVITY, ground, law=PairLaw(0.0, 0.5))[0]
        return [free_flight(b, 1e-3, GRAVITY) for b in bs]

    bodies = one(bodies)  # warm-up (hulls, coal shapes)
    start = time.perf_counter()
    for _ in range(steps):
        bodies = one(bodies)
    return (time.perf_counter() - start) / steps


def run_scene(sizes, steps: int, repeat: int) -> None:
    rows = []
    print(f"{'N':>6} {'step (ms)':>22} {'free flight (ms)':>18} {'contact (ms)':>14} "
          f"{'per body (us)':>14}")
    for n in sizes:
        full = [time_steps(scene(n), steps, True) for _ in range(repeat)]
        free = [time_steps(scene(n), steps, False) for _ in range(repeat)]
        cost = np.median(full) - np.median(free)
        rows.append((n, cost))
        print(f"{n:>6} {1e3 * np.median(full):>9.2f} [{1e3 * min(full):.2f}, "
              f"{1e3 * max(full):.2f}] {1e3 * np.median(free):>18.3f} {1e3 * cost:>14.2f} "
              f"{1e6 * cost / n:>14.1f}")
    n, cost = np.array(rows).T
    slope = np.polyfit(np.log(n), np.log(cost), 1)[0]
    print(f"growth exponent of the contact cost: {slope:.3f} "
          f"(N log N over this range: {np.polyfit(np.log(n), np.log(n * np.log(n)), 1)[0]:.3f})")


def _hull(rng, n=50):
    p = rng.normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1)[:, None] * rng.uniform(0.3, 0.5, 3)


def _coal_query():
    import coal

    def shape(p):
        v = coal.StdVec_Vec3s()
        v.extend(list(np.asarray(p, dtype=float)))
        return coal.Convex.convexHull(v, True, "Qt")

    def make(a, b):
        sa, sb = shape(a), shape(b)
        request, result = coal.DistanceRequest(), coal.DistanceResult()

        def query(r, t):
            result.clear()
            d = coal.distance(sa, coal.Transform3s(), sb, coal.Transform3s(r, t), request,
                              result)
            return d, np.array(result.normal), np.array(result.getNearestPoint1())
        return query
    return make


def _fcl_query():
    try:
        import fcl
    except ImportError:
        return None
    from scipy.spatial import ConvexHull

    def shape(p):
        h = ConvexHull(p)
        faces = np.hstack([np.full((len(h.simplices), 1), 3), h.simplices]).ravel()
        return fcl.Convex(np.asarray(p, dtype=float), len(h.simplices), faces)

    def make(a, b):
        oa = fcl.CollisionObject(shape(a), fcl.Transform())
        ob = fcl.CollisionObject(shape(b), fcl.Transform())
        request = fcl.DistanceRequest(enable_nearest_points=True, enable_signed_distance=True)
        collide = fcl.CollisionRequest(num_max_contacts=1, enable_contact=True)

        def query(r, t):
            ob.setTransform(fcl.Transform(r, t))
            result = fcl.DistanceResult()
            d = fcl.distance(oa, ob, request, result)
            if d >= 0:
                return d, None, np.array(result.nearest_points[0])
            hit = fcl.CollisionResult()
            fcl.collide(oa, ob, collide, hit)
            c = hit.contacts[0]
            return -c.penetration_depth, np.array(c.normal), np.array(c.pos)
        return query
    return make


def run_library() -> None:
    cube = np.array(list(itertools.product([-0.5, 0.5], repeat=3)))
    turn = np.array([[np.cos(np.pi / 4), -np.sin(np.pi / 4), 0.0],
                     [np.sin(np.pi / 4), np.cos(np.pi / 4), 0.0], [0.0, 0.0, 1.0]])
    cases = [("face-face apart", np.eye(3), [1.2, 0.1, 0.05], 0.2),
             ("face-face overlap", np.eye(3), [0.9, 0.1, 0.05], -0.1),
             ("corner-face apart", turn, [1.3, 0.0, 0.0], 0.8 - np.sqrt(0.5)),
             ("corner-face overlap", turn, [1.1, 0.0, 0.0], 0.6 - np.sqrt(0.5))]
    for name, make in (("coal", _coal_query()), ("python-fcl", _fcl_query())):
        if make is None:
            print(f"{name}: not installed")
            continue
        q = make(cube, cube)
        for label, r, t, exact in cases:
            d, normal, point = q(r, np.asarray(t, dtype=float))
            normal_error = (np.nan if normal is None
                            else np.abs(normal - [1.0, 0.0, 0.0]).max())
            print(f"{name:>10} {label:<20} distance error {d - exact:+.1e}  normal error "
                  f"{normal_error:.1e}  witness x {point[0]:.6f}")
        rng = np.random.default_rng(0)
        q = make(_hull(rng), _hull(rng))
        r = exp_map([0.3, 0.2, 0.1])
        from fem_frac.rigid.body import rotation_matrix

        r = rotation_matrix(r)
        for label, t in (("apart", [1.2, 0.0, 0.0]), ("overlapping", [0.6, 0.1, 0.0])):
            best = np.inf
            for _ in range(5):
                start = time.perf_counter()
                for _ in range(5000):
                    d = q(r, np.asarray(t, dtype=float))[0]
                best = min(best, (time.perf_counter() - start) / 5000)
            print(f"{name:>10} 50-vertex hulls {label:<12} d = {d:+.6f}  "
                  f"{1e6 * best:.1f} us per query")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="what", required=True)
    s = sub.add_parser("scene")
    s.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 1000])
    s.add_argument("--steps", type=int, default=5)
    s.add_argument("--repeat", type=int, default=3)
    sub.add_parser("library")
    args = parser.parse_args()
    if args.what == "scene":
        run_scene(args.sizes, args.steps, args.repeat)
    else:
        run_library()


if __name__ == "__main__":
    main()
