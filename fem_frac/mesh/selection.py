"""Selecting boundary faces by name or by a box."""

from __future__ import annotations

import difflib

import numpy as np

from .mesh import Mesh, exterior_facets

# The group every mesh has: all exterior faces.
ALL_BOUNDARY = "boundary"


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
    """Exterior faces ``(k, 3)`` whose three vertices lie in the closed box ``[lo, hi]``.

    The box is widened by 1e-9 of the mesh's extent so faces lying exactly on its sides count.
    """
    faces = exterior_facets(mesh.tets) if exterior is None else exterior
    extent = np.ptp(mesh.points, axis=0).max()
    tol = 1e-9 * extent
    x = mesh.points[faces]  # (k, 3 vertices, 3)
    inside = np.all((x >= np.asarray(lo) - tol) & (x <= np.asarray(hi) + tol), axis=(1, 2))
    return faces[inside]
