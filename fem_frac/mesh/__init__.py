"""Meshes: the shared :class:`Mesh` type, gmsh geometry, mesh files."""

from .mesh import Mesh, exterior_facets, min_dihedral_angles, tet_volumes

__all__ = ["Mesh", "exterior_facets", "min_dihedral_angles", "tet_volumes"]
