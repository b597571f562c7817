"""Linear solvers for the SPD matrix K_eff = a M + S, behind one interface.

``factorize(K, backend)`` returns an object with ``solve(b)`` (vector or matrix of
right-hand sides), ``name`` and ``nbytes``.  Backends:

``superlu``  scipy's SuperLU, symmetric ordering (MMD on A^T + A), no off-diagonal
             pivoting: an LU that behaves like a Cholesky factor on SPD matrices.
             Always available (the pip-only default).
``pardiso``  Intel MKL Pardiso through ``pypardiso`` (extra ``pardiso``), SPD mode with
             nested-dissection ordering: much smaller factors in 3D.  Used automatically
             when installed.
``cg``       no factorization: conjugate gradients preconditioned by Jacobi (or by
             smoothed-aggregation AMG with ``pyamg``, extra ``amg``), warm-started; used
             with the active-set contact stepper when a factor would not fit in memory.

:func:`choose_backend` picks one automatically from the estimated factor size and a
memory budget (default 40% of the machine's RAM); ``backend=...`` overrides it.
"""

from __future__ import annotations

import importlib.util
import os

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import InputError

BACKENDS = ("auto", "superlu", "pardiso", "cg")


def has_pardiso() -> bool:
    return importlib.util.find_spec("pypardiso") is not None


def has_pyamg() -> bool:
    return importlib.util.find_spec("pyamg") is not None


def total_memory() -> int:
    """Physical memory of the machine [bytes]."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 8 * 2**30


def estimate_factor_bytes(n: int, dim: int, backend: str) -> float:
    """Rough size of a sparse factor of a P1/Q1 elasticity matrix with n dofs [bytes].

    Fitted on this project's bars (values + indices, 12 bytes per entry):
    SuperLU/MMD grows like n^1.9 in 3D (0.59e6 entries at 3e3 dofs, 19.7e6 at 1.9e4);
    Pardiso/nested dissection like 16 n^(4/3) in 3D; both like ~40 n log n in 2D.
    """
    if dim <= 1:
        return 12.0 * 3 * n
    if dim == 2:
        return 12.0 * 40 * n * max(np.log2(n), 1.0)
    if backend == "pardiso":
        return 12.0 * 16 * n ** (4 / 3)
    return 12.0 * 0.5925e6 * (n / 3000.0) ** 1.875


SMALL = 30_000  # below this many dofs SuperLU factors faster than Pardiso starts


def choose_backend(n: int, dim: int, budget: float | None = None) -> str:
    """Direct solver when its estimated factor fits in ``budget`` bytes, else ``cg``.

    SuperLU for small systems (< 30k dofs, where Pardiso's start-up dominates), then
    Pardiso when installed, SuperLU otherwise, and CG when no factor fits.
    """
    budget = 0.4 * total_memory() if budget is None else budget
    if n < SMALL and estimate_factor_bytes(n, dim, "superlu") <= budget:
        return "superlu"
    if has_pardiso() and estimate_factor_bytes(n, dim, "pardiso") <= budget:
        return "pardiso"
    if estimate_factor_bytes(n, dim, "superlu") <= budget:
        return "superlu"
    return "cg"


class SuperLUFactor:
    """SuperLU factor of an SPD matrix (symmetric mode)."""

    name = "superlu"

    def __init__(self, K: sp.spmatrix):
        self._lu = spla.splu(
            sp.csc_matrix(K),
            permc_spec="MMD_AT_PLUS_A",
            diag_pivot_thresh=0.0,
            options={"SymmetricMode": True},
        )

    @property
    def nbytes(self) -> int:
        return int(12 * (self._lu.L.nnz + self._lu.U.nnz))

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(np.asarray(b, dtype=float))


class PardisoFactor:
    """MKL Pardiso (pypardiso), real SPD mode on the upper triangle, factorized once."""

    name = "pardiso"

    def __init__(self, K: sp.spmatrix):
        try:
            import pypardiso
        except ImportError:  # pragma: no cover - depends on the machine
            raise InputError("backend 'pardiso' needs pypardiso: pip install 'signorini[pardiso]'") from None
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

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asfortranarray(np.asarray(b, dtype=float))
        self._solver.set_phase(33)  # solve only: the factor is reused, no re-hashing of A
        return self._solver._call_pardiso(self._A, b)


def factorize(K: sp.spmatrix, backend: str = "superlu"):
    """Factorize the SPD matrix ``K`` once with a direct backend."""
    if backend == "superlu":
        return SuperLUFactor(K)
    if backend == "pardiso":
        return PardisoFactor(K)
    raise InputError(f"unknown direct solver backend {backend!r}; allowed: superlu, pardiso")


# ----------------------------------------------------------------------------- iterative
class Preconditioner:
    """Jacobi, or smoothed-aggregation AMG (pyamg) when ``kind='amg'``."""

    def __init__(self, K: sp.csr_matrix, kind: str = "jacobi"):
        self.kind = kind
        if kind == "amg":
            if not has_pyamg():
                raise InputError("preconditioner 'amg' needs pyamg: pip install 'signorini[amg]'")
            import pyamg

            self._amg = pyamg.smoothed_aggregation_solver(K, symmetry="hermitian", max_coarse=500)
            self._M = self._amg.aspreconditioner(cycle="V")
        elif kind == "jacobi":
            self._dinv = 1.0 / K.diagonal()
        else:
            raise InputError(f"unknown preconditioner {kind!r}; allowed: jacobi, amg")

    def __call__(self, r: np.ndarray) -> np.ndarray:
        if self.kind == "amg":
            return self._M @ r
        return self._dinv * r


def projected_cg(
    K: sp.csr_matrix,
    rhs: np.ndarray,
    x0: np.ndarray,
    project,
    precond: Preconditioner,
    rtol: float = 1e-12,
    max_iter: int = 2000,
) -> tuple[np.ndarray, int]:
    """Solve P K P x = P rhs on range(P) by preconditioned CG, started from P x0.

    ``project`` applies the orthogonal projector P.  Stops when |P(rhs - K x)| <=
    rtol |P rhs|.  Raises RuntimeError if it does not converge in ``max_iter``.
    """
    x = project(x0)
    r = project(rhs - K @ x)
    bnorm = np.linalg.norm(project(rhs))
    if bnorm == 0.0:
        return np.zeros_like(x), 0
    tol = rtol * bnorm
    if np.linalg.norm(r) <= tol:
        return x, 0
    z = project(precond(r))
    p = z.copy()
    rz = r @ z
    for it in range(1, max_iter + 1):
        Kp = project(K @ p)
        alpha = rz / (p @ Kp)
        x += alpha * p
        r -= alpha * Kp
        if np.linalg.norm(r) <= tol:
            return x, it
        z = project(precond(r))
        rz_new = r @ z
        p = z + (rz_new / rz) * p
        rz = rz_new
    raise RuntimeError(f"conjugate gradients did not converge in {max_iter} iterations")
