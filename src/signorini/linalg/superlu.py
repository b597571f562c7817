"""SuperLU (scipy) factor of an SPD matrix, in symmetric mode."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from . import ordering as _ordering
from .base import Factor

ND_MIN_DOFS = 15_000  # below this (bar3d n <= 6), or on 2D-like patterns, MMD fills less than nested dissection
ND_MIN_ROW_NNZ = 30.0  # mean entries per row: 3D elements (Q1 81, P1 ~45) vs 2D (Q1 18, P1 ~14)


def use_nested_dissection(K: sp.spmatrix) -> bool:
    """Whether SuperLU should factor K in a nested-dissection order rather than MMD's:
    large systems with a 3D element pattern (measured in ``docs/performance.md``)."""
    n = K.shape[0]
    return n >= ND_MIN_DOFS and K.nnz >= ND_MIN_ROW_NNZ * n


class SuperLUFactor(Factor):
    """SuperLU with no off-diagonal pivoting (symmetric mode): an LU that behaves like a
    Cholesky factor on SPD matrices.  Always available.

    Ordering: on large 3D systems, nested dissection (METIS when pymetis is installed,
    else :func:`~.ordering.nested_dissection`) applied as a symmetric permutation of K with
    SuperLU's ``NATURAL`` column order; otherwise SuperLU's minimum degree on A^T + A.
    """

    name = "superlu"

    def __init__(self, K: sp.spmatrix):
        super().__init__()
        K = sp.csc_matrix(K)
        self.perm: np.ndarray | None = None
        permc = "MMD_AT_PLUS_A"
        self.ordering = "mmd"
        if use_nested_dissection(K):
            self.perm, self.ordering = _ordering.fill_reducing_order(K)
            K = sp.csc_matrix(K[self.perm][:, self.perm])
            permc = "NATURAL"
        self._lu = spla.splu(K, permc_spec=permc, diag_pivot_thresh=0.0, options={"SymmetricMode": True})

    @property
    def nbytes(self) -> int:
        """Stored entries of L and U (values + indices) [bytes]; read from SuperLU's count,
        since ``L``/``U`` would copy the factor into new CSC matrices."""
        return int(12 * self._lu.nnz)

    def _solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=float)
        if self.perm is None:
            return self._lu.solve(b)
        x = np.empty_like(b)
        x[self.perm] = self._lu.solve(b[self.perm])
        return x
