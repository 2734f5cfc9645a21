"""Double cantilever beam (DCB) in mode I: beam theory with a root-rotation correction.

A symmetric DCB: two arms of height ``h`` and width ``b``, crack length ``a`` from the load
line to the crack tip, equal and opposite opening forces ``P`` at the arm ends, load-point
opening ``delta`` (the two arms together), Young's modulus ``E`` of the arms in bending.
Each arm is a cantilever built in a distance ``chi h`` behind the crack tip, which stands for
the rotation and shear of the arm's root in the uncracked part (Kanninen 1973; Williams
1989):

    C(a) = delta / P = 8 (a + chi h)^3 / (E b h^3)                       (both arms)
    G    = P^2 / (2 b) dC/da = 12 P^2 (a + chi h)^2 / (E b^2 h^3)         (Irwin-Kies)

While the crack grows, G = G_c. Eliminating the crack length between delta = C P and
G = G_c, with the effective length a_e = a + chi h:

    a_e(delta) = sqrt(sqrt(12) delta / 8) (E h^3 / G_c)^(1/4)
    P(delta)   = b sqrt(G_c E h^3 / 12) / a_e
               = (G_c E b^2 h^3 / 12)^(3/4) (8 / (E b h^3 delta))^(1/2)

so on the propagation branch the load does not depend on chi at all (any correction that
shifts the crack length by a constant drops out); the crack length a = a_e - chi h does.

Root-rotation corrections: plane elasticity gives chi = 0.673 (:data:`CHI_PLANE`, whatever
nu); Kanninen's arm on a Winkler foundation of stiffness 2 E b / h (the uncracked half-height
as springs) gives chi = 1 / (lambda h) = 6^(-1/4) = 0.639; Williams (1989), for orthotropic
arms, chi = sqrt(E11 / (11 G13) (3 - 2 (Gamma / (1 + Gamma))^2)) with Gamma = 1.18
sqrt(E11 E22) / G13 (E11 along the arm, E22 through its height, G13 the shear modulus in
their plane): 0.605 for an isotropic material with nu = 0, 0.66 with nu = 0.3. ``E`` is the
modulus of the arms in bending: E for a narrow beam (and, by Saint-Venant, for any
prismatic bar in linear elasticity), E / (1 - nu^2) for a wide plate in cylindrical
bending; the two agree when nu = 0.

Layer 1: numpy and the standard library only.
"""

from __future__ import annotations

import math

import numpy as np

CHI_KANNINEN = 6.0 ** -0.25
"""Kanninen's (1973) root-rotation correction, 1 / (lambda h) with lambda^4 = k / (4 E I)
for a Winkler foundation k = 2 E b / h: 6^(-1/4) = 0.639."""


CHI_PLANE = 0.673
"""The root-rotation correction of plane elasticity: for a long DCB (a several h) the exact
stress intensity factor is K_I = 2 sqrt(3) P (a + 0.673 h) / (b h^(3/2)) up to terms
exponentially small in a / h (Fichter 1983; Foote & Buchwald 1985), so G = K_I^2 / E has
the (a + chi h)^2 of beam theory with chi = 0.673, whatever nu; the compliance, G's
integral, up to a constant (the far end's share)."""


def chi_williams(e11: float, e22: float, g13: float) -> float:
    """Williams' (1989) root-rotation correction of an orthotropic DCB arm:
    ``sqrt(E11 / (11 G13) (3 - 2 (Gamma / (1 + Gamma))^2))``, ``Gamma = 1.18 sqrt(E11 E22) /
    G13``."""
    gamma = 1.18 * math.sqrt(e11 * e22) / g13
    return math.sqrt(e11 / (11.0 * g13) * (3.0 - 2.0 * (gamma / (1.0 + gamma)) ** 2))


def chi_williams_isotropic(poissons_ratio: float) -> float:
    """:func:`chi_williams` of an isotropic material (E11 = E22 = E, G13 = E / (2 (1 + nu)))."""
    return chi_williams(1.0, 1.0, 1.0 / (2.0 * (1.0 + poissons_ratio)))


def compliance(a, youngs_modulus: float, width: float, height: float, chi: float):
    """Load-point compliance ``8 (a + chi h)^3 / (E b h^3)`` of the two arms (opening over
    load)."""
    ae = np.asarray(a, dtype=float) + chi * height
    return 8.0 * ae**3 / (youngs_modulus * width * height**3)


def compliance_slope(a, youngs_modulus: float, width: float, height: float, chi: float):
    """``dC/da = 24 (a + chi h)^2 / (E b h^3)``."""
    ae = np.asarray(a, dtype=float) + chi * height
    return 24.0 * ae**2 / (youngs_modulus * width * height**3)


def energy_release_rate(load, a, youngs_modulus: float, width: float, height: float,
                        chi: float):
    """``G = P^2 / (2 b) dC/da = 12 P^2 (a + chi h)^2 / (E b^2 h^3)``."""
    p = np.asarray(load, dtype=float)
    return p**2 / (2.0 * width) * compliance_slope(a, youngs_modulus, width, height, chi)


def effective_length(opening, youngs_modulus: float, fracture_energy: float,
                     height: float):
    """``a + chi h`` on the propagation branch: ``sqrt(sqrt(12) delta / 8) (E h^3 /
    G_c)^(1/4)`` (independent of the width and of chi)."""
    delta = np.asarray(opening, dtype=float)
    return (np.sqrt(math.sqrt(12.0) * delta / 8.0)
            * (youngs_modulus * height**3 / fracture_energy) ** 0.25)


def crack_length(opening, youngs_modulus: float, fracture_energy: float, height: float,
                 chi: float):
    """Crack length ``a`` (from the load line) at the opening ``delta`` while the crack
    grows: :func:`effective_length` minus ``chi h``."""
    return effective_length(opening, youngs_modulus, fracture_energy, height) - chi * height


def propagation_load(opening, youngs_modulus: float, fracture_energy: float, width: float,
                     height: float):
    """Load at the opening ``delta`` while the crack grows (G = G_c):
    ``(G_c E b^2 h^3 / 12)^(3/4) (8 / (E b h^3 delta))^(1/2)``; independent of chi."""
    delta = np.asarray(opening, dtype=float)
    e, gc, b, h = youngs_modulus, fracture_energy, width, height
    return (gc * e * b**2 * h**3 / 12.0) ** 0.75 * np.sqrt(8.0 / (e * b * h**3 * delta))


def critical_load(a, youngs_modulus: float, fracture_energy: float, width: float,
                  height: float, chi: float):
    """The load at which a crack of length ``a`` starts to grow: ``b sqrt(G_c E h^3 / 12) /
    (a + chi h)``."""
    ae = np.asarray(a, dtype=float) + chi * height
    return width * np.sqrt(fracture_energy * youngs_modulus * height**3 / 12.0) / ae


def initiation_opening(a, youngs_modulus: float, fracture_energy: float, width: float,
                       height: float, chi: float):
    """The opening at which a crack of length ``a`` starts to grow: ``C(a) P_c(a)``."""
    return (compliance(a, youngs_modulus, width, height, chi)
            * critical_load(a, youngs_modulus, fracture_energy, width, height, chi))


def length_from_compliance(c, youngs_modulus: float, width: float, height: float):
    """The effective length ``a + chi h = (C E b h^3 / 8)^(1/3)`` of a measured compliance
    (subtract the crack length to measure chi)."""
    return np.cbrt(np.asarray(c, dtype=float) * youngs_modulus * width * height**3 / 8.0)


def root_bending_stress(youngs_modulus: float, fracture_energy: float, height: float):
    """The bending stress ``6 M / (b h^2)`` at the root of an arm while the crack grows
    (``M = P (a + chi h)`` at G = G_c): ``sqrt(3 G_c E / h)``; in units of the tensile
    strength it is ``sqrt(3 l_cz / h)`` with the cohesive length ``l_cz = E G_c /
    sigma_t^2``. It acts along the arm, parallel to the crack."""
    return math.sqrt(3.0 * fracture_energy * youngs_modulus / height)
