"""SuperLU (scipy) factor of an SPD matrix, in symmetric mode."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .base import Factor


class SuperLUFactor(Factor):
    """SuperLU with the symmetric ordering MMD on A^T + A and no off-diagonal pivoting:
    an LU that behaves like a Cholesky factor on SPD matrices.  Always available."""

    name = "superlu"

    def __init__(self, K: sp.spmatrix):
        super().__init__()
        self._lu = spla.splu(
            sp.csc_matrix(K),
            permc_spec="MMD_AT_PLUS_A",
            diag_pivot_thresh=0.0,
            options={"SymmetricMode": True},
        )

    @property
    def nbytes(self) -> int:
        return int(12 * (self._lu.L.nnz + self._lu.U.nnz))

    def _solve(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(np.asarray(b, dtype=float))
