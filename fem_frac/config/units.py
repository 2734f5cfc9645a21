"""Sanity checks of magnitudes against the case's declared unit system (warnings only)."""

from __future__ import annotations

import math

from .schema import Case

# Plausible ranges for engineering solids: (Young's modulus, density, |gravity|).
RANGES = {
    "SI": {"youngs_modulus": (1e3, 2e12, "Pa"), "density": (1.0, 3e4, "kg/m^3"),
           "gravity": (0.1, 100.0, "m/s^2")},
    "mm-N-s": {"youngs_modulus": (1e-3, 2e6, "MPa"), "density": (1e-12, 3e-8, "t/mm^3"),
               "gravity": (100.0, 1e5, "mm/s^2")},
}


def magnitude_warnings(case: Case) -> list[tuple[tuple, str]]:
    """(key path, message) for values far outside the usual range of the unit system."""
    ranges = RANGES[case.units]
    out = []
    checks = [(("material", "youngs_modulus"), case.material.youngs_modulus, "youngs_modulus")]
    if case.material.density is not None:
        checks.append((("material", "density"), case.material.density, "density"))
    if case.body_force is not None:
        g = math.hypot(*case.body_force.gravity)  # no overflow warning for 1e300
        if g > 0:
            checks.append((("body_force", "gravity"), g, "gravity"))
    for path, value, key in checks:
        lo, hi, unit = ranges[key]
        if not lo <= value <= hi:
            out.append((path, f"{value:g} is unusual for {key} in {case.units} units "
                              f"(expected {lo:g} to {hi:g} {unit}); check the 'units' key"))
    return out
