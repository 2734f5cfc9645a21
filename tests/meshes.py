"""Small meshes built without gmsh, for unit tests."""

from __future__ import annotations

import numpy as np

from fem_frac.mesh import Mesh, tet_volumes


def structured_box(n=(4, 3, 3), lengths=(1.0, 1.0, 1.0), distortion=0.0, seed=0) -> Mesh:
    """A box split into tets; interior vertices moved randomly by ``distortion`` of a cell."""
    from skfem import MeshTet

    axes = [np.linspace(0.0, length, k + 1) for k, length in zip(n, lengths, strict=True)]
    m = MeshTet.init_tensor(*axes)
    points = m.p.T.copy()
    tets = m.t.T.copy()
    if distortion:
        rng = np.random.default_rng(seed)
        h = np.array(lengths) / np.array(n)
        interior = np.all((points > 1e-12) & (points < np.array(lengths) - 1e-12), axis=1)
        points[interior] += distortion * h * rng.uniform(-1, 1, (interior.sum(), 3))
    v = tet_volumes(points, tets)
    tets[v < 0] = tets[v < 0][:, [0, 2, 1, 3]]
    return Mesh(points, tets)
