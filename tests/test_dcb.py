"""Double cantilever beam (cases/dcb.yaml): mode-I crack growth against beam theory with a
root-rotation correction (fem_frac/verify/dcb.py). Derivation of every tolerance:
docs/fracture/dcb.md.

- before the crack grows, the load-point compliance gives the root-rotation length chi h,
  which must lie among the published values for isotropic arms (Williams 0.605 at nu = 0,
  Kanninen 0.639, plane elasticity 0.673), widened by the element error of the compliance;
- while it grows (once the theory's crack has run l_cz / 2 past the slit, the process zone
  established), the load at each opening is within 6 s / a_e of the propagation branch (a
  crack that trails the continuum one by up to two elements of size s), and the theory's
  crack length lies between the traction-free crack (less 2 s) and the inserted faces
  (plus 2 s);
- the cohesive faces dissipate G_c per unit area: between G_c times the broken area and
  G_c times the inserted area.

The shipped case (s = 1 mm) runs once for the module (about 20 s on 2 cores); the refined
mesh (s = 0.5 mm, further growth) is a slow test.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import meshio
import numpy as np
import pytest
from ruamel.yaml import YAML

from fem_frac.app.cli import main
from fem_frac.verify import dcb
from fem_frac.writers.history import read_history

ROOT = Path(__file__).parent.parent
CASE = ROOT / "cases" / "dcb.yaml"
GEO = ROOT / "meshes" / "dcb.geo"
NAME = CASE.stem
# published root-rotation corrections for isotropic arms (fem_frac/verify/dcb.py)
CHI_RANGE = (dcb.chi_williams_isotropic(0.0), dcb.CHI_PLANE)
# the element error of the elastic compliance, measured by refinement (docs/fracture/dcb.md:
# 0.9 % at s = 1 mm, 0.5 % at 0.5 mm, 0.3 % at 0.25 mm), bounded by 1.5 % at 1 mm and 1 %
# at 0.5 mm
COMPLIANCE_ERROR = 0.015


def geo_numbers(text: str) -> dict[str, float]:
    """The numeric assignments ``name = value;`` of a .geo text (its parameters)."""
    return {k: float(v) for k, v in re.findall(r"\b([A-Za-z]\w*) = ([-+0-9.eE]+);", text)}


@dataclass
class Run:
    """What a DCB run gives, per step: the opening ``delta`` and the load ``load`` of the
    upper arm; the crack length from the load line by the inserted faces ``a_inserted``, by
    the broken (traction-free) faces ``a_broken`` and by the dissipated energy
    (``a0 + D / (G_c b)``) ``a_dissipated``; the number of crack faces; with the
    geometry, the material and the summary."""

    delta: np.ndarray
    load: np.ndarray
    a_inserted: np.ndarray
    a_broken: np.ndarray
    a_dissipated: np.ndarray
    faces: np.ndarray
    normals_ok: bool
    dissipated: np.ndarray
    geo: dict
    case: dict
    summary: dict

    @property
    def E(self) -> float:
        return float(self.case["material"]["youngs_modulus"])

    @property
    def gc(self) -> float:
        return float(self.case["fracture"]["fracture_energy"])

    @property
    def lcz(self) -> float:
        return self.E * self.gc / float(self.case["fracture"]["tensile_strength"]) ** 2


def run_dcb(out: Path, geo_changes: dict | None = None, sets: tuple = ()) -> Run:
    """Run cases/dcb.yaml into ``out`` (the mesh file with ``geo_changes`` to its
    parameters, ``--set`` options ``sets``) and measure it."""
    args = ["run", str(CASE), "-o", str(out), "-q"]
    text = GEO.read_text()
    if geo_changes:
        for key, value in geo_changes.items():
            text, n = re.subn(rf"^{key} = [-+0-9.eE]+;", f"{key} = {value!r};", text,
                              flags=re.M)
            assert n == 1, key
        out.parent.mkdir(parents=True, exist_ok=True)
        geo = out.parent / f"{out.name}.geo"
        geo.write_text(text)
        args += ["--set", f"mesh.file={geo}"]
    for s in sets:
        args += ["--set", s]
    assert main(args) == 0
    return measure(out, geo_numbers(text))


def measure(out: Path, geo: dict) -> Run:
    """The per-step quantities of a finished run in ``out`` (see :class:`Run`)."""
    case = YAML(typ="safe").load((out / "case.resolved.yaml").read_text())
    summary = json.loads((out / "summary.json").read_text())
    history = read_history(out / "history.csv")
    (bc,) = [c for c in case["boundary_conditions"] if c.get("boundary") == "load_top"
             and c["type"] == "displacement"]
    points = np.asarray(case["load_curves"][bc["curve"]]["points"], dtype=float)
    t = np.asarray(history["time"])
    delta = 2.0 * bc["z"] * np.interp(t, points[:, 0], points[:, 1])
    b, h, a0 = geo["b"], geo["h"], geo["a0"]
    gc = float(case["fracture"]["fracture_energy"])
    inserted, broken, faces, ok = [], [], [], True
    for step in range(len(t)):
        crack = meshio.read(out / f"{NAME}_crack_{step:06d}.vtu")
        tri = crack.cells_dict.get("triangle", np.zeros((0, 3), dtype=int))
        p = crack.points[tri]
        area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        if len(tri):
            damage = crack.cell_data_dict["damage"]["triangle"]
            normal = crack.cell_data_dict["normal"]["triangle"]
            ok &= bool(np.all(np.abs(normal[:, 2]) > 1 - 1e-9))
            ok &= bool(np.all(np.abs(p[:, :, 2] - h) < 1e-9))
            ok &= bool(np.all(p[:, :, 0] >= a0 - 1e-9))
        else:
            damage = np.zeros(0)
        inserted.append(area.sum())
        broken.append(area[damage >= 1.0 - 1e-9].sum())
        faces.append(len(tri))
    dissipated = np.asarray(history["cohesive_dissipated"])
    # the compression along the arms alone (step 0) pulls a little on the load faces: the
    # slit's flanks are tilted by e / a0, and the arms with them (meshes/dcb.geo); its share
    # is constant and, the problem being linear until cracks open, subtracted
    reaction = np.asarray(history["reaction_load_top_z"])
    return Run(delta, reaction - reaction[0],
               a0 + np.asarray(inserted) / b, a0 + np.asarray(broken) / b,
               a0 + dissipated / (gc * b), np.asarray(faces), ok, dissipated, geo, case,
               summary)


def growth_steps(r: Run) -> np.ndarray:
    """Steps past the process zone's development: the theory's crack has run l_cz / 2."""
    g = r.geo
    a = dcb.crack_length(r.delta, r.E, r.gc, g["h"], dcb.CHI_PLANE)
    return np.flatnonzero(a >= g["a0"] + r.lcz / 2.0)


def load_errors(r: Run) -> tuple[np.ndarray, np.ndarray]:
    """``(P / P_theory - 1, 6 s / a_e)`` on the growth steps."""
    g = r.geo
    k = growth_steps(r)
    theory = dcb.propagation_load(r.delta[k], r.E, r.gc, g["b"], g["h"])
    ae = dcb.effective_length(r.delta[k], r.E, r.gc, g["h"])
    return r.load[k] / theory - 1.0, 6.0 * g["s"] / ae


# --- the closed form ------------------------------------------------------------------------

E, GC, B, H, A = 10e9, 18.0, 0.001, 0.01, 0.04


def test_compliance_slope_is_the_derivative_of_the_compliance():
    a = np.linspace(0.02, 0.08, 7)
    step = 1e-7
    for chi in (0.0, dcb.CHI_KANNINEN, dcb.CHI_PLANE):
        fd = (dcb.compliance(a + step, E, B, H, chi)
              - dcb.compliance(a - step, E, B, H, chi)) / (2 * step)
        np.testing.assert_allclose(dcb.compliance_slope(a, E, B, H, chi), fd, rtol=1e-7)
        # Irwin-Kies: G = P^2 / (2 b) dC/da
        np.testing.assert_allclose(dcb.energy_release_rate(2.0, a, E, B, H, chi),
                                   4.0 / (2 * B) * fd, rtol=1e-7)


def test_propagation_branch_satisfies_g_equals_gc():
    """On the branch, G(P(delta), a(delta)) = G_c and delta = C(a) P, for any chi; the load
    does not depend on chi; it starts where the initial crack's critical load is reached."""
    delta = np.linspace(1e-4, 6e-4, 11)
    load = dcb.propagation_load(delta, E, GC, B, H)
    for chi in (0.0, dcb.chi_williams_isotropic(0.0), dcb.CHI_KANNINEN, dcb.CHI_PLANE):
        a = dcb.crack_length(delta, E, GC, H, chi)
        np.testing.assert_allclose(dcb.energy_release_rate(load, a, E, B, H, chi), GC,
                                   rtol=1e-12)
        np.testing.assert_allclose(dcb.compliance(a, E, B, H, chi) * load, delta, rtol=1e-12)
        d0 = dcb.initiation_opening(A, E, GC, B, H, chi)
        np.testing.assert_allclose(dcb.propagation_load(d0, E, GC, B, H),
                                   dcb.critical_load(A, E, GC, B, H, chi), rtol=1e-12)
    # the branch of a wider beam carries proportionally more load
    np.testing.assert_allclose(dcb.propagation_load(delta, E, GC, 3 * B, H), 3 * load,
                               rtol=1e-12)
    ae = dcb.length_from_compliance(delta / load, E, B, H)
    np.testing.assert_allclose(ae, dcb.effective_length(delta, E, GC, H), rtol=1e-12)


def test_root_rotation_corrections():
    assert dcb.CHI_KANNINEN == pytest.approx(0.6389, abs=1e-4)
    assert dcb.chi_williams_isotropic(0.0) == pytest.approx(0.605, abs=1e-3)
    assert dcb.chi_williams_isotropic(0.3) == pytest.approx(0.6635, abs=1e-3)
    # orthotropic arms stiff along the beam have a longer root (Williams 1989)
    assert dcb.chi_williams(140e9, 10e9, 5e9) > 1.0
    # root bending stress on the branch: 6 P a_e / (b h^2)
    load = dcb.critical_load(A, E, GC, B, H, dcb.CHI_PLANE)
    assert dcb.root_bending_stress(E, GC, H) == pytest.approx(
        6 * load * (A + dcb.CHI_PLANE * H) / (B * H**2), rel=1e-12)


# --- the shipped case -----------------------------------------------------------------------

@pytest.fixture(scope="module")
def coarse(tmp_path_factory):
    return run_dcb(tmp_path_factory.mktemp("dcb") / "coarse")


def test_dcb_elastic_compliance_gives_the_root_rotation(coarse):
    """Step 1 is elastic (no face yet); its compliance makes chi h the length between the
    crack tip and the beam's built-in end, among the published values +- the element
    error."""
    r, g = coarse, coarse.geo
    assert r.faces[1] == 0
    compliance = r.delta[1] / r.load[1]
    chi = (dcb.length_from_compliance(compliance, r.E, g["b"], g["h"]) - g["a0"]) / g["h"]
    slack = COMPLIANCE_ERROR * (g["a0"] + dcb.CHI_PLANE * g["h"]) / (3 * g["h"])
    assert CHI_RANGE[0] - slack <= chi <= CHI_RANGE[1] + slack
    # with the plane-elasticity value the compliance is within the element error
    assert compliance == pytest.approx(
        dcb.compliance(g["a0"], r.E, g["b"], g["h"], dcb.CHI_PLANE), rel=COMPLIANCE_ERROR)


def test_dcb_crack_grows_in_the_mid_plane(coarse):
    r, g = coarse, coarse.geo
    assert r.normals_ok  # every face normal to z, in the plane z = h, ahead of the slit
    assert r.summary["fracture"]["fragments"] == 1
    # it grew: more than l_cz past the slit by the end
    assert r.a_broken[-1] > g["a0"] + r.lcz


def test_dcb_load_follows_beam_theory_while_the_crack_grows(coarse):
    error, tolerance = load_errors(coarse)
    assert len(error) >= 4
    assert np.all(np.abs(error) <= tolerance), (error, tolerance)


def test_dcb_crack_length_follows_beam_theory(coarse):
    r, g = coarse, coarse.geo
    k = growth_steps(r)
    theory = dcb.crack_length(r.delta[k], r.E, r.gc, g["h"], dcb.CHI_PLANE)
    lag = 2 * g["s"]
    assert np.all(r.a_broken[k] - lag <= theory), (r.a_broken[k], theory)
    assert np.all(theory <= r.a_inserted[k] + lag), (r.a_inserted[k], theory)
    # and it grows as much as the theory says, within the same bounds
    grown = theory[-1] - theory[0]
    assert r.a_inserted[k[-1]] - r.a_broken[k[0]] + 2 * lag >= grown
    assert r.a_broken[k[-1]] - r.a_inserted[k[0]] - 2 * lag <= grown


def test_dcb_faces_dissipate_the_fracture_energy(coarse):
    """Broken faces have dissipated G_c per unit area, the rest of the inserted ones less."""
    r, b = coarse, coarse.geo["b"]
    low = r.gc * b * (r.a_broken - r.geo["a0"])
    high = r.gc * b * (r.a_inserted - r.geo["a0"])
    assert np.all(low <= r.dissipated * (1 + 1e-9))
    assert np.all(r.dissipated <= high * (1 + 1e-9))
    assert r.dissipated[-1] > 0


@pytest.mark.slow
def test_dcb_refined_mesh_is_closer_to_beam_theory(coarse, tmp_path):
    """Elements of 0.5 mm on the crack path, the crack grown further (to ~ 54 mm) in
    finer steps: the same bounds at half the element size, and a smaller error of the load
    than on the shipped 1 mm mesh (about 2 minutes on 2 cores)."""
    r = run_dcb(tmp_path / "fine", {"s": 0.0005}, (
        "boundary_conditions.1.z=1.8e-4", "boundary_conditions.2.z=-1.8e-4",
        "load_curves.opening.points=[[0, 0], [0.025, 0.1], [0.05, 0.3], [1, 1]]",
        "analysis.steps=40"))
    g = r.geo
    assert r.faces[1] == 0 and r.normals_ok
    compliance = r.delta[1] / r.load[1]
    assert compliance == pytest.approx(
        dcb.compliance(g["a0"], r.E, g["b"], g["h"], dcb.CHI_PLANE), rel=0.01)
    error, tolerance = load_errors(r)
    assert np.all(np.abs(error) <= tolerance), (error, tolerance)
    k = growth_steps(r)
    theory = dcb.crack_length(r.delta[k], r.E, r.gc, g["h"], dcb.CHI_PLANE)
    assert np.all(r.a_broken[k] - 2 * g["s"] <= theory)
    assert np.all(theory <= r.a_inserted[k] + 2 * g["s"])
    assert r.a_broken[-1] > g["a0"] + 2 * r.lcz
    coarse_error, _ = load_errors(coarse)
    assert np.abs(error).max() < np.abs(coarse_error).max()
