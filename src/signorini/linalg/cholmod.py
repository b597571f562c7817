"""Supernodal sparse Cholesky (CHOLMOD inside ``cvxopt``: a core dependency where cvxopt has
wheels, pyproject.toml; elsewhere the extra ``cholmod``).

K = P^T L L^T P with P the nested-dissection order of :func:`~.ordering.fill_reducing_order`
(METIS when pymetis is installed): cvxopt's CHOLMOD is built without METIS and its own
AMD ordering fills 3D factors like SuperLU's MMD (``docs/performance.md``).

A run factorizes many matrices of one pattern (each Newton tangent).  A factor released
(:meth:`CholmodFactor.release`: no longer of use) leaves its analysis, CHOLMOD's symbolic
factorization with the matrix that holds the pattern, to the next factorization of the same
pattern (:data:`KEPT`), which then costs its numeric factorization alone: cvxopt cannot copy a
factor, so an analysis is shared only once its factor is done with.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..optional import optional_import
from . import ordering as _ordering
from .base import Factor, KeptAnalyses

#: from this many right-hand sides a solve goes through ``cholmod.spsolve`` (blocked)
BLOCKED = 2

#: the analyses of released factors, by pattern: (cvxopt matrix, factor, lower-triangle positions, resident bytes)
KEPT = KeptAnalyses()


def _resident_bytes() -> int:
    """Current resident memory of the process [bytes] (Linux; 0 elsewhere)."""
    try:
        import resource

        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * resource.getpagesize()
    except (OSError, ImportError, ValueError, IndexError):
        return 0


class CholmodFactor(Factor):
    """CHOLMOD supernodal L L^T of the lower triangle of K in a nested-dissection order."""

    name = "cholmod"

    def __init__(self, K: sp.spmatrix):
        super().__init__()
        optional_import("cvxopt.cholmod", "backend 'cholmod'", "cholmod")
        self._cvxopt = cvxopt = optional_import("cvxopt", "backend 'cholmod'", "cholmod")
        K = sp.csc_matrix(K)
        if not K.has_canonical_format:  # sorted, without duplicates (which cvxopt would sum: another pattern)
            K = K.copy()
            K.sum_duplicates()
        self._digest = _ordering.pattern_digest(K)
        perm, self.ordering = _ordering.fill_reducing_order(K, digest=self._digest)
        before = _resident_bytes()
        kept = KEPT.take(self._digest)
        held = 0
        if kept is not None:  # the same pattern analysed for a factor since released: the new values only
            A, F, lower, held = kept
            A.V = cvxopt.matrix(K.data[lower])
        else:
            cols = np.repeat(np.arange(K.shape[1]), np.diff(K.indptr))
            lower = np.flatnonzero(K.indices >= cols)  # the lower triangle, in CSC (cvxopt's) order
            A = cvxopt.spmatrix(K.data[lower], K.indices[lower].astype(int), cols[lower].astype(int), K.shape)
            F = cvxopt.cholmod.symbolic(A, p=cvxopt.matrix(perm.astype(int)), uplo="L")
        cvxopt.cholmod.numeric(A, F)  # a failure (not positive definite) drops the analysis with the factor
        self._A, self._F, self._lower = A, F, lower
        self._held = max(_resident_bytes() - before, held)  # a kept analysis: the memory its factor took

    def release(self) -> None:
        """No longer of use: its analysis goes to the next factorization of its pattern (:data:`KEPT`); this
        factor solves no more."""
        if self._F is not None:
            KEPT.keep(self._digest, (self._A, self._F, self._lower, self._held), self._held)
            self._A = self._F = None

    @property
    def nbytes(self) -> int:
        """Resident memory the factorization added (cvxopt does not report the factor's
        size; Linux only, else 0) [bytes]."""
        return int(self._held)

    def _solve(self, b: np.ndarray) -> np.ndarray:
        if self._F is None:
            raise RuntimeError("a released CHOLMOD factor was asked to solve (its analysis serves another now)")
        b = np.asarray(b, dtype=float)
        if b.ndim == 2 and b.shape[1] >= BLOCKED:
            return self._solve_block(b)
        B = self._cvxopt.matrix(b.reshape(b.shape[0], -1))
        self._cvxopt.cholmod.solve(self._F, B)
        return np.array(B).reshape(b.shape)

    def _solve_block(self, b: np.ndarray) -> np.ndarray:
        """K^-1 b for a block of columns through ``cholmod.spsolve``: cvxopt's ``solve``
        calls CHOLMOD once per column, reading the whole factor each time, where
        ``cholmod_spsolve`` takes the columns several at a time (the Delassus columns, a
        few nonzeros each, come 64 at a time: docs/performance.md)."""
        cvxopt = self._cvxopt
        c = sp.csc_matrix(b)
        c.sort_indices()
        rows = c.indices.astype(int)
        cols = np.repeat(np.arange(c.shape[1]), np.diff(c.indptr)).astype(int)
        B = cvxopt.spmatrix(c.data, rows, cols, c.shape)
        X = cvxopt.cholmod.spsolve(self._F, B)
        ptr, idx, val = (np.array(a).ravel() for a in X.CCS)
        out = np.zeros(b.shape, order="F")
        out[idx, np.repeat(np.arange(b.shape[1]), np.diff(ptr))] = val
        return out
