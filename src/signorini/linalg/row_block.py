"""A sparse matrix of which each rank holds one block of rows (the distributed backends).

Rank r of P holds rows [bounds[r], bounds[r + 1]) of an (n, m) matrix A, with all m
columns, as a scipy CSR block ``local`` of shape (bounds[r + 1] - bounds[r], m).  The
state vectors of a run stay replicated (docs/parallel.md), so

    A @ x    (x of shape (m,), the same on every rank)

is each rank's ``local @ x`` followed by one ``Allgatherv``: every rank gets the whole
product (n,) and no halo exchange is needed.  The work and the memory per rank are
nnz(A) / P.  The step operator K of ``petsc`` and ``petsc-cg`` is formed this way from
the start (:func:`~signorini.linalg.sparse.principal_rows`): no rank ever holds all of K.

The row blocks of the contact solve end at node boundaries (:func:`node_row_bounds`),
so the rows of one contact node, and the projection onto its normal, stay on one rank.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp


def row_bounds(n: int, size: int) -> np.ndarray:
    """Even blocks of rows (size + 1,): rank r gets rows [bounds[r], bounds[r + 1])."""
    return np.linspace(0, n, size + 1).round().astype(np.int64)


def node_row_bounds(nodes: np.ndarray, size: int) -> np.ndarray:
    """Row blocks (size + 1,) of about n / size rows that end at node boundaries.

    ``nodes`` (n,) is the mesh node of each row, a node's rows consecutive (node-major
    dofs): the even split of :func:`row_bounds` moved up to the first row of the next
    node, so that a contact node's rows (and its projection) stay on one rank.
    """
    nodes = np.asarray(nodes)
    n = nodes.size
    starts = np.flatnonzero(np.r_[True, nodes[1:] != nodes[:-1]])  # first row of each node
    if np.unique(nodes).size != starts.size:
        raise ValueError("the rows of a node are not consecutive (node-major dofs are expected)")
    even = row_bounds(n, size)
    snapped = np.r_[starts, n][np.searchsorted(np.r_[starts, n], even)]
    return np.maximum.accumulate(snapped).astype(np.int64)


def row_view(A: sp.csr_matrix, lo: int, hi: int) -> sp.csr_matrix:
    """Rows [lo, hi) of the canonical CSR matrix A without copying its values or indices
    (views of A's arrays; only the (hi - lo + 1) row pointers are new)."""
    s, e = int(A.indptr[lo]), int(A.indptr[hi])
    out = sp.csr_matrix((hi - lo, A.shape[1]), dtype=A.dtype)
    out.indptr = (A.indptr[lo : hi + 1] - s).astype(A.indptr.dtype, copy=False)
    out.indices, out.data = A.indices[s:e], A.data[s:e]
    out.has_canonical_format = A.has_canonical_format
    return out


@dataclass
class RowBlock:
    """Rows [lo, hi) of an (n, m) matrix on this rank (see the module docstring).

    ``local`` (hi - lo, m) CSR; ``bounds`` (P + 1,) every rank's first row and n last;
    ``comm`` the run's :class:`~signorini.parallel.Comm` (``MPIComm`` on P ranks).
    """

    local: sp.csr_matrix
    bounds: np.ndarray
    comm: Any

    @classmethod
    def of(cls, A: sp.spmatrix, bounds: np.ndarray, comm: Any, copy: bool = True) -> RowBlock:
        """This rank's rows of A, the same matrix on every rank (``copy=False``: views of
        A's arrays, see :func:`row_view`)."""
        A = A.tocsr() if sp.issparse(A) else sp.csr_matrix(A)
        lo, hi = int(bounds[comm.rank]), int(bounds[comm.rank + 1])
        local = A[lo:hi] if copy else row_view(A, lo, hi)
        return cls(local, np.asarray(bounds, dtype=np.int64), comm)

    @property
    def lo(self) -> int:
        return int(self.bounds[self.comm.rank])

    @property
    def hi(self) -> int:
        return int(self.bounds[self.comm.rank + 1])

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.bounds[-1]), int(self.local.shape[1])

    @property
    def counts(self) -> np.ndarray:
        """Rows per rank (P,)."""
        return np.diff(self.bounds)

    def gather(self, local: np.ndarray) -> np.ndarray:
        """The whole (n,) or (n, k) array from every rank's (hi - lo,) or (hi - lo, k) rows,
        on every rank."""
        local = np.ascontiguousarray(local, dtype=np.float64)
        if self.comm.size == 1:
            return local
        k = 1 if local.ndim == 1 else local.shape[1]
        out = np.empty((self.shape[0],) + local.shape[1:])
        counts = self.counts * k
        self.comm.comm.Allgatherv(local, [out, counts, counts.cumsum() - counts, self.comm.MPI.DOUBLE])
        return out

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        """A @ x, (n,) or (n, k) on every rank, from x (m,) or (m, k) given on every rank."""
        return self.gather(self.local @ x)

    def __getitem__(self, idx: np.ndarray) -> RowBlock:
        """The rows ``idx`` (sorted, unique) of A, still a block of rows per rank (A[D] @ x)."""
        idx = np.asarray(idx, dtype=np.int64)
        if idx.size > 1 and not np.all(np.diff(idx) > 0):
            raise ValueError("the rows of a RowBlock are taken in increasing order, without repeats")
        if idx.size and (idx[0] < 0 or idx[-1] >= self.shape[0]):
            raise IndexError(f"rows {idx[0]}..{idx[-1]} out of 0..{self.shape[0] - 1}")
        cut = np.searchsorted(idx, self.bounds)
        mine = idx[cut[self.comm.rank] : cut[self.comm.rank + 1]]
        return RowBlock(self.local[mine - self.lo], cut.astype(np.int64), self.comm)

    def principal(self, idx: np.ndarray) -> RowBlock:
        """A[idx][:, idx] (``idx`` sorted, unique), a block of rows per rank."""
        sub = self[idx]
        return RowBlock(sub.local[:, idx].tocsr(), sub.bounds, self.comm)

    def _allmax(self, value: float) -> float:
        return float(max(self.comm.gather(float(value))))

    @property
    def nnz(self) -> int:
        """Stored entries over all ranks."""
        return int(sum(self.comm.gather(int(self.local.nnz))))

    def abs_max(self) -> float:
        """max |A_ij| over all ranks (0 without entries)."""
        return self._allmax(np.abs(self.local.data).max(initial=0.0))

    def all_finite(self) -> bool:
        """Whether every entry on every rank is finite (the same answer on every rank)."""
        return self._allmax(0.0 if np.all(np.isfinite(self.local.data)) else 1.0) == 0.0

    def whole(self) -> sp.csr_matrix:
        """All of A on every rank (a fallback of set-up: memory nnz(A) per rank)."""
        return self.rows(np.arange(self.shape[0]))

    def diagonal(self) -> np.ndarray:
        """The diagonal (n,) of a square A, on every rank."""
        lo, hi = self.lo, self.hi
        C = self.local.tocoo()
        d = np.zeros(hi - lo)
        on = C.col == C.row + lo
        np.add.at(d, C.row[on], C.data[on])
        return self.gather(d)

    def rows(self, idx: np.ndarray) -> sp.csr_matrix:
        """The rows ``idx`` (sorted, unique) of A as a CSR matrix (len(idx), m), on every rank
        (each rank contributes those in its block; a set-up operation, pickled once)."""
        idx = np.asarray(idx, dtype=np.int64)
        lo, hi = self.lo, self.hi
        mine = idx[(idx >= lo) & (idx < hi)]
        parts = self.comm.gather(self.local[mine - lo])
        out = sp.vstack(parts, format="csr") if len(parts) > 1 else parts[0].tocsr()
        return out
