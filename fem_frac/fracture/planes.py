"""Prescribed crack planes: cracks that may open only in given planes (``fracture.planes``).

Where the path of a crack is known in advance (the ligament of a notched specimen, a glued
joint) a model may confine cracks to it, as interface elements along a predefined path do.
A plane is usable where it is a mesh surface: a vertex on the plane (within ``TOL`` of the
mesh's extent) may split only when none of its tets crosses the plane, so the split, which
gives new copies of the vertex to the tets on one side of the plane through it
(:func:`~fem_frac.mesh.crack.open_crack`), opens exactly the mesh faces in the plane.

An element with a usable vertex is checked against the smoothed normal stress on that
vertex's plane, ``n . sigma . n``, instead of its largest principal stress (the crack can
open nowhere else), and its crack normal is the plane's normal ``n``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fem.tensors import matrices_from_mandel

# A vertex lies on a plane when its distance from it is below this share of the mesh's
# largest extent (gmsh places the nodes of a plane surface on it to round-off).
TOL = 1e-9


@dataclass(frozen=True, eq=False)
class PlaneSites:
    """The planes on one mesh: ``usable (n,)`` the vertices that may split, ``normal (m, 3)``
    each tet's crack normal (the plane of its first usable vertex; zero where it has none)
    and ``crossing (m,)`` the tets that cross a plane."""

    usable: np.ndarray
    normal: np.ndarray
    crossing: np.ndarray

    @property
    def elements(self) -> np.ndarray:
        """``(m,)`` bool: the tets with a usable vertex."""
        return np.linalg.norm(self.normal, axis=1) > 0


def unit_normals(planes) -> np.ndarray:
    """``(k, 3)`` unit normals of the ``planes`` (schema entries)."""
    n = np.array([p.normal for p in planes], dtype=float).reshape(-1, 3)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def plane_sites(points: np.ndarray, tets: np.ndarray, planes) -> PlaneSites:
    """The usable vertices and the tets' crack normals of ``planes`` on the mesh
    ``points (n, 3)``, ``tets (m, 4)`` (module docstring)."""
    normals = unit_normals(planes)
    origin = np.array([p.point for p in planes], dtype=float).reshape(-1, 3)
    tol = TOL * float(np.ptp(points, axis=0).max())
    tets = np.asarray(tets, dtype=np.int64)
    distance = (points @ normals.T) - np.einsum("kj,kj->k", origin, normals)  # (n, k)
    on = np.abs(distance) <= tol
    d = distance[tets]  # (m, 4, k)
    crossing = (d.min(axis=1) < -tol) & (d.max(axis=1) > tol)  # (m, k)
    blocked = np.zeros(on.shape, dtype=bool)
    for k in range(on.shape[1]):  # a handful of planes
        blocked[tets[crossing[:, k]].ravel(), k] = True
    usable_on = on & ~blocked  # (n, k)
    usable = usable_on.any(axis=1)
    first = np.argmax(usable_on, axis=1)  # the first plane a usable vertex lies on
    plane_of = np.where(usable, first, -1)  # (n,)
    corner = plane_of[tets]  # (m, 4)
    has = corner >= 0
    which = corner[np.arange(len(tets)), np.argmax(has, axis=1)]
    normal = np.where(has.any(axis=1)[:, None], normals[np.maximum(which, 0)], 0.0)
    return PlaneSites(usable, normal, crossing.any(axis=1))


def normal_stress(smoothed: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """``(m,)``: the normal stress ``n . sigma . n`` of the smoothed stress ``(6, m)``
    (Mandel) on each tet's crack plane ``normal (m, 3)`` (zero where the normal is)."""
    sigma = matrices_from_mandel(smoothed)
    return np.einsum("mi,mij,mj->m", normal, sigma, normal)
