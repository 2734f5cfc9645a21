"""Solves through the previous mesh's factorization after a crack insertion
(fem_frac.solve.bordered): the same answers as a direct solve of the new stiffness (or of
Newmark's ``K + c M``), through a chain of insertions, and a refusal where a crack cuts a
piece loose; a dynamic run through them equals one that refactorizes, to round-off."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from fem_frac.fem.elasticity import stiffness
from fem_frac.fem.mass import consistent_mass
from fem_frac.fem.space import build_space
from fem_frac.fem.tensors import isotropic_tangent
from fem_frac.fracture.topology import open_crack
from fem_frac.solve import bordered
from fem_frac.solve.bordered import bordered_factor
from fem_frac.solve.linalg import available_methods, factorize
from meshes import structured_box

ROOT = Path(__file__).parent.parent
TANGENT = isotropic_tangent(100.0, 0.25)


def system(mesh, c_mass=0.0):
    """The stiffness of ``mesh`` (plus ``c_mass`` times its consistent mass, Newmark's
    Jacobian) on its free dofs (the nodes on x = 0 held) and those dofs."""
    space = build_space(mesh, 1)
    k = stiffness(space, TANGENT).tocsr()
    if c_mass:
        k = (k + c_mass * consistent_mass(space, 1.0)).tocsr()
    held = np.flatnonzero(np.abs(mesh.points[:, 0]) < 1e-12)
    free = np.setdiff1d(np.arange(space.n_dofs), (3 * held[:, None] + np.arange(3)).ravel())
    return k[free][:, free].tocsr(), free


def tie(old_free, new_free, node_map, n_old_dofs):
    """The old free dof each new free dof copies."""
    index = np.full(n_old_dofs, -1)
    index[old_free] = np.arange(old_free.size)
    dofs = (3 * node_map[:, None] + np.arange(3)).ravel()
    return index[dofs[new_free]]


def crack(mesh, x, axis=0):
    """Split the interior vertices on the plane x_axis = ``x`` (a crack across, its edges
    short of the sides so the body holds together)."""
    p = mesh.points
    on = np.abs(p[:, axis] - x) < 1e-12
    others = [k for k in range(3) if k != axis]
    extent = p.max(axis=0)
    inside = on & np.all((p[:, others] > 1e-12) & (p[:, others] < extent[others] - 1e-12),
                         axis=1)
    vertices = np.flatnonzero(inside)
    return open_crack(mesh, vertices, np.tile(np.eye(3)[axis], (vertices.size, 1)))


@pytest.fixture(scope="module")
def chain():
    """A cube of tets, then two insertions: the meshes, their systems and their ties."""
    m0 = structured_box((6, 4, 4))
    m1, t1 = crack(m0, 0.5)
    m2, t2 = crack(m1, 2 / 6)
    (a0, f0), (a1, f1), (a2, f2) = system(m0), system(m1), system(m2)
    return [(a0, None), (a1, tie(f0, f1, np.asarray(t1.node_map), 3 * m0.n_points)),
            (a2, tie(f1, f2, np.asarray(t2.node_map), 3 * m1.n_points))]


@pytest.mark.parametrize("method", available_methods())
def test_solves_as_the_new_stiffness_does_through_a_chain_of_insertions(chain, monkeypatch,
                                                                         method):
    """Through the root's forward halves (PARDISO: Y = R C) and through its whole solves
    (the other backends: G = A^-1 C) alike."""
    (a0, _), (a1, tie1), (a2, tie2) = chain
    monkeypatch.setattr(bordered, "SHARE", 1e9)  # the policy aside: keep the base here
    monkeypatch.setattr(bordered, "COPIES", 1e9)
    base = factorize(a0, method)
    assert (base.halves is not None) == (method == "pardiso")
    rng = np.random.default_rng(0)
    one = bordered_factor(base, tie1, a1)
    assert one is not None and one.copies == a1.shape[0] - a0.shape[0] > 0
    two = bordered_factor(one, tie2, a2)
    assert two is not None and two.root is base
    assert two.copies == a2.shape[0] - a0.shape[0] > one.copies
    for a, f in ((a1, one), (a2, two)):
        b = rng.standard_normal((a.shape[0], 3))
        exact = spla.spsolve(a.tocsc(), b)
        for x in (f.solve(b), np.stack([f.solve(b[:, k]) for k in range(3)], axis=1)):
            # exact to round-off: cond(A) ~ 1e3 here
            assert np.abs(x - exact).max() <= 1e-10 * np.abs(exact).max()


def test_the_whole_jacobian_with_its_free_dofs_gives_the_same_factor(monkeypatch):
    """``free=``: the copies' columns taken from the whole Jacobian are the free-dof
    matrix's entries, so the factor solves to the same bits."""
    monkeypatch.setattr(bordered, "SHARE", 1e9)
    monkeypatch.setattr(bordered, "COPIES", 1e9)
    m0 = structured_box((6, 4, 4))
    m1, t1 = crack(m0, 0.5)
    (a0, f0) = system(m0)
    space = build_space(m1, 1)
    whole = stiffness(space, TANGENT).tocsr()
    a1, f1 = system(m1)
    t = tie(f0, f1, np.asarray(t1.node_map), 3 * m0.n_points)
    base = factorize(a0)
    sub, through_whole = bordered_factor(base, t, a1), bordered_factor(base, t, whole, free=f1)
    assert sub.copies == through_whole.copies > 0
    b = np.random.default_rng(1).standard_normal((a1.shape[0], 2))
    np.testing.assert_array_equal(through_whole.solve(b), sub.solve(b))
    np.testing.assert_array_equal(through_whole.c.toarray(), sub.c.toarray())


def test_pieces_that_left_solve_through_the_old_factor():
    """A piece sharing no vertex with the rest leaves: the old matrix is block diagonal,
    and the rest's block is solved through the old factorization (bordered.restricted)
    as by its own."""
    from fem_frac.fracture.topology import extract

    m0 = structured_box((6, 4, 4))
    p = m0.points
    plane = np.flatnonzero(np.abs(p[:, 0] - 0.5) < 1e-12)
    cut, _ = open_crack(m0, plane, np.tile([1.0, 0.0, 0.0], (plane.size, 1)))
    _, f_cut = system(cut)  # held on x = 0: the piece x > 0.5 is free, mass makes it SPD
    space = build_space(cut, 1)
    a_cut = (stiffness(space, TANGENT) + 1e3 * consistent_mass(space, 1.0)).tocsr()
    a_cut = a_cut[f_cut][:, f_cut].tocsr()
    keep = cut.points[cut.tets].mean(axis=1)[:, 0] < 0.5
    rest, tr = extract(cut, keep)
    space_r = build_space(rest, 1)
    a_rest = (stiffness(space_r, TANGENT) + 1e3 * consistent_mass(space_r, 1.0)).tocsr()
    held = np.flatnonzero(np.abs(rest.points[:, 0]) < 1e-12)
    f_rest = np.setdiff1d(np.arange(space_r.n_dofs), (3 * held[:, None] + np.arange(3)))
    a_rest = a_rest[f_rest][:, f_rest].tocsr()
    t = tie(f_cut, f_rest, np.asarray(tr.node_map), 3 * cut.n_points)
    assert np.all(t >= 0) and t.size < a_cut.shape[0]
    f = bordered.restricted(factorize(a_cut), t)
    b = np.random.default_rng(5).standard_normal((a_rest.shape[0], 2))
    exact = spla.spsolve(a_rest.tocsc(), b)
    assert np.abs(f.solve(b) - exact).max() <= 1e-10 * np.abs(exact).max()
    # a chain stacks at most RESTRICTED of them (each a pass over the old dofs a solve)
    every = np.arange(a_rest.shape[0])
    for _ in range(bordered.RESTRICTED - 1):
        f = bordered.restricted(f, every)
    assert f is not None and bordered.restricted(f, every) is None


@pytest.mark.parametrize("method", available_methods())
def test_copies_off_a_support_are_bordered_as_dofs_of_their_own(monkeypatch, method):
    """A split vertex held in the base mesh whose copies the new mesh leaves free (a copy
    off the support that holds the vertex): their dofs tie to no base dof (-1), E's rows
    are zero there, and they are bordered like the copies; through a second insertion
    too (the -1 composed). Solves as the new free-dof matrix does."""
    monkeypatch.setattr(bordered, "SHARE", 1e9)
    monkeypatch.setattr(bordered, "COPIES", 1e9)
    m0 = structured_box((6, 4, 4))
    m1, t1 = crack(m0, 0.5)
    m2, t2 = crack(m1, 2 / 6)
    split = np.unique(np.asarray(t1.node_map)[m0.n_points:])  # the vertices t1 split

    def held_system(mesh, extra):
        space = build_space(mesh, 1)
        k = stiffness(space, TANGENT).tocsr()
        held = np.union1d(np.flatnonzero(np.abs(mesh.points[:, 0]) < 1e-12), extra)
        free = np.setdiff1d(np.arange(space.n_dofs), (3 * held[:, None] + np.arange(3)))
        return k[free][:, free].tocsr(), free

    (a0, f0), (a1, f1), (a2, f2) = (held_system(m, split) for m in (m0, m1, m2))
    t01 = tie(f0, f1, np.asarray(t1.node_map), 3 * m0.n_points)
    t12 = tie(f1, f2, np.asarray(t2.node_map), 3 * m1.n_points)
    assert np.count_nonzero(t01 < 0) == 3 * (m1.n_points - m0.n_points) > 0
    one = bordered_factor(factorize(a0, method), t01, a1)
    two = bordered_factor(one, t12, a2)
    assert one is not None and two is not None and two.root is one.root
    rng = np.random.default_rng(6)
    for a, f in ((a1, one), (a2, two)):
        b = rng.standard_normal((a.shape[0], 2))
        exact = spla.spsolve(a.tocsc(), b)
        assert np.abs(f.solve(b) - exact).max() <= 1e-10 * np.abs(exact).max()


def test_solves_as_newmarks_jacobian_does_through_a_chain_of_insertions(monkeypatch):
    """With inertia the Jacobian is ``K + c M``: the element mass matrices, like the
    stiffness's, are the old mesh's scattered to new dofs, so the same algebra holds. ``c``
    puts the mass term's diagonal at the stiffness's (2.3e4 between them here): a step of
    about an element's wave transit time, as explicit-like dynamics take."""
    monkeypatch.setattr(bordered, "SHARE", 1e9)
    monkeypatch.setattr(bordered, "COPIES", 1e9)
    m0 = structured_box((6, 4, 4))
    m1, t1 = crack(m0, 0.5)
    m2, t2 = crack(m1, 2 / 6)
    (a0, f0), (a1, f1), (a2, f2) = (system(m, c_mass=2e4) for m in (m0, m1, m2))
    one = bordered_factor(factorize(a0), tie(f0, f1, np.asarray(t1.node_map),
                                             3 * m0.n_points), a1)
    two = bordered_factor(one, tie(f1, f2, np.asarray(t2.node_map), 3 * m1.n_points), a2)
    assert one is not None and two is not None and two.copies > one.copies > 0
    rng = np.random.default_rng(4)
    for a, f in ((a1, one), (a2, two)):
        b = rng.standard_normal(a.shape[0])
        exact = spla.spsolve(a.tocsc(), b)
        assert np.abs(f.solve(b) - exact).max() <= 1e-10 * np.abs(exact).max()


def test_reuses_the_columns_an_insertion_left_alone(monkeypatch):
    """A second crack beside the first leaves the first one's columns of C as they were (to
    round-off), so their columns of G are reused; a third across both splits some of their
    copies again, whose changed columns are solved afresh. Every solve stays the direct
    one's to round-off, and matches the same chain with nothing reused."""
    monkeypatch.setattr(bordered, "SHARE", 1e9)
    monkeypatch.setattr(bordered, "COPIES", 1e9)
    m0 = structured_box((6, 4, 4))
    m1, t1 = crack(m0, 0.5)
    m2, t2 = crack(m1, 2 / 6)
    m3, t3 = crack(m2, 0.5, axis=1)
    systems = [system(m) for m in (m0, m1, m2, m3)]
    ties = [tie(f0, f1, np.asarray(t.node_map), 3 * m.n_points)
            for (_, f0), (_, f1), t, m in zip(systems[:-1], systems[1:], (t1, t2, t3),
                                              (m0, m1, m2), strict=True)]
    rng = np.random.default_rng(1)

    def chain():
        f, out = factorize(systems[0][0]), []
        for (a, _), t in zip(systems[1:], ties, strict=True):
            f = bordered_factor(f, t, a)
            out.append(f)
        return out

    one, two, three = chain()
    assert one.solved == one.copies  # nothing before it to reuse
    assert 0 < two.solved < two.copies  # the first crack's columns reused
    assert two.copies - two.solved == one.copies
    assert 0 < three.copies - three.solved < two.copies  # some of them changed
    monkeypatch.setattr(bordered, "REUSE", -1.0)  # nothing counts as unchanged
    plain = chain()
    assert all(f.solved == f.copies for f in plain)
    for (a, _), f, p in zip(systems[1:], (one, two, three), plain, strict=True):
        b = rng.standard_normal(a.shape[0])
        exact = spla.spsolve(a.tocsc(), b)
        assert np.abs(f.solve(b) - exact).max() <= 1e-10 * np.abs(exact).max()
        assert np.abs(f.solve(b) - p.solve(b)).max() <= 1e-10 * np.abs(exact).max()


def test_two_factors_from_one_keep_their_own_columns(chain, monkeypatch):
    """The columns of G live in one buffer along a chain; a second factor made from the
    same one (a fork) must not write over the first's."""
    (a0, _), (a1, tie1), (a2, tie2) = chain
    monkeypatch.setattr(bordered, "SHARE", 1e9)
    monkeypatch.setattr(bordered, "COPIES", 1e9)
    one = bordered_factor(factorize(a0), tie1, a1)
    two = bordered_factor(one, tie2, a2)
    again = bordered_factor(one, tie2, a2)
    assert again.columns is not two.columns and two.columns is one.columns
    b = np.random.default_rng(2).standard_normal(a2.shape[0])
    exact = spla.spsolve(a2.tocsc(), b)
    for f in (two, again):
        assert np.abs(f.solve(b) - exact).max() <= 1e-10 * np.abs(exact).max()
    b1 = np.random.default_rng(3).standard_normal(a1.shape[0])
    exact1 = spla.spsolve(a1.tocsc(), b1)
    assert np.abs(one.solve(b1) - exact1).max() <= 1e-10 * np.abs(exact1).max()


def test_refactorizes_past_its_share_of_copies(chain, monkeypatch):
    """The base is kept while G (n x m) holds at most SHARE of its factor's entries (where
    the backend reports them; else up to COPIES n^(1/3) copies), past that a fresh
    factorization is asked for (the same answer every time: no clock in the rule)."""
    (a0, _), (a1, tie1), _ = chain
    base = factorize(a0)
    n, m = a0.shape[0], a1.shape[0] - a0.shape[0]
    if base.nonzeros:
        assert base.nonzeros >= a0.nnz // 2  # a Cholesky factor holds A's lower triangle
        monkeypatch.setattr(bordered, "SHARE", m * n / base.nonzeros)
        assert bordered_factor(base, tie1, a1) is not None
        monkeypatch.setattr(bordered, "SHARE", 0.99 * m * n / base.nonzeros)
        assert bordered_factor(base, tie1, a1) is None
    base.nonzeros = None  # a backend that does not report them
    monkeypatch.setattr(bordered, "COPIES", m / n ** (1 / 3))
    assert bordered_factor(base, tie1, a1) is not None
    monkeypatch.setattr(bordered, "COPIES", 0.99 * m / n ** (1 / 3))
    assert bordered_factor(base, tie1, a1) is None


def test_a_piece_cut_loose_is_refused(monkeypatch):
    """A crack right across the cube leaves the far part free: the Schur complement is
    singular, and the caller's fresh factorization is the one to say so."""
    m0 = structured_box((4, 3, 3))
    on = np.flatnonzero(np.abs(m0.points[:, 0] - 0.5) < 1e-12)
    m1, t1 = open_crack(m0, on, np.tile([1.0, 0, 0], (on.size, 1)))
    (a0, f0), (a1, f1) = system(m0), system(m1)
    monkeypatch.setattr(bordered, "SHARE", 1e9)
    monkeypatch.setattr(bordered, "COPIES", 1e9)
    base = factorize(a0)
    assert bordered_factor(base, tie(f0, f1, np.asarray(t1.node_map), 3 * m0.n_points),
                           a1) is None


def test_a_dynamic_run_through_older_factors_equals_one_that_refactorizes(monkeypatch):
    """The first five steps of cases/impact_plate.yaml (Newmark, three of them opening
    cracks in batches): solved after each batch through an older factorization where the
    policy allows, and solved with a fresh factorization after every batch, they give the
    same cracks and the same fields to round-off (the direct solves' own, amplified by the
    conditioning of ``K + c M``: 2e-13 here, four orders under 1e-9)."""
    from ruamel.yaml import YAML

    from fem_frac.solve import discretization
    from solve import run_fracture

    case = YAML(typ="safe").load((ROOT / "cases" / "impact_plate.yaml").read_text())
    case["analysis"]["steps"] = 5
    made = []
    inner = bordered.bordered_factor

    def counted(*args, **kwargs):
        out = inner(*args, **kwargs)
        made.append(out is not None)
        return out

    monkeypatch.setattr(bordered, "bordered_factor", counted)
    _, world, through, _, _ = run_fracture(case, ROOT / "cases")
    assert sum(made) >= 5  # 10 of its 12 batches go through an older factorization
    monkeypatch.setattr(discretization, "_seed", lambda *args: None)
    made.clear()
    _, fresh_world, fresh, _, _ = run_fracture(case, ROOT / "cases")
    assert not made
    assert np.array_equal(world.body.disc.mesh.tets, fresh_world.body.disc.mesh.tets)
    for name in ("u", "v", "a"):
        x, y = getattr(through, name), getattr(fresh, name)
        assert np.abs(x - y).max() <= 1e-9 * np.abs(y).max(), name
