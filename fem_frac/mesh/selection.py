"""Selecting boundary faces by name or by a box."""

from __future__ import annotations

import difflib

import numpy as np

from .mesh import Mesh, exterior_facets

# The group every mesh has: all exterior faces.
ALL_BOUNDARY = "boundary"
# A box thinner than this share of the mesh's extent along one axis is a plane.
FLAT = 1e-4


def boundary_names(mesh: Mesh) -> list[str]:
    """Named boundary groups of ``mesh``, plus ``boundary`` (every exterior face)."""
    return sorted(mesh.boundaries) + [ALL_BOUNDARY]


def named_facets(mesh: Mesh, name: str, exterior: np.ndarray | None = None) -> np.ndarray:
    """Vertex triples ``(k, 3)`` of the group ``name``. Raises LookupError when absent."""
    if name == ALL_BOUNDARY and name not in mesh.boundaries:
        return exterior_facets(mesh.tets) if exterior is None else exterior
    if name not in mesh.boundaries:
        names = boundary_names(mesh)
        close = difflib.get_close_matches(name, names, n=1)
        hint = f"did you mean '{close[0]}'? " if close else ""
        available = ", ".join(names)
        raise LookupError(f"the mesh has no boundary '{name}' ({hint}available: {available})")
    return mesh.boundaries[name]


def box_facets(mesh: Mesh, lo, hi, exterior: np.ndarray | None = None) -> np.ndarray:
    """Exterior faces ``(k, 3)`` whose centroid (the mean of its three corners) lies in the
    closed box ``[lo, hi]``.

    A face straddling a side of the box is in or out by its centroid, so the faces chosen
    cover about the box's share of a surface (all-corners-inside would leave out every face
    cut by the box's outline: a patch of a few elements would get half its area). The box is
    widened by 1e-9 of the mesh's extent so faces lying exactly on its sides count (a box of
    zero thickness selects the faces in its plane).
    """
    faces = exterior_facets(mesh.tets) if exterior is None else exterior
    return faces[in_box(mesh, mesh.points[faces].mean(axis=1), lo, hi)]


def in_box(mesh: Mesh, x: np.ndarray, lo, hi) -> np.ndarray:
    """Which points ``x (k, 3)`` lie in the closed box ``[lo, hi]`` widened by 1e-9 of the
    extent of ``mesh``."""
    tol = 1e-9 * np.ptp(mesh.points, axis=0).max()
    return np.all((x >= np.asarray(lo) - tol) & (x <= np.asarray(hi) + tol), axis=1)


def box_face_area(mesh: Mesh, lo, hi) -> float | None:
    """The area of the box's own face where the box is flat (``min`` and ``max`` equal, to
    1e-4 of the mesh's extent, along exactly one axis), clipped to the mesh's bounding box:
    what a selection of the faces in that plane is meant to cover. None for a box with
    thickness (it has no one face to compare a selection with)."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    extent = np.ptp(mesh.points, axis=0).max()
    flat = np.flatnonzero(hi - lo <= FLAT * extent)
    if len(flat) != 1:
        return None
    others = [k for k in range(3) if k != flat[0]]
    low = np.maximum(lo[others], mesh.points[:, others].min(axis=0))
    high = np.minimum(hi[others], mesh.points[:, others].max(axis=0))
    return float(np.prod(np.clip(high - low, 0.0, None)))
