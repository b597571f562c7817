"""Sparse matrix-vector products split over threads (the CG path's inner loop).

scipy's CSR product runs on one core and releases the GIL, so rows split into blocks
of equal non-zeros can be multiplied by threads at once.  bar3d n = 24 (450k dofs, 37M
non-zeros) on 2 cores: one product 21.5-22.2 ms -> 11.8-12.0 ms, one CG iteration 20.9
-> 13.3 ms (with the loop's BLAS on one thread, :mod:`.threads`; with a threaded BLAS
beside it the gain was lost, docs/design.md).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

#: below this many non-zeros one product takes under a millisecond: not split
MIN_NNZ = 1_000_000


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS reports it)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - macOS, Windows
        return os.cpu_count() or 1


def rows_view(A: sp.csr_matrix, a: int, b: int) -> sp.csr_matrix:
    """Rows a..b-1 of A sharing A's values and column indices (no copy of the non-zeros)."""
    lo, hi = A.indptr[a], A.indptr[b]
    view = sp.csr_matrix((b - a, A.shape[1]), dtype=A.dtype)
    # set after construction: the constructor copies a small slice of a large array
    view.indptr = (A.indptr[a : b + 1] - lo).astype(A.indices.dtype)
    view.indices, view.data = A.indices[lo:hi], A.data[lo:hi]
    return view


class ThreadedCSR:
    """``A @ x`` for a CSR matrix A (n x m), its rows split over ``threads`` threads.

    Row blocks hold equal numbers of non-zeros.  The products are the same as
    ``A @ x`` to the last bit (each row is summed by the same routine, in the same
    order).  ``threads = 0``: one per usable core; a single block when that is one or
    A has fewer than :data:`MIN_NNZ` non-zeros.
    """

    def __init__(self, A: sp.csr_matrix, threads: int = 0):
        self.A = A
        self.shape = A.shape
        parts = threads or usable_cores()
        parts = max(1, min(parts, A.shape[0])) if A.nnz >= MIN_NNZ else 1
        cuts = np.searchsorted(A.indptr, A.nnz * np.arange(1, parts) / parts)
        edges = [0, *(int(c) for c in cuts), A.shape[0]]
        self.blocks = [(a, b, rows_view(A, a, b)) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]
        self._pool = ThreadPoolExecutor(len(self.blocks) - 1) if len(self.blocks) > 1 else None

    @property
    def threads(self) -> int:
        return len(self.blocks)

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        if self._pool is None:
            return self.A @ x
        y = np.empty(self.shape[0])

        def block(k: int) -> None:
            a, b, Ak = self.blocks[k]
            y[a:b] = Ak @ x

        futures = [self._pool.submit(block, k) for k in range(1, len(self.blocks))]
        block(0)
        for f in futures:
            f.result()
        return y

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False)
            self._pool = None

    def __del__(self):  # pragma: no cover - at garbage collection
        self.close()
