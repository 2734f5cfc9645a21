"""Material properties per element: the case's ``material``, overridden in ``regions``.

A uniform body (no regions) keeps scalar properties, so nothing downstream pays for arrays
it does not need.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import schema
from ..errors import CaseError
from ..mesh.mesh import Mesh


@dataclass(frozen=True, eq=False)
class ElementMaterials:
    """Young's modulus, Poisson's ratio and density: scalars for a uniform body, else
    ``(n_tets,)`` arrays; ``density`` is ``None`` where the case gives none, and an array
    with NaN where some elements have none."""

    youngs_modulus: float | np.ndarray
    poissons_ratio: float | np.ndarray
    density: float | np.ndarray | None
    counts: tuple[int, ...] = ()  # elements per region, in case order

    @property
    def uniform(self) -> bool:
        return np.ndim(self.youngs_modulus) == 0

    def has_density(self) -> bool:
        return self.density is not None and bool(np.all(np.isfinite(self.density)))

    def per_element(self, value) -> np.ndarray:
        """``(n_tets, 1)`` array (broadcasts against ``(n_tets, n_qp)``), or the scalar."""
        return value if np.ndim(value) == 0 else np.asarray(value)[:, None]


def element_materials(material: schema.Material, regions: list[schema.Region],
                      mesh: Mesh) -> ElementMaterials:
    """Per-element properties of the case; an empty or unknown region is a located error."""
    if not regions:
        return ElementMaterials(material.youngs_modulus, material.poissons_ratio,
                                material.density)
    n = mesh.n_tets
    e = np.full(n, material.youngs_modulus)
    nu = np.full(n, material.poissons_ratio)
    rho = np.full(n, np.nan if material.density is None else material.density)
    centroids = mesh.points[mesh.tets].mean(axis=1)
    counts = []
    for i, region in enumerate(regions):
        chosen = selected_elements(mesh, region.subdomain, region.box, ("regions", i),
                                   centroids)
        counts.append(len(chosen))
        if region.youngs_modulus is not None:
            e[chosen] = region.youngs_modulus
        if region.poissons_ratio is not None:
            nu[chosen] = region.poissons_ratio
        if region.density is not None:
            rho[chosen] = region.density
    density = None if np.all(np.isnan(rho)) else rho
    return ElementMaterials(e, nu, density, tuple(counts))


def selected_elements(mesh: Mesh, subdomain: str | None, box, key: tuple,
                      centroids: np.ndarray | None = None, strict: bool = True) -> np.ndarray:
    """Tet ids of the mesh volume group ``subdomain``, or of the tets whose centroid lies in
    ``box`` (a ``schema.BoxSelection``). An unknown group is an error located at
    ``key + ("subdomain",)``; an empty selection one at ``key + (<which>,)`` when ``strict``."""
    if subdomain is not None:
        if subdomain not in mesh.subdomains:
            known = ", ".join(sorted(mesh.subdomains)) or "none"
            raise CaseError(key + ("subdomain",),
                            f"no volume group {subdomain!r} in the mesh (groups: {known})")
        chosen, which = np.asarray(mesh.subdomains[subdomain], dtype=np.int64), "subdomain"
    else:
        if centroids is None:
            centroids = mesh.points[mesh.tets].mean(axis=1)
        lo, hi = np.asarray(box.min), np.asarray(box.max)
        chosen = np.flatnonzero(np.all((centroids >= lo) & (centroids <= hi), axis=1))
        which = "box"
    if len(chosen) == 0 and strict:
        raise CaseError(key + (which,), "selects no elements")
    return chosen

