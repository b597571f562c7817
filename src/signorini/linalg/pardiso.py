"""MKL Pardiso through ``pypardiso`` (optional extra ``pardiso``), imported lazily."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..optional import optional_import
from .base import Factor


class PardisoFactor(Factor):
    """Real SPD mode on the upper triangle, nested-dissection ordering, factorized once."""

    name = "pardiso"

    def __init__(self, K: sp.spmatrix):
        super().__init__()
        pypardiso = optional_import("pypardiso", "backend 'pardiso'", "pardiso")
        self._A = sp.triu(K, format="csr")
        self._A.sort_indices()
        self._solver = pypardiso.PyPardisoSolver(mtype=2)
        self._solver.set_statistical_info_off()
        self._solver.set_iparm(18, -1)  # (1-based) ask Pardiso to report the factor's non-zeros
        self._solver.factorize(self._A)

    @property
    def nbytes(self) -> int:
        """Factor size from Pardiso's report (non-zeros of L, values + indices) [bytes]."""
        return int(12 * max(self._solver.get_iparm(18), 0))

    def _solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asfortranarray(np.asarray(b, dtype=float))
        self._solver.set_phase(33)  # solve only: the factor is reused, no re-hashing of A
        return self._solver._call_pardiso(self._A, b)
