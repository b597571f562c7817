"""``A @ x`` shared between the ranks: each rank multiplies its block of rows, one gather.

The state vectors are replicated (docs/parallel.md), so the products of a step's
right-hand side and of the energies (M V, S U) need no halo exchange: rank r computes
rows [lo_r, hi_r) of A x with scipy from the whole x it already has, and one
``Allgatherv`` gives every rank the whole product.  The work per rank is nnz(A)/P.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .factor import row_bounds


class RowBlockProduct:
    """``A @ x`` (x of shape (n,)) computed by blocks of rows over the ranks of ``comm``
    (a :class:`~signorini.parallel.MPIComm`)."""

    def __init__(self, A: sp.spmatrix, comm):
        self.comm = comm.comm
        self.MPI = comm.MPI
        n = A.shape[0]
        bounds = row_bounds(n, comm.size)
        self.lo, self.hi = int(bounds[comm.rank]), int(bounds[comm.rank + 1])
        self.block = sp.csr_matrix(A)[self.lo : self.hi]
        counts = np.diff(bounds)
        self.recv = (counts, counts.cumsum() - counts)
        self.shape = A.shape

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        local = np.ascontiguousarray(self.block @ x)
        out = np.empty(self.shape[0])
        self.comm.Allgatherv(local, [out, self.recv[0], self.recv[1], self.MPI.DOUBLE])
        return out
