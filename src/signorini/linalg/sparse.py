"""Set-up operations on large CSR matrices, without the temporaries scipy's generic ones make.

On bar3d n = 32 (1.05M dofs, 81M non-zeros in S) scipy's ``a * M + b * S`` copies
both matrices, index arrays included, before adding them; ``K[f][:, f]`` copies the
rows, then the columns; ``sp.triu`` goes through COO and sorts.  The functions here
work on the CSR arrays with boolean masks and share index arrays where they can
(docs/performance.md, "Set-up of the CG path").  All take and return canonical CSR
(sorted indices, no duplicates) and give the same matrices as the scipy expressions.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..fem.dofmap import component_of, whole_blocks


def _canonical(A: sp.spmatrix) -> sp.csr_matrix:
    # tocsr() keeps a CSR object (and its cached format flags: a new object would scan
    # its 81M entries again at bar3d n = 32)
    A = A.tocsr() if sp.issparse(A) else sp.csr_matrix(A)
    if not A.has_canonical_format:
        A = A.copy()
        A.sum_duplicates()
    return A


def linear_combination(a: float, A: sp.spmatrix, b: float, B: sp.spmatrix, overwrite: bool = False) -> sp.csr_matrix:
    """``a A + b B`` (CSR).  The scaled operands share A's and B's index arrays (scipy's
    ``a * A`` copies them); when A and B have the same pattern the result shares it too.

    ``overwrite``: A and B are temporaries; when one pattern holds the other, the larger
    one's values become the result's (no new array of its size).
    """
    A, B = _canonical(A), _canonical(B)
    if A.shape != B.shape:
        raise ValueError(f"shapes differ: {A.shape} and {B.shape}")
    data_type = np.result_type(A.dtype, B.dtype, np.float64, np.asarray(a).dtype, np.asarray(b).dtype)
    if a == 0 or b == 0:  # one operand (a mass-only operator): its own pattern, no zeros of the other's
        keep, c = (B, b) if a == 0 else (A, a)
        return _share_pattern(keep, c * keep.data.astype(data_type, copy=False))
    if A.indices is B.indices or (
        A.nnz == B.nnz and np.array_equal(A.indptr, B.indptr) and np.array_equal(A.indices, B.indices)
    ):
        return sp.csr_matrix(
            (a * A.data.astype(data_type, copy=False) + b * B.data, B.indices, B.indptr), shape=B.shape
        )
    # a pattern inside the other (a vector mass in the stiffness pattern): add into a copy
    # of the larger one's values, which keeps its index arrays (scipy's sum merges rows)
    (big, cb), (small, cs) = ((B, b), (A, a)) if B.nnz >= A.nnz else ((A, a), (B, b))
    pos = subpattern_positions(small, big)
    if pos is not None:
        if overwrite and big.data.dtype == data_type:
            data = big.data
            data *= cb
        else:
            data = cb * big.data.astype(data_type, copy=False)
        for k in range(0, pos.size, 1 << 22):  # in blocks of entries: small temporaries
            part = slice(k, k + (1 << 22))
            data[pos[part]] += cs * small.data[part]
        return _share_pattern(big, data)
    As = sp.csr_matrix((a * A.data.astype(data_type, copy=False), A.indices, A.indptr), shape=A.shape)
    Bs = sp.csr_matrix((b * B.data.astype(data_type, copy=False), B.indices, B.indptr), shape=B.shape)
    return (As + Bs).tocsr()


def _share_pattern(A: sp.csr_matrix, data: np.ndarray) -> sp.csr_matrix:
    """A CSR matrix with A's index arrays (shared, not copied) and the values ``data``."""
    out = sp.csr_matrix(A.shape, dtype=data.dtype)
    out.indptr, out.indices, out.data = A.indptr, A.indices, data  # no check of the large arrays
    out.has_canonical_format = True  # A is canonical
    return out


def subpattern_positions(A: sp.csr_matrix, B: sp.csr_matrix, chunk: int = 1 << 22) -> np.ndarray | None:
    """Where A's entries sit in B's arrays: ``pos`` (A.nnz,) with B.indices[pos] ==
    A.indices row by row, or None when some entry of A is not in B's pattern.

    Both canonical, same shape.  A binary search per entry of A in the sorted keys
    row * n_cols + col of B, built for about ``chunk`` entries of B at a time (bounded
    memory: the keys of B whole would take 8 bytes per non-zero).
    """
    if A.shape != B.shape:
        return None
    pos = _block_diagonal_positions(A, B)
    if pos is not None:
        return pos
    n, ncol = A.shape
    pos = np.empty(A.nnz, dtype=np.int64)
    cuts = np.searchsorted(B.indptr, np.arange(0, B.nnz, chunk), side="right") - 1
    cuts = np.unique(np.concatenate([[0], cuts, [n]]))
    for r0, r1 in zip(cuts[:-1], cuts[1:], strict=False):  # a few rows blocks, not entries
        a0, a1, b0, b1 = A.indptr[r0], A.indptr[r1], B.indptr[r0], B.indptr[r1]
        if a1 == a0:
            continue
        if b1 == b0:
            return None
        local = np.arange(r1 - r0, dtype=np.int64)
        kb = np.repeat(local, np.diff(B.indptr[r0 : r1 + 1])) * ncol + B.indices[b0:b1]
        ka = np.repeat(local, np.diff(A.indptr[r0 : r1 + 1])) * ncol + A.indices[a0:a1]
        p = np.searchsorted(kb, ka)
        np.minimum(p, kb.size - 1, out=p)
        if not np.array_equal(kb[p], ka):
            return None
        pos[a0:a1] = p + b0
    return pos


def _block_diagonal_positions(A: sp.csr_matrix, B: sp.csr_matrix) -> np.ndarray | None:
    """The positions of A in B when A holds the diagonal of B's d x d blocks (a vector
    mass m (x) I_d in the stiffness pattern of the same mesh, d = B.nnz / A.nnz): entry
    k of row r is B's entry d k + (r mod d) of that row.  Checked entry by entry; None
    when the guess fails (then :func:`subpattern_positions` searches)."""
    if A.nnz == 0 or B.nnz % A.nnz:
        return None
    d = B.nnz // A.nnz
    n = A.shape[0]
    if d < 2 or not whole_blocks(n, d) or not np.array_equal(B.indptr, d * A.indptr.astype(np.int64)):
        return None
    itype = np.int32 if B.nnz < 2**31 else np.int64  # 4 bytes an entry where they suffice
    pos = np.repeat(component_of(np.arange(n), d).astype(itype), np.diff(A.indptr))
    pos += np.arange(0, B.nnz, d, dtype=itype)
    return pos if np.array_equal(B.indices[pos], A.indices) else None


def principal_combination(
    a: float, A: sp.spmatrix, b: float, B: sp.spmatrix, free: np.ndarray, fixed: np.ndarray
) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """:func:`principal_blocks` of ``a A + b B`` without forming the whole combination:
    the blocks of A and B are combined, the larger free block (a fresh copy) taking the
    result in place.  On bar3d n = 32 this skips an 81M-value array (0.65 GB)."""
    Aff, AfD = principal_blocks(A, free, fixed)
    Bff, BfD = principal_blocks(B, free, fixed)
    return linear_combination(a, Aff, b, Bff, overwrite=True), linear_combination(a, AfD, b, BfD)


def principal_rows(
    a: float, A: sp.spmatrix, b: float, B: sp.spmatrix, free: np.ndarray, fixed: np.ndarray, rows: np.ndarray
) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """The rows ``rows`` (dof indices, sorted) of ``K = a A + b B`` split by columns:
    ``K[rows][:, free]`` and ``K[rows][:, fixed]``, forming only those rows.

    A rank of the distributed backends takes its own block of free rows this way
    (:class:`~signorini.linalg.row_block.RowBlock`): its memory is nnz(K) / P, never
    all of K.  ``free`` and ``fixed`` are sorted, disjoint and cover 0..n-1.
    """
    rows = np.asarray(rows, dtype=np.intp)
    Kr = linear_combination(a, _canonical(A)[rows], b, _canonical(B)[rows], overwrite=True)
    n = Kr.shape[1]
    free, fixed = np.asarray(free, dtype=np.intp), np.asarray(fixed, dtype=np.intp)
    colmap = np.full(n, -1, dtype=np.int64)
    colmap[free] = np.arange(free.size)
    colmap[fixed] = np.arange(fixed.size)
    to_free = np.zeros(n, dtype=bool)
    to_free[free] = True
    mask = to_free[Kr.indices]
    Kf = _from_mask(Kr, mask, count_per_row(mask, Kr.indptr), (rows.size, free.size), colmap)
    KD = _from_mask(Kr, ~mask, count_per_row(~mask, Kr.indptr), (rows.size, fixed.size), colmap)
    return Kf, KD


def count_per_row(mask: np.ndarray, indptr: np.ndarray) -> np.ndarray:
    """Number of True entries of ``mask`` (nnz,) in each row of a CSR structure."""
    n = indptr.size - 1
    counts = np.zeros(n, dtype=np.int64)
    nonempty = np.flatnonzero(np.diff(indptr))
    if nonempty.size:
        counts[nonempty] = np.add.reduceat(mask, indptr[nonempty], dtype=np.int64)
    return counts


def _from_mask(A: sp.csr_matrix, mask: np.ndarray, counts: np.ndarray, shape, colmap=None) -> sp.csr_matrix:
    """The CSR matrix of A's entries where ``mask``; ``counts`` per kept row (in order)."""
    indptr = np.zeros(counts.size + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    indices = A.indices[mask]
    if colmap is not None:
        if colmap.dtype == indices.dtype:  # renumbered in place: no second index array
            np.take(colmap, indices, out=indices, mode="clip")
        else:
            indices = colmap[indices]
    idx_type = np.int32 if max(shape[1], indptr[-1]) < 2**31 else np.int64
    out = sp.csr_matrix(shape, dtype=A.dtype)
    # set after construction: the constructor would check (and may copy) the large arrays
    out.indptr, out.indices, out.data = indptr.astype(idx_type), indices.astype(idx_type, copy=False), A.data[mask]
    out.has_canonical_format = True  # a subset of canonical A's entries, in order
    return out


def principal_blocks(K: sp.spmatrix, free: np.ndarray, fixed: np.ndarray) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """``K[free][:, free]`` and ``K[free][:, fixed]`` in one pass over K's entries.

    ``free`` and ``fixed`` are disjoint dof indices covering 0..n-1 (in any other case,
    unsorted for instance, scipy's indexing does the work).
    """
    K = _canonical(K)
    n = K.shape[0]
    free, fixed = np.asarray(free, dtype=np.intp), np.asarray(fixed, dtype=np.intp)
    both = np.concatenate([free, fixed])
    ordered = np.all(np.diff(free) > 0) and np.all(np.diff(fixed) > 0)
    partition = both.size == n and (n == 0 or (both.min() >= 0 and both.max() < n))
    partition = partition and bool(np.all(np.bincount(both, minlength=n) == 1))
    if K.shape[0] != K.shape[1] or not ordered or not partition:
        Kf = K[free]
        return Kf[:, free].tocsr(), Kf[:, fixed].tocsr()
    keep = np.zeros(n, dtype=bool)
    keep[free] = True
    colmap = np.full(n, -1, dtype=np.int64 if n >= 2**31 else np.int32)
    colmap[free] = np.arange(free.size)
    row_nnz = np.diff(K.indptr)
    in_row = np.repeat(keep, row_nnz)  # entry lies in a free row
    to_fixed = np.flatnonzero(in_row & ~keep[K.indices])  # free row, fixed column: few
    mask = in_row
    mask[to_fixed] = False
    removed = np.bincount(np.searchsorted(K.indptr, to_fixed, side="right") - 1, minlength=n)
    Kff = _from_mask(K, mask, (row_nnz - removed)[free], (free.size, free.size), colmap)
    rows = np.searchsorted(K.indptr, to_fixed, side="right") - 1
    fixed_map = np.full(n, -1, dtype=np.int64)
    fixed_map[fixed] = np.arange(fixed.size)
    KfD = sp.csr_matrix(
        (K.data[to_fixed], (colmap[rows], fixed_map[K.indices[to_fixed]])), shape=(free.size, fixed.size)
    )
    return Kff, KfD


def upper_triangle(A: sp.spmatrix) -> sp.csr_matrix:
    """``sp.triu(A)`` (the diagonal and above) of a square matrix, from a mask."""
    A = _canonical(A)
    if A.shape[0] != A.shape[1]:
        raise ValueError(f"a square matrix is needed, got shape {A.shape}")
    rows = np.repeat(np.arange(A.shape[0], dtype=A.indices.dtype), np.diff(A.indptr))
    mask = A.indices >= rows
    del rows
    return _from_mask(A, mask, count_per_row(mask, A.indptr), A.shape)


def upper_block_triangle(A: sp.spmatrix, b: int, max_fill: float = 1.25) -> sp.bsr_matrix | None:
    """The b x b blocks of a square matrix A on and above the block diagonal (BSR), or
    None when A's size is not a multiple of b or its blocks would store more than
    ``max_fill`` times the non-zeros they hold (explicit zeros complete the blocks).

    The diagonal blocks are kept whole, as MKL's symmetric block storage expects.  Only
    the entries of those blocks are converted (no block copy of the whole of A).
    """
    A = _canonical(A)
    n = A.shape[0]
    if A.shape[1] != n or b < 1 or n % b:
        return None
    whole = _upper_of_whole_blocks(A, b)
    if whole is not None:
        return whole
    block_row = np.repeat(np.arange(n, dtype=A.indices.dtype) // b, np.diff(A.indptr))
    mask = A.indices // b >= block_row
    del block_row
    upper = _from_mask(A, mask, count_per_row(mask, A.indptr), A.shape)
    del mask
    blocks = upper.tobsr(blocksize=(b, b))
    if blocks.data.size > max_fill * max(upper.nnz, 1):
        return None
    return blocks


def _upper_of_whole_blocks(A: sp.csr_matrix, b: int) -> sp.bsr_matrix | None:
    """:func:`upper_block_triangle` when A is made of whole b x b blocks (the vector
    assembly's pattern: the b rows of a block row list the same block columns, each as b
    consecutive columns).  Then the values of a block row i are runs of b consecutive
    entries, gathered run by run: no mask over A's entries, no intermediate CSR.  None
    when A is not made of whole blocks.
    """
    nb = A.shape[0] // b
    length = np.diff(A.indptr)
    if np.any(length % b):
        return None
    L = length.reshape(nb, b)
    if np.any(L != L[:, :1]):
        return None
    runs = A.indices.reshape(-1, b)  # rows start at multiples of b: runs never straddle rows
    first = runs[:, 0]
    if np.any(first % b) or not all(np.array_equal(runs[:, j], first + j) for j in range(1, b)):
        return None
    itype = np.int32 if A.nnz < 2**31 else np.int64  # the run and block numbers
    per_row = (L[:, 0] // b).astype(itype)  # blocks per block row
    row_of = np.repeat(np.arange(nb, dtype=itype), per_row)
    offset = np.zeros(nb + 1, dtype=itype)
    np.cumsum(per_row, out=offset[1:])
    # run of block k of row (a, i): indptr[b a] / b + i per_row[a] + k
    run = np.arange(offset[-1], dtype=itype)
    run += np.repeat((A.indptr[:-1:b] // b).astype(itype) - offset[:-1], per_row)
    step = np.repeat(per_row, per_row)
    block_col = first[run] // b
    if not all(np.array_equal(first[run + i * step], first[run]) for i in range(1, b)):
        return None
    upper = block_col >= row_of
    run, step = run[upper], step[upper]
    indptr = np.zeros(nb + 1, dtype=np.int64)
    np.cumsum(np.bincount(row_of[upper], minlength=nb), out=indptr[1:])
    values = A.data.reshape(-1, b)
    data = np.empty((run.size, b, b), dtype=A.dtype)
    for i in range(b):  # the b rows of a block
        data[:, i, :] = values[run + i * step]
    return sp.bsr_matrix((data, block_col[upper].astype(itype), indptr.astype(itype)), shape=A.shape)
