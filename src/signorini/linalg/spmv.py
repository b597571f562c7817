"""Sparse matrix-vector products ``A @ x`` (CG's inner loop, a step's right-hand side).

Two implementations, chosen by the solver option ``spmv`` (:data:`SPMV_KINDS`):

* :class:`ThreadedCSR` (``scipy``, always available): scipy's CSR product runs on one
  core and releases the GIL, so rows split into blocks of equal non-zeros are
  multiplied by threads at once.  bar3d n = 24 (450k dofs, 37M non-zeros) on 2 cores:
  one product 21.5-22.2 ms -> 11.8-12.0 ms.
* :class:`MKLProduct` (``mkl``, with the extra ``pardiso``): MKL's sparse BLAS
  (``mkl_sparse_d_mv``), threaded by MKL.  bar3d n = 32 (1.05M dofs, K with 70M
  non-zeros) on 2 cores, best of 9: 24 ms as a general CSR matrix, the same as
  ThreadedCSR; 15.5-18 ms from the upper triangle of the symmetric K (half the bytes
  read); 13.3 ms from its upper triangle of 3 x 3 nodal blocks (one column index per
  block).  The two symmetric storages are copies of half of K; the CG path uses them.
  MKL's ``mkl_sparse_optimize`` made no product faster and is not used.

``auto`` takes ``mkl`` when MKL is present.  Both give ``A @ x`` to round-off; only
ThreadedCSR gives the same bits as scipy.
"""

from __future__ import annotations

import ctypes
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from .mkl import has_mkl, mkl_runtime
from .sparse import upper_block_triangle, upper_triangle

#: the values of the solver option ``spmv``
SPMV_KINDS = ("auto", "scipy", "mkl")

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
        return self.matvec(x)

    def matvec(self, x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``A @ x`` (m,) into ``out`` (n,) when given (a new array otherwise)."""
        if self._pool is None:
            if out is None:
                return self.A @ x
            out[:] = self.A @ x
            return out
        y = np.empty(self.shape[0]) if out is None else out

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


# MKL's enumerations (mkl_spblas.h)
_INDEX_BASE_ZERO, _OPERATION_NON_TRANSPOSE = 0, 10
_MATRIX_TYPE_GENERAL, _MATRIX_TYPE_SYMMETRIC, _FILL_MODE_UPPER, _DIAG_NON_UNIT = 20, 21, 41, 50
_LAYOUT_ROW_MAJOR = 101


class _MatrixDescr(ctypes.Structure):
    _fields_ = [("type", ctypes.c_int), ("mode", ctypes.c_int), ("diag", ctypes.c_int)]


class MKLProduct:
    """``A @ x`` for a sparse matrix A (n x m, float64) by MKL's ``mkl_sparse_d_mv``.

    * general: MKL reads A's own CSR arrays (no copy; A must not change while this
      object lives);
    * ``symmetric`` (A symmetric, not checked): only the upper triangle is kept (a copy)
      and read, which halves the bytes a product moves;
    * ``symmetric`` and ``block_size = b > 1`` (dofs in nodal blocks of b, such as the
      components of a displacement): the upper triangle of b x b blocks in MKL's block
      storage, one column index per block instead of per entry; used when the blocks
      hold at most 1.25 times A's non-zeros (:func:`~.sparse.upper_block_triangle`),
      else the symmetric CSR storage.

    ``threads = 0``: MKL's thread count (one per physical core by default); else that
    many threads for these products only (``MKL_Set_Num_Threads_Local``, C interface).
    :attr:`storage` says which storage was taken: ``csr``, ``csr-upper`` or ``bsr-upper``.
    """

    def __init__(self, A: sp.spmatrix, threads: int = 0, symmetric: bool = False, block_size: int = 1):
        lib = mkl_runtime()
        if lib is None:
            raise InputError(
                "solver option spmv='mkl' needs MKL's runtime, from the extra 'pardiso' (pip install '.[pardiso]'); "
                "use spmv='scipy' or 'auto'"
            )
        A = A.tocsr() if sp.issparse(A) else sp.csr_matrix(A)
        if A.dtype != np.float64:
            A = A.astype(np.float64)
        self.symmetric = bool(symmetric)
        self.shape = A.shape
        if self.symmetric and A.shape[0] != A.shape[1]:
            raise ValueError(f"a symmetric matrix is square; got shape {A.shape}")
        blocks = upper_block_triangle(A, block_size) if self.symmetric and block_size > 1 else None
        if blocks is not None:
            self.storage, self.A, b = "bsr-upper", blocks, block_size
            # scipy's blocks are row-major, a layout MKL reads as is (as fast as its
            # column-major one, measured): MKL works on the BSR's own arrays, no copy
            self._data = np.ascontiguousarray(blocks.data)
        else:
            self.storage = "csr-upper" if self.symmetric else "csr"
            self.A, b = (upper_triangle(A) if self.symmetric else A), 1
            self._data = np.ascontiguousarray(self.A.data)
        if self._data.size >= 2**31 or max(A.shape) >= 2**31:
            raise MemoryError(f"A has {self._data.size} stored values: more than MKL's 32-bit indices hold")
        self._indptr = self.A.indptr.astype(np.int32, copy=False)
        self._indices = self.A.indices.astype(np.int32, copy=False)
        self._lib = lib
        self._threads = int(threads)
        kind = _MATRIX_TYPE_SYMMETRIC if self.symmetric else _MATRIX_TYPE_GENERAL
        self._descr = _MatrixDescr(kind, _FILL_MODE_UPPER, _DIAG_NON_UNIT)
        i32, f64 = ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_double)
        handle_p = ctypes.POINTER(ctypes.c_void_p)
        lib.mkl_sparse_d_create_csr.argtypes = [
            handle_p,
            ctypes.c_int,
            ctypes.c_int32,
            ctypes.c_int32,
            i32,
            i32,
            i32,
            f64,
        ]
        lib.mkl_sparse_d_create_bsr.argtypes = [
            handle_p,
            ctypes.c_int,
            ctypes.c_int,
            ctypes.c_int32,
            ctypes.c_int32,
            ctypes.c_int32,
            i32,
            i32,
            i32,
            f64,
        ]
        lib.mkl_sparse_d_create_csr.restype = lib.mkl_sparse_d_create_bsr.restype = ctypes.c_int
        lib.mkl_sparse_d_mv.argtypes = [
            ctypes.c_int,
            ctypes.c_double,
            ctypes.c_void_p,
            _MatrixDescr,
            f64,
            ctypes.c_double,
            f64,
        ]
        lib.mkl_sparse_d_mv.restype = ctypes.c_int
        lib.mkl_sparse_destroy.argtypes = [ctypes.c_void_p]
        lib.MKL_Set_Num_Threads_Local.argtypes = [ctypes.c_int]
        lib.MKL_Set_Num_Threads_Local.restype = ctypes.c_int
        self._handle = ctypes.c_void_p()
        ptr = self._indptr.ctypes.data
        # rows_start = indptr[:-1], rows_end = indptr[1:] (of rows of blocks for BSR)
        starts, ends = ctypes.cast(ptr, i32), ctypes.cast(ptr + 4, i32)
        indices, data = self._indices.ctypes.data_as(i32), self._data.ctypes.data_as(f64)
        if b > 1:
            rows, cols = A.shape[0] // b, A.shape[1] // b
            status = lib.mkl_sparse_d_create_bsr(
                ctypes.byref(self._handle),
                _INDEX_BASE_ZERO,
                _LAYOUT_ROW_MAJOR,
                rows,
                cols,
                b,
                starts,
                ends,
                indices,
                data,
            )
        else:
            status = lib.mkl_sparse_d_create_csr(
                ctypes.byref(self._handle), _INDEX_BASE_ZERO, A.shape[0], A.shape[1], starts, ends, indices, data
            )
        if status != 0:
            self._handle = None
            raise RuntimeError(f"MKL could not create its sparse matrix handle (status {status})")
        self._f64 = f64

    @property
    def threads(self) -> int:
        return self._threads

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        return self.matvec(x)

    def matvec(self, x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``A @ x`` (m,) into ``out`` (n,) when given (a new array otherwise)."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        if x.shape != (self.shape[1],):
            raise ValueError(f"x must have shape ({self.shape[1]},), got {x.shape}")
        y = np.empty(self.shape[0]) if out is None else out
        if self._threads:
            previous = self._lib.MKL_Set_Num_Threads_Local(self._threads)
        try:
            status = self._lib.mkl_sparse_d_mv(
                _OPERATION_NON_TRANSPOSE,
                1.0,
                self._handle,
                self._descr,
                x.ctypes.data_as(self._f64),
                0.0,
                y.ctypes.data_as(self._f64),
            )
        finally:
            if self._threads:
                self._lib.MKL_Set_Num_Threads_Local(previous)
        if status != 0:
            raise RuntimeError(f"mkl_sparse_d_mv failed with status {status}")
        return y

    def close(self) -> None:
        if getattr(self, "_handle", None) is not None:
            self._lib.mkl_sparse_destroy(self._handle)
            self._handle = None

    def __del__(self):  # pragma: no cover - at garbage collection
        self.close()


def sparse_product(
    A: sp.spmatrix, kind: str = "auto", threads: int = 0, symmetric: bool = False, block_size: int = 1
) -> ThreadedCSR | MKLProduct:
    """The object computing ``A @ x`` for ``kind`` (:data:`SPMV_KINDS`; ``auto``: MKL
    when present and A is large enough to gain from threads, else ThreadedCSR).
    ``symmetric`` (A symmetric, not checked) and ``block_size``: MKL's storage
    (:class:`MKLProduct`)."""
    if kind not in SPMV_KINDS:
        raise InputError(f"solver option 'spmv' must be one of {', '.join(SPMV_KINDS)}; got {kind!r}")
    A = A.tocsr() if sp.issparse(A) else sp.csr_matrix(A)
    if kind == "mkl" or (kind == "auto" and A.nnz >= MIN_NNZ and has_mkl()):
        return MKLProduct(A, threads, symmetric, block_size)
    return ThreadedCSR(A, threads)
