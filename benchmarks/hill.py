"""Elastic-perfectly plastic thick sphere against Hill's closed form, and volumetric locking
of linear tets.

    python benchmarks/hill.py        # prints the tables, writes docs/plasticity.md (~5 min)

Case and measures: tests/test_hill.py. Convergence study at nu = 0.3, plastic radius
c = 1.5, three sizes each of P1, P1 averaged (B-bar) and P2; locking study on the two
coarser of them with nu = 0.3 and 0.49 at c = 1.5, and nu = 0.3 near the limit load
(c = 1.9).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent.parent / "tests"))

from test_hill import (  # noqa: E402
    FINE,
    SIGMA_Y,
    A,
    B,
    E,
    HillResult,
    averaged_available,
    hill,
    slope,
)

from fem_frac.verify.exact import hill_sphere_outer_displacement, hill_sphere_pressure  # noqa: E402

DOC = Path(__file__).parent.parent / "docs" / "plasticity.md"
LOCKING_SIZES = FINE[:2]
LOCKING_CASES = ((0.3, 1.5), (0.49, 1.5), (0.3, 1.9))
_RUNS: dict[tuple, HillResult] = {}


def once(order: int, size: float, formulation: str = "standard", nu: float = 0.3,
         c: float = 1.5) -> HillResult:
    """:func:`hill`, each case run once (the locking study repeats convergence rows)."""
    key = (order, size, formulation, nu, c)
    if key not in _RUNS:
        _RUNS[key] = hill(*key)
    return _RUNS[key]


def elements() -> list[tuple[int, str]]:
    out = [(1, "standard")]
    if averaged_available():
        out.append((1, "averaged"))
    else:
        print("formulation 'averaged' is not available here: its rows are skipped")
    return out + [(2, "standard")]


def convergence() -> dict[str, list[HillResult]]:
    runs = {}
    for order, formulation in elements():
        rows = [once(order, s, formulation) for s in FINE]
        runs[rows[0].element] = rows
    return runs


def locking() -> list[HillResult]:
    return [once(order, s, formulation, nu, c)
            for nu, c in LOCKING_CASES
            for order, formulation in elements()
            for s in LOCKING_SIZES]


def convergence_table(runs: dict[str, list[HillResult]]) -> str:
    lines = ["| element | element size | mean h | dofs | c_h | c error | u_b error | "
             "iterations | wall s |", "|---|---|---|---|---|---|---|---|---|"]
    for element, rows in runs.items():
        for r in rows:
            lines.append(f"| {element} | {r.size:g} | {r.h:.4f} | {r.dofs:,} | {r.c_h:.4f} | "
                         f"{r.c_error:+.2e} | {r.u_b_error:+.2e} | {r.iterations} | "
                         f"{r.wall:.1f} |")
        lines.append(f"| {element} | fitted slope | | | | {slope(rows, 'c_error'):.2f} | "
                     f"{slope(rows, 'u_b_error'):.2f} | | |")
    return "\n".join(lines)


def locking_table(rows: list[HillResult]) -> str:
    lines = ["| nu | c | p / p_L | element | mean h | c_h | c error | u_b error | "
             "u_b error of the P1 facets | iterations | wall s |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    p_l = 2 * SIGMA_Y * np.log(B / A)
    for r in rows:
        p = float(hill_sphere_pressure(r.c, A, B, SIGMA_Y))
        geometry = "" if r.order == 2 else f"{r.geometry_u_b_error:+.2e}"
        lines.append(f"| {r.nu:g} | {r.c:g} | {p / p_l:.3f} | {r.element} | {r.h:.4f} | "
                     f"{r.c_h:.4f} | {r.c_error:+.2e} | {r.u_b_error:+.2e} | {geometry} | "
                     f"{r.iterations} | {r.wall:.1f} |")
    return "\n".join(lines)


def summary_table(rows: list[HillResult]) -> str:
    """u_b error per element and mesh (rows) and case (columns)."""
    head = " | ".join(f"nu = {nu:g}, c = {c:g}" for nu, c in LOCKING_CASES)
    lines = [f"| element | mean h | {head} |", "|---|---|" + "---|" * len(LOCKING_CASES)]
    for order, formulation in elements():
        for size in LOCKING_SIZES:
            picked = [pick(rows, order, formulation, nu, c, size) for nu, c in LOCKING_CASES]
            cells = " | ".join(f"{r.u_b_error:+.2%}" for r in picked)
            lines.append(f"| {picked[0].element} | {picked[0].h:.3f} | {cells} |")
    return "\n".join(lines)


def pick(rows: list[HillResult], order: int, formulation: str, nu: float, c: float,
         size: float) -> HillResult:
    return next(r for r in rows
                if (r.order, r.formulation, r.nu, r.c, r.size) == (order, formulation, nu, c, size))


def document(runs: dict[str, list[HillResult]], locked: list[HillResult]) -> str:
    def p(c):
        return float(hill_sphere_pressure(c, A, B, SIGMA_Y))

    ub = {nu: hill_sphere_outer_displacement(1.5, B, SIGMA_Y, E, nu) for nu in (0.3, 0.49)}
    s = {e: (slope(rows, "c_error"), slope(rows, "u_b_error")) for e, rows in runs.items()}
    nan = (float("nan"), float("nan"))
    coarse, fine = LOCKING_SIZES

    def err(order, formulation, nu, c, size=coarse):
        if formulation == "averaged" and "P1 averaged" not in runs:
            return "n/a"
        return f"{abs(pick(locked, order, formulation, nu, c, size).u_b_error):.1%}"

    finest = {e: rows[-1] for e, rows in runs.items()}
    layers = [abs(r.c_h - r.c) / r.h for e, rows in runs.items() if e != "P2" for r in rows]
    avg = finest.get("P1 averaged")
    return TEMPLATE.format(
        p15=p(1.5), p19=p(1.9), p_e=p(A), p_l=p(B), ub03=ub[0.3], ub049=ub[0.49],
        r15=p(1.5) / p(B), r19=p(1.9) / p(B),
        convergence=convergence_table(runs), locking=locking_table(locked),
        summary=summary_table(locked),
        s1c=s["P1"][0], s1u=s["P1"][1], s2c=s["P2"][0], s2u=s["P2"][1],
        sac=s.get("P1 averaged", nan)[0], sau=s.get("P1 averaged", nan)[1],
        p2u_coarse=abs(runs["P2"][0].u_b_error), p2c_coarse=abs(runs["P2"][0].c_error),
        p2_dofs=runs["P2"][0].dofs, p2_wall=runs["P2"][0].wall,
        p1u_fine=abs(finest["P1"].u_b_error), p1_dofs=finest["P1"].dofs,
        au_fine=abs(avg.u_b_error) if avg else float("nan"),
        ag_fine=abs(avg.geometry_u_b_error) if avg else float("nan"),
        a_wall=avg.wall if avg else float("nan"), p1_wall=finest["P1"].wall,
        p1_03=err(1, "standard", 0.3, 1.5), p1_049=err(1, "standard", 0.49, 1.5),
        p1_19=err(1, "standard", 0.3, 1.9),
        pa_03=err(1, "averaged", 0.3, 1.5), pa_049=err(1, "averaged", 0.49, 1.5),
        pa_19=err(1, "averaged", 0.3, 1.9),
        pa_19f=err(1, "averaged", 0.3, 1.9, fine),
        pa_19g=f"{abs(pick(locked, 1, 'standard', 0.3, 1.9, coarse).geometry_u_b_error):.1%}",
        pa_19gf=f"{abs(pick(locked, 1, 'standard', 0.3, 1.9, fine).geometry_u_b_error):.1%}",
        p2_049=err(2, "standard", 0.49, 1.5), p2_19=err(2, "standard", 0.3, 1.9),
        h_coarse=pick(locked, 2, "standard", 0.3, 1.5, coarse).h,
        h_fine=pick(locked, 2, "standard", 0.3, 1.5, fine).h,
        it15=runs["P2"][-1].iterations / 10,
        lay_lo=min(layers), lay_hi=max(layers),
        shift_c=pick(locked, 1, "standard", 0.3, 1.9, coarse).limit_load_shift,
        shift_f=pick(locked, 1, "standard", 0.3, 1.9, fine).limit_load_shift,
        margin=1.0 - p(1.9) / p(B),
        it19=pick(locked, 2, "standard", 0.3, 1.9, fine).iterations / 10,
    )


TEMPLATE = """\
# Plasticity verification: Hill's thick sphere

Every figure here is reproduced by `python benchmarks/hill.py` (a few minutes; it rewrites
this file). Wall times are from the 2-core development machine, shared with other jobs
while these were taken: read them as rough. The pytest suite asserts the same properties
on coarser meshes (`tests/test_hill.py`); `python -m pytest -m slow tests/test_hill.py`
runs the convergence meshes below and checks the fitted rates. The closed form itself is
checked in `tests/test_exact.py`.

## Problem and closed form

Octant of a thick-walled sphere, inner radius a = 1, outer b = 2 (units mm-N-s: mm, MPa),
symmetry supports on the three planes, internal pressure p ramped from 0 over 10
quasi-static steps (modified Newton, relative residual 1e-8). E = 210e3, nu = 0.3 (0.49 in
the locking study), von Mises with yield stress sigma_Y = 240 and no hardening.

Hill (The Mathematical Theory of Plasticity, 1950, ch. V), small strain: the stress is
spherically symmetric with sigma_theta = sigma_phi > sigma_r, so von Mises and Tresca agree
(equivalent stress sigma_theta - sigma_r). The plastic zone a <= r <= c is statically
determined, sigma_r = -p + 2 sigma_Y ln(r/a), sigma_theta = sigma_r + sigma_Y; the shell
c <= r <= b is elastic and at yield on r = c. Then

    p(c) = 2 sigma_Y [ln(c/a) + (1 - c^3/b^3) / 3],      u_b = sigma_Y (1 - nu) c^3 / (E b^2),

first yield at p_e = p(a) = {p_e:.1f}, limit load p_L = p(b) = 2 sigma_Y ln(b/a) = {p_l:.1f}.
The loading is monotonic (no point unloads), so the final state does not depend on the
path or the number of steps. `fem_frac.verify.exact.hill_sphere_*` implements these, with c from p
by Brent's method; `tests/test_exact.py` checks p(a) = p_e, p(b) = p_L, the inverse, and that
u_b at c = a is Lamé's outer displacement under p_e.

The pressure is chosen for c = 1.5: p = {p15:.2f} ({r15:.3f} p_L); exact u_b = {ub03:.4e} mm
at nu = 0.3 ({ub049:.4e} at nu = 0.49). Near the limit load: c = 1.9, p = {p19:.2f}
({r19:.3f} p_L). There the answer is sensitive: dp/dc = 2 sigma_Y (1/c - c^2/b^3) is 3.3x
smaller at c = 1.9 than at c = 1.5, and u_b grows like c^3.

## Measures

- **Outer displacement u_b**: mean of u . x/|x| over the nodes of the outer surface (for P2
  its vertices and mid-side nodes). u_r is uniform on r = b in the exact solution, so any
  average of it converges like the nodal values. u_b is a property of the elastic shell
  alone and grows like c^3: a relative error dc/c of the FE's plastic zone moves it by
  3 dc/c.
- **Plastic radius c_h**: from the yielded volume. V_p = sum of the quadrature weights dx
  of the points whose equivalent plastic strain is > 0; the octant of the shell a..c has
  volume (pi/6)(c^3 - a^3), so c_h = (a^3 + 6 V_p/pi)^(1/3).

Why c_h converges, at O(h): V_p is the quadrature sum of the indicator of the FE's yielded
set. The indicator jumps across the elastic-plastic interface, so the sum is exact only in
the cells (a quadrature point and its weight, of diameter O(h)) that the interface does not
cross: the error is confined to one layer of cells along the sphere r = c, of volume
O(c^2 h). To it adds the shift of the FE's interface itself: the stress error divided by
the slope of the equivalent stress just outside r = c (it is sigma_Y c^3/r^3 in the elastic
shell, slope -3 sigma_Y/c, nonzero), O(h) for P1 and O(h^2) for P2. Hence
|V_p - V| = O(h) and, dividing by dV/dc = (pi/2) c^2, |c_h - c| = O(h). For P1 (one point
per tet) the error has a sign: a tet's stress is constant, and in the tets the interface
crosses it stays below yield, so they stay elastic and c_h lies about half a tet layer low
(|c_h - c| / h from {lay_lo:.2f} to {lay_hi:.2f} in the P1 rows below). With four points
per P2 tet the cells are smaller and the stress at each point is the local one, so the
constant is far smaller; the rate is the same. h is the mean element size
(volume / n_tets)^(1/3).

## Convergence (nu = 0.3, c = 1.5)

{convergence}

Reading:

- **P2** is within {p2u_coarse:.1e} (u_b) and {p2c_coarse:.1e} (c) of Hill on the
  coarsest mesh ({p2_dofs:,} dofs, {p2_wall:.0f} s). u_b converges at a fitted rate
  {s2u:.1f}, at least the 2 expected (the shell c..b is elastic and smooth, the
  displacement C^1 across the interface; the slope scatters, the meshes being unstructured
  and the error small). c_h converges at {s2c:.1f}, the O(h) of the cell layer; its error
  stays positive.
- **P1 averaged** (nodal-averaged volumetric strain, B-bar): u_b at rate {sau:.1f}, c_h at
  {sac:.1f}. On the finest mesh its u_b error {au_fine:.2%} is mostly geometry, not the
  element: the flat facets of P1 cut inside both spheres (by O(h^2)), and Hill's u_b for the
  spheres of the same volumes as the two polyhedral surfaces is already {ag_fine:.2%} low
  (the last column of the next table).
- **P1 standard** converges (rates {s1c:.1f} for c_h, {s1u:.1f} for u_b), but from far: u_b is
  still {p1u_fine:.1%} low at {p1_dofs:,} dofs, several times the averaged element's error on
  the same mesh; the difference is locking (next section). The element is too stiff, its
  plastic zone too small, and u_b low by about 3x its c error (u_b ~ c^3).
- Cost: P2 is the cheapest per accuracy by far: its coarsest run beats the finest of
  either P1. The averaged P1 factorizes a wider stencil than the standard one and iterates
  more ({a_wall:.0f} s against {p1_wall:.0f} s on the finest mesh).
- Iterations: modified Newton with the elastic matrix, Anderson-accelerated (the default),
  about {it15:.0f} iterations a load step on average over the ten (one each while the wall is
  still elastic, so more in each step after it yields; `python benchmarks/hill_speed.py`
  prints them per step) (plain modified Newton, linear convergence: about 3x as many, with
  the same results); every run reached 1e-8.

One load step is enough for this case: the loading is monotonic and proportional, and on
the same mesh one step reaches the u_b of ten to 6e-5 of itself or better, 0.4-1.3 % of
the discretization error on meshes of element size 0.5 to 0.24 (a discretization effect,
it shrinks with h; `tests/test_hill_speed.py`), in 30 iterations instead of 102, 22 at
tolerance 1e-6, which moves u_b by 5e-8. Run as a whole `fem-frac run`, P2 in one step
reaches -1.46e-3 at element size 0.24 in 1.8 CPU s (tolerance 1e-6; the least of 3 runs,
which vary by up to 0.5 s) and -8.3e-5 at 0.1 in 11.7 (1e-5), against 2.2 and 19.6 with
the ten steps above; full Newton takes 6
iterations in one step but costs more than it saves (`python benchmarks/hill_speed.py`,
docs/performance.md, "The Hill sphere: error against process CPU time").

## Volumetric locking of linear tets

Plastic flow is isochoric. A standard linear tet mesh has one volumetric-strain constraint
per element, against about 0.5 free displacement components per element (3 per vertex,
some 5 to 6 tets per vertex), so where the wall flows (or everywhere as nu -> 1/2) the
displacement fields that satisfy them are too few and too stiff. The averaged formulation
has about one constraint per vertex. The two coarser meshes of the
convergence study, every element, at nu = 0.3 and 0.49 (c = 1.5) and near the limit load
(c = 1.9, nu = 0.3). The column "u_b error of the P1 facets" is Hill's u_b for spheres of
the same volumes as the polyhedral inner and outer surfaces of the P1 mesh: the share of
the error that geometry alone explains.

{locking}

u_b error, by element, mesh (h = {h_coarse:.3f} and {h_fine:.3f}) and case:

{summary}

Reading:

- **Standard P1 locks.** On the h = {h_coarse:.3f} mesh its u_b error grows from {p1_03} at
  nu = 0.3 to {p1_049} at nu = 0.49, and to {p1_19} near the limit load, where almost the
  whole wall flows. The exact u_b depends on nu only through the factor (1 - nu), so the
  growth is the element's, not the problem's. Even at nu = 0.3 and c = 1.5 the isochoric
  plastic flow makes it several times worse than the averaged P1.
- **The averaged P1 locks far less**: {pa_03}, {pa_049} and {pa_19} on the same mesh, and
  its nu = 0.49 error shrinks fast with h. Near the limit load it converges slowly ({pa_19}
  to {pa_19f}), and geometry explains most of it: the polyhedral surfaces raise the limit
  load 2 sigma_Y ln(b/a) by {shift_c:.2%} on the coarse mesh and {shift_f:.2%} on the finer,
  against the {margin:.2%} margin left at c = 1.9; that alone puts u_b {pa_19g} and
  {pa_19gf} low.
- **P2 neither locks** ({p2_049} at nu = 0.49, {p2_19} near the limit) **nor suffers from
  the geometry**: it is isoparametric, its mid-side nodes lie on the spheres.
- Near the limit load modified Newton needs about {it19:.0f} iterations a load step on average
  over the ten (the flowing
  wall is far softer than the elastic matrix). The step count changes only the cost, not
  the answer (monotonic loading).

## Warnings before a run

`fem-frac check` (in its report, under `locking`) and `fem-frac run` (on stderr, before
the first step, also with `-q`) warn when linear tets will be too stiff, quoting the
figures of this page (`fem_frac/app/locking.py`):

- **standard linear tets with plasticity** (`mesh.order: 1`, `mesh.formulation: standard`,
  a `plasticity` section): the isochoric flow locks them (above: u_b 18.2 % low on the
  coarse mesh at nu = 0.3, against 3.6 % averaged and 0.15 % P2). Use `mesh.order: 2` or
  `mesh.formulation: averaged`. Neither P2 nor the averaged formulation is warned of.
- **standard linear tets with nu >= 0.45** (the largest nu of the material and its
  regions, plastic or not): the bulk modulus is then at least 9.7 times the shear modulus,
  K / G = 2 (1 + nu) / (3 (1 - 2 nu)), printed for the case (above, at nu = 0.49, K / G = 50:
  53.2 % low, 7.9 % averaged, 0.26 % P2).
- **fewer than 4 linear tets across the body's extent in a direction it is loaded along**
  (standard or averaged): the count is the side of the bounding box over the median of the
  tets' mean edge lengths, for each axis along which a force (surface load, gravity), a
  non-zero prescribed displacement, an initial velocity or an initial displacement acts;
  a plate pulled in its own plane is not warned of, a plate pressed across it is. A thin
  curved wall (a hollow sphere's) is not measured. The shipped cantilever
  (`cases/cantilever.yaml`, tip shear, Timoshenko's tip deflection as the reference):

  | order | element_size | elements across the depth | dofs | tip deflection error |
  |---|---|---|---|---|
  | P1 | 0.1 | 1.19 | 258 | -0.535 |
  | P1 | 0.05 | 1.64 | 579 | -0.447 |
  | P1 | 0.0333 | 2.64 | 1,785 | -0.233 |
  | P1 | 0.025 | 3.34 | 3,327 | -0.153 |
  | P2 | 0.1 | 1.19 | 1,329 | -0.013 |
  | P2 | 0.05 | 1.64 | 3,081 | -0.009 |

  (`python benchmarks/thin_cantilever.py`, about a minute on 2 cores.) P1 stays 15 % too
  stiff with 3.3 elements across the depth; P2 is within 1.3 % with one.

```
locking
  warning: linear tets (mesh.order 1, formulation standard) lock under plastic flow,
    ... ; use mesh.order: 2 or mesh.formulation: averaged
```
"""


def main() -> None:
    runs = convergence()
    print("Convergence, nu = 0.3, c = 1.5\n")
    print(convergence_table(runs))
    locked = locking()
    print("\nLocking\n")
    print(locking_table(locked))
    DOC.write_text(document(runs, locked))
    print(f"\nwrote {DOC}")


if __name__ == "__main__":
    main()
