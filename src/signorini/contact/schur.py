"""The Delassus matrix from the Schur complement of K on the contact dofs.

With C the dofs that B (nc x n) touches (one per node on a plane obstacle, up to d
per node on a curved one), I the others, and a factorization of K that eliminates I
first and returns the dense Schur complement S = K_CC - K_CI K_II^-1 K_IC
(:class:`~signorini.linalg.pardiso.PardisoFactor` with ``schur_dofs``):

    (K^-1)_CC = S^-1,   W = B K^-1 B^T = B_C S^-1 B_C^T,

so the set-up is that one factorization plus a dense Cholesky of S, and a contact solve

    y = forward(b)                      y_C = b_C - K_CI K_II^-1 b_I
    x_C,free = S^-1 y_C,                q = bound - B_C x_C,free      (LCP on W, q)
    x_C = x_C,free + S^-1 B_C^T lambda, x = backward(y with y_C := x_C)

costs one forward and one backward substitution (one solve) and dense products of
size |C|: no column of Z = K^-1 B^T is ever computed.  Memory O(n + |C| nc).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp


def schur_dofs(B: sp.spmatrix) -> np.ndarray:
    """The dofs (sorted) where the contact matrix B has non-zero entries."""
    B = sp.csr_matrix(B, copy=True)
    B.eliminate_zeros()
    return np.unique(B.indices)


class SchurDelassus:
    """W = B_C S^-1 B_C^T for every contact node at once, and the split solve.

    Same interface as :class:`~signorini.contact.delassus.DelassusColumns` (``ensure``,
    ``W``, ``block``, ``free``, ``complete``, ``count``, ``seconds``).

    Parameters
    ----------
    factor : a factor of K computed with ``schur_dofs = schur_dofs(B)``.
    B : (nc, n) sparse contact matrix.
    """

    keeps_Z = False

    def __init__(self, factor, B: sp.csr_matrix):
        t0 = time.perf_counter()
        self.factor = factor
        self.B = sp.csr_matrix(B)
        self.dofs = np.asarray(factor.schur_dofs)
        nc = self.B.shape[0]
        self.Bc = self.B[:, self.dofs].tocsr()  # (nc, |C|)
        self._chol = sla.cho_factor(factor.schur, lower=True, overwrite_a=True, check_finite=False)
        factor.schur = None  # overwritten by its Cholesky factor
        self._G = sla.cho_solve(self._chol, self.Bc.T.toarray(), check_finite=False)  # S^-1 B_C^T (|C|, nc)
        W = np.asarray(self.Bc @ self._G)
        W += W.T  # symmetrized in place (round-off)
        W *= 0.5
        self._W = W
        self.count = self.solved = nc
        self.slot = np.arange(nc)
        self.seconds = time.perf_counter() - t0

    @property
    def nbytes(self) -> int:
        return self._W.nbytes + self._G.nbytes + self._chol[0].nbytes

    def ensure(self, nodes: np.ndarray, fill: np.ndarray | None = None) -> None:
        """Nothing to do: every column of W is known from the set-up."""

    def W(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """W[rows][:, cols], shape (len(rows), len(cols))."""
        return self._W[np.asarray(rows)[:, None], np.asarray(cols)[None, :]]

    def block(self, nodes: np.ndarray) -> np.ndarray:
        """The symmetric block W[nodes][:, nodes]."""
        return self.W(nodes, nodes)

    def free(self, b: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
        """(state, B x_free) for x_free = K^-1 b, from the forward substitution only."""
        y = self.factor.forward(b)
        xc = sla.cho_solve(self._chol, y[self.dofs], check_finite=False)
        return (y, xc), self.Bc @ xc

    def complete(self, state: tuple[np.ndarray, np.ndarray], lam: np.ndarray) -> np.ndarray:
        """x = K^-1 (b + B^T lambda) from :meth:`free`'s state (the backward substitution)."""
        y, xc = state
        A = np.flatnonzero(lam)
        if A.size:
            xc = xc + self._G[:, A] @ lam[A]
        y[self.dofs] = xc
        return self.factor.backward(y)
