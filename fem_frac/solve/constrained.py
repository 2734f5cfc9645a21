"""The free/constrained split of the dofs, and factorizations on the free dofs."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .linalg import factorize
from .refactorizer import Refactorizer


class Constrained:
    """Free/constrained split of the dofs of ``problem`` and factorizations of matrices
    restricted to the free dofs (with the linear solver ``method``)."""

    def __init__(self, problem, method: str, petsc=None):
        n = problem.space.n_dofs
        self.dofs = problem.constraints.dofs
        mask = np.ones(n, dtype=bool)
        mask[self.dofs] = False
        self.free = np.flatnonzero(mask)
        self.method = method
        self.points = problem.space.node_points  # for PETSc's rigid-body modes
        self.petsc = petsc  # the analysis.petsc section (None: its defaults)

    def factorize(self, matrix: sp.csr_matrix, refactorizer: Refactorizer | None = None):
        """Factorization of ``matrix`` on the free dofs (through ``refactorizer`` when given,
        which reuses the symbolic analysis of its previous matrix); PETSc's solver when
        ``method`` is ``petsc`` or ``auto`` picks it (fem_frac/solve/petsc.py)."""
        from .petsc import chosen

        if chosen(self.method, len(self.free)):
            from .petsc import PetscFactorization, Settings
            from .ranks import active

            return PetscFactorization(matrix, self.free, self.points,
                                      Settings.of(self.petsc), active())
        if refactorizer is not None:
            return refactorizer.factorize_free(matrix, self.free)
        return factorize(matrix[self.free][:, self.free].tocsr(), self.method)
