"""MKL Pardiso through ``pypardiso`` (optional extra ``pardiso``), imported lazily.

pypardiso finds MKL's ``mkl_rt`` library and declares the ``pardiso`` entry point; the
calls are made here (:meth:`PardisoFactor._call`) so that

* the 1-based index arrays of K are built once, not at every solve;
* the factorization can also return the **Schur complement** of K on a set of dofs C
  (MKL's ``iparm[35] = 2`` with ``perm`` marking C; C is ordered last), keeping the full
  factor: ``S = K_CC - K_CI K_II^-1 K_IC`` (dense, |C| x |C|), and a solve can be split
  into its forward part (phase 331: ``y_C = b_C - K_CI K_II^-1 b_I``, the reduced
  right-hand side on C) and its backward part (phase 333: from ``y`` with ``y_C``
  replaced by x_C, the interior x_I = K_II^-1 (b_I - K_IC x_C)).  Together they cost
  one solve (docs/design.md, "Schur condensation").

A run factorizes many matrices of one pattern (each Newton tangent): a factor released
(:meth:`PardisoFactor.release`: no longer of use) leaves its MKL handle, holding the analysis
(the METIS ordering and the symbolic factorization, phase 11), to the next factorization of the
same pattern (:data:`KEPT`), which runs the numeric phase (22) alone.
"""

from __future__ import annotations

import ctypes
import os

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..optional import optional_import
from .base import Factor, KeptAnalyses
from .mkl import mkl_path_hint
from .ordering import compressed_digest
from .sparse import upper_triangle

#: MKL phases: analysis + factorization, numeric factorization, solve, forward part, backward part, release
FACTORIZE, NUMERIC, SOLVE, FORWARD, BACKWARD, RELEASE = 12, 22, 33, 331, 333, -1

#: released factors, whose MKL handles hold their analyses, by (mode, shape, pattern digest)
KEPT = KeptAnalyses()


def _mkl_threads() -> int:
    """The threads MKL would use now (``mkl_get_max_threads``; the cores when it is not known)."""
    from .mkl import mkl_runtime

    lib = mkl_runtime()
    get = getattr(lib, "MKL_Get_Max_Threads", None) if lib is not None else None
    return int(get()) if get is not None else (os.cpu_count() or 1)


class PardisoFactor(Factor):
    """Real SPD mode on the upper triangle, nested-dissection ordering, factorized once.

    ``schur_dofs`` (indices, optional): also compute the Schur complement of K on these
    dofs (:attr:`schur`) and allow :meth:`forward` / :meth:`backward`.  ``reproducible``: MKL's
    conditional numerical reproducibility mode (``iparm[33]``, the threads MKL would take): the
    same bits from run to run on the same machine and thread count; without it the parallel
    factorization differs at round-off from one run to the next (measured in docs/performance.md,
    with its cost: the solves about twice slower).
    """

    name = "pardiso"
    supports_schur = True
    supports_reproducible = True

    def __init__(self, K: sp.spmatrix, schur_dofs: np.ndarray | None = None, reproducible: bool = False):
        super().__init__()
        with mkl_path_hint():
            pypardiso = optional_import("pypardiso", "backend 'pardiso'", "pardiso")
        A = upper_triangle(K).astype(np.float64, copy=False)
        if A.nnz >= 2**31:
            raise MemoryError(f"K has {A.nnz} non-zeros in its upper triangle: more than MKL's 32-bit indices hold")
        self._A = A
        self._n = A.shape[0]
        self.schur: np.ndarray | None = None
        self.schur_dofs = None
        self._key: tuple | None = None
        if schur_dofs is None:  # a released factor of this pattern: its analysis, the numeric phase only
            threads = max(_mkl_threads(), 1) if reproducible else 0  # the reproducible mode's threads: its bits
            self._key = (threads, A.shape, compressed_digest(A.indptr, A.indices))
            kept = KEPT.take(self._key)
            if kept is not None:
                self._solver, self._ia, self._ja, self._perm = kept._solver, kept._ia, kept._ja, kept._perm
                kept._solver = None  # this factor releases MKL's memory now, not the one it came from
                self._call(NUMERIC, np.zeros(self._n), np.zeros(1))
                return
        self._ia = (A.indptr + 1).astype(np.int32)
        self._ja = (A.indices + 1).astype(np.int32)
        self._solver = None
        with mkl_path_hint():  # a new solver object searches for mkl_rt again
            solver = pypardiso.PyPardisoSolver(mtype=2)
        if not all(hasattr(solver, a) for a in ("_mkl_pardiso", "pt", "iparm", "_pt_type")):
            raise InputError(
                f"pypardiso {getattr(pypardiso, '__version__', '?')} does not expose MKL's pardiso handle as the "
                "versions 0.4.x do; install pypardiso<0.5 or use another backend"
            )
        self._solver = solver
        iparm = solver.iparm
        iparm[:] = 0
        iparm[0] = 1  # the values below, not MKL's defaults
        iparm[1] = 3  # nested dissection (METIS), its parallel version
        iparm[9] = 8  # pivot perturbation 1e-8 (MKL's default for symmetric matrices)
        iparm[17] = -1  # report the factor's non-zeros
        if reproducible:
            iparm[33] = max(_mkl_threads(), 1)  # conditional numerical reproducibility with this many threads
        self._perm = np.zeros(self._n, dtype=np.int32)
        buffer = np.zeros(1)
        if schur_dofs is not None:
            dofs = np.unique(np.asarray(schur_dofs, dtype=np.intp))  # MKL returns S in increasing dof order
            if dofs.size and (dofs[0] < 0 or dofs[-1] >= self._n):
                raise ValueError(f"schur_dofs must lie in [0, {self._n}); got {dofs[0]}..{dofs[-1]}")
            self.schur_dofs = dofs
            ns = dofs.size
            self._perm[self.schur_dofs] = 1
            iparm[35] = 2  # Schur complement, and keep the whole factor for solves
            buffer = np.zeros((ns, ns), order="F")
        self._call(FACTORIZE, np.zeros(self._n), buffer)
        if schur_dofs is not None:
            self.schur = buffer

    def release(self) -> None:
        """No longer of use: its MKL handle (the analysis) goes to the next factorization of its pattern
        (:data:`KEPT`); this factor solves no more."""
        if self._key is not None and self._solver is not None and not KEPT.holds(self):
            KEPT.keep(self._key, self, self.nbytes)  # a factor dropped from it releases its handle (``__del__``)

    def _call(self, phase: int, b: np.ndarray, x: np.ndarray) -> None:
        """One call of MKL's ``pardiso`` (b, x Fortran-ordered float64; x is written)."""
        s = self._solver
        if s is None and phase == RELEASE:  # its handle went to another factor (or it was never made)
            return
        if s is None or KEPT.holds(self):
            raise RuntimeError("a released Pardiso factor was asked to solve (its analysis serves another now)")
        i32, f64 = ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_double)
        err = ctypes.c_int32(0)
        nrhs = 1 if b.ndim == 1 else b.shape[1]

        def ref(v: int):
            return ctypes.byref(ctypes.c_int32(v))

        pt_type = np.ctypeslib.as_ctypes_type(s.pt.dtype)  # pypardiso's handle: 64 integers of the platform's size
        s.libmkl.pardiso(  # the MKL function pypardiso declared (its argtypes)
            s.pt.ctypes.data_as(ctypes.POINTER(pt_type)),
            ref(1),
            ref(1),
            ref(2),
            ref(phase),
            ref(self._n),
            self._A.data.ctypes.data_as(f64),
            self._ia.ctypes.data_as(i32),
            self._ja.ctypes.data_as(i32),
            self._perm.ctypes.data_as(i32),
            ref(nrhs),
            s.iparm.ctypes.data_as(i32),
            ref(0),
            b.ctypes.data_as(f64),
            x.ctypes.data_as(f64),
            ctypes.byref(err),
        )
        if err.value != 0:
            raise RuntimeError(f"MKL Pardiso error {err.value} in phase {phase}")

    @property
    def nbytes(self) -> int:
        """Factor size from Pardiso's report (non-zeros of L, values + indices) [bytes]."""
        return 0 if self._solver is None else int(12 * max(int(self._solver.iparm[17]), 0))

    def _run(self, phase: int, b: np.ndarray) -> np.ndarray:
        b = np.asfortranarray(np.asarray(b, dtype=float))
        x = np.zeros_like(b, order="F")
        self._call(phase, b, x)
        return np.ascontiguousarray(x)

    def _solve(self, b: np.ndarray) -> np.ndarray:
        return self._run(SOLVE, b)

    def forward(self, b: np.ndarray) -> np.ndarray:
        """The forward part of a solve (needs ``schur_dofs``): y with y_C the reduced
        right-hand side b_C - K_CI K_II^-1 b_I; counts one solve per right-hand side."""
        self.solves += 1 if np.ndim(b) == 1 else int(np.shape(b)[1])
        return self._run(FORWARD, b)

    def backward(self, y: np.ndarray) -> np.ndarray:
        """The solution x from ``forward``'s y with y_C replaced by x_C."""
        return self._run(BACKWARD, y)

    def __del__(self) -> None:
        try:
            self._call(RELEASE, np.zeros(1), np.zeros(1))
        except Exception:  # interpreter shutdown, or never factorized
            pass
