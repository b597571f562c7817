"""Factor-once linear solvers for the SPD matrix K_eff = a M + S.

``factorize(K, backend)`` returns an object with ``solve(b)`` for a vector or a
matrix of right-hand sides.  Backends:

``superlu``  scipy's SuperLU with a symmetric ordering (MMD on A^T + A) and no pivoting
             across the diagonal, i.e. an LU that behaves like a Cholesky factor on SPD
             matrices.  Always available (pip-only default).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .errors import InputError

BACKENDS = ("superlu",)


class SuperLUFactor:
    """SuperLU factor of an SPD matrix (symmetric mode)."""

    name = "superlu"

    def __init__(self, K: sp.spmatrix):
        self.n = K.shape[0]
        self._lu = spla.splu(
            sp.csc_matrix(K),
            permc_spec="MMD_AT_PLUS_A",
            diag_pivot_thresh=0.0,
            options={"SymmetricMode": True},
        )

    @property
    def nnz(self) -> int:
        return int(self._lu.L.nnz + self._lu.U.nnz)

    @property
    def nbytes(self) -> int:
        """Approximate memory of the factor (values + row indices) [bytes]."""
        return 12 * self.nnz

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(np.asarray(b, dtype=float))


def factorize(K: sp.spmatrix, backend: str = "superlu"):
    """Factorize the SPD matrix ``K`` once; see the module docstring for backends."""
    if backend not in BACKENDS:
        raise InputError(f"unknown linear solver backend {backend!r}; allowed: {', '.join(BACKENDS)}")
    return SuperLUFactor(K)
