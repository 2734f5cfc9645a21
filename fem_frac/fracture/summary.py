"""Measures of the cracks of a mesh: opened faces and their area."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh.mesh import Mesh
from .topology import CRACK


@dataclass(frozen=True)
class CrackMeasures:
    """``faces``: interior faces opened so far (each is two triangles of the ``crack``
    group, one per side); ``area``: their area in the reference configuration (one side)."""

    faces: int
    area: float


def crack_measures(mesh: Mesh) -> CrackMeasures:
    tri = np.asarray(mesh.boundaries.get(CRACK, np.zeros((0, 3), dtype=np.int64)))
    if tri.size == 0:
        return CrackMeasures(0, 0.0)
    x = mesh.points[tri]
    areas = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
    return CrackMeasures(len(tri) // 2, float(areas.sum() / 2.0))
