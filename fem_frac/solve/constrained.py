"""The free/constrained split of the dofs, and factorizations on the free dofs."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .linalg import Refactorizer, factorize


class Constrained:
    """Free/constrained split of the dofs of ``problem`` and factorizations of matrices
    restricted to the free dofs (with the linear solver ``method``)."""

    def __init__(self, problem, method: str):
        n = problem.space.n_dofs
        self.dofs = problem.constraints.dofs
        mask = np.ones(n, dtype=bool)
        mask[self.dofs] = False
        self.free = np.flatnonzero(mask)
        self.method = method

    def factorize(self, matrix: sp.csr_matrix, refactorizer: Refactorizer | None = None):
        """Factorization of ``matrix`` on the free dofs (through ``refactorizer`` when given,
        which reuses the symbolic analysis of its previous matrix)."""
        sub = matrix[self.free][:, self.free].tocsr()
        if refactorizer is not None:
            return refactorizer.factorize(sub)
        return factorize(sub, self.method)
