"""The Delassus columns of a distributed factor (backend ``petsc``, docs/parallel.md)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .delassus import DelassusColumns


class DistributedColumns(DelassusColumns):
    """:class:`~signorini.contact.delassus.DelassusColumns` on a :class:`PetscFactor`: each rank
    keeps its own rows of the Z columns (memory n m / P per rank), W = B Z is summed over
    the ranks and replicated, and a contact step is one distributed solve, the local
    product Z_loc lambda and one gather of x (instead of a gathered solve and a product
    of the whole Z on every rank)."""

    def __init__(self, factor, B: sp.csr_matrix, budget: float):
        self.Bloc = sp.csr_matrix(B)[:, factor.lo : factor.hi]
        super().__init__(factor, B, budget)  # condense_budget is per rank: the Z rows it stores

    #: the re-paired rows' columns are solved again (a cache of dof columns is not distributed)
    updates_columns = False

    def _rows(self) -> int:
        return self.factor.hi - self.factor.lo

    def replace_rows(self, rows: np.ndarray, B: sp.csr_matrix) -> None:
        """As the serial columns (every rank with the same B and rows: the solves are collective)."""
        self.undo.before_change()  # (a rollback puts this rank's block of B back too)
        self.Bloc = sp.csr_matrix(B)[:, self.factor.lo : self.factor.hi]
        super().replace_rows(rows, B)

    def _row_products(self, rows: np.ndarray, slots: np.ndarray) -> np.ndarray:
        """B[rows] Z[:, slots], each rank from its own rows of Z, summed over the ranks."""
        return self.factor.allreduce(np.asarray(self.Bloc[rows] @ self._Zt[slots].T))

    def _budget_rows(self) -> int:
        # the largest block of rows: every rank takes the same keep-or-drop decision (one
        # rank dropping Z while another keeps it would send them into different collectives)
        return int(np.max(np.diff(self.factor.bounds)))

    def _solve_block(self, J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        f = self.factor
        Zj = f.solve_owned(self.Bt[f.lo : f.hi][:, J].toarray())
        return Zj, f.allreduce(self.Bloc @ Zj)

    def free(self, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        f = self.factor
        x = f.solve_owned(np.asarray(b, dtype=float)[f.lo : f.hi])
        return x, f.allreduce(self.Bloc @ x)

    def complete(self, x_free: np.ndarray, lam: np.ndarray) -> np.ndarray:
        f = self.factor
        A = np.flatnonzero(lam)
        if A.size and self.keeps_Z:
            x_free = x_free + self.Z_times(A, lam[A])
        elif A.size:
            x_free = x_free + f.solve_owned(np.asarray(self.Bt[f.lo : f.hi] @ lam))
        return f.gather(x_free)
