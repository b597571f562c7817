"""Preconditioned conjugate gradients on a subspace (no factorization)."""

from __future__ import annotations

import importlib.util
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from scipy.linalg.blas import daxpy as _daxpy

from ..errors import ConvergenceError
from ..optional import optional_import


def has_pyamg() -> bool:
    return importlib.util.find_spec("pyamg") is not None


class Preconditioner:
    """A symmetric positive definite approximation P^-1 of K^-1, applied as ``P(r)``.

    Subclasses are entries of :data:`~signorini.linalg.PRECONDITIONERS`; they are built
    from the matrix K (n x n, CSR) and ``nodes`` (n,), the mesh node of each row (rows of
    one node form one block of ``block-jacobi``).
    """

    def __init__(self, K: sp.csr_matrix, nodes: np.ndarray | None = None):
        self.K = K

    def __call__(self, r: np.ndarray) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError

    def apply(self, r: np.ndarray, out: np.ndarray) -> np.ndarray:
        """``P(r)`` written into ``out`` (n,) (subclasses may avoid the temporary)."""
        out[:] = self(r)
        return out


class JacobiPreconditioner(Preconditioner):
    """P^-1 r = r / diag(K)."""

    def __init__(self, K: sp.csr_matrix, nodes: np.ndarray | None = None):
        self._dinv = 1.0 / K.diagonal()

    def __call__(self, r: np.ndarray) -> np.ndarray:
        return self._dinv * r

    def apply(self, r: np.ndarray, out: np.ndarray) -> np.ndarray:
        return np.multiply(self._dinv, r, out=out)


class BlockJacobiPreconditioner(Preconditioner):
    """P^-1 r = blockdiag(K_nn)^-1 r with the d x d block K_nn of each mesh node.

    The blocks (nodes with fewer free dofs padded by the identity) are inverted once,
    batched; applying costs a gather, one batched d x d matrix-vector product and a
    scatter.
    """

    def __init__(self, K: sp.csr_matrix, nodes: np.ndarray | None = None):
        n = K.shape[0]
        nodes = np.arange(n) if nodes is None else np.asarray(nodes)
        uniq, group = np.unique(nodes, return_inverse=True)
        order = np.argsort(group, kind="stable")
        first = np.searchsorted(group[order], np.arange(uniq.size))
        local = np.empty(n, dtype=np.intp)
        local[order] = np.arange(n) - first[group[order]]
        d = int(local.max()) + 1 if n else 1
        C = K.tocoo()
        same = group[C.row] == group[C.col]
        blocks = np.zeros((uniq.size, d, d))
        blocks[group[C.row[same]], local[C.row[same]], local[C.col[same]]] = C.data[same]
        pad = np.ones((uniq.size, d), dtype=bool)
        pad[group, local] = False
        blocks[pad.nonzero()[0], pad.nonzero()[1], pad.nonzero()[1]] = 1.0
        self._inv = np.linalg.inv(blocks)
        self._group, self._local, self._d = group, local, d

    def __call__(self, r: np.ndarray) -> np.ndarray:
        R = np.zeros((self._inv.shape[0], self._d))
        R[self._group, self._local] = r
        Z = np.einsum("gij,gj->gi", self._inv, R)
        return Z[self._group, self._local]


class AMGPreconditioner(Preconditioner):
    """One V-cycle of smoothed-aggregation AMG (pyamg, extra ``amg``)."""

    def __init__(self, K: sp.csr_matrix, nodes: np.ndarray | None = None):
        pyamg = optional_import("pyamg", "preconditioner 'amg'", "amg")
        self._M = pyamg.smoothed_aggregation_solver(K, symmetry="hermitian", max_coarse=500).aspreconditioner(cycle="V")

    def __call__(self, r: np.ndarray) -> np.ndarray:
        return self._M @ r


def make_preconditioner(kind: str, K: sp.csr_matrix, nodes: np.ndarray | None = None) -> Preconditioner:
    """The preconditioner registered as ``kind`` in PRECONDITIONERS, built for K."""
    from .base import PRECONDITIONERS

    obj = PRECONDITIONERS.get(kind).obj
    if isinstance(obj, str):  # "module:Class", imported only when chosen
        module, cls = obj.split(":")
        obj = getattr(importlib.import_module(module, __package__), cls)
    return obj(K, nodes)


def _product(K, x: np.ndarray, out: np.ndarray) -> np.ndarray:
    """``K @ x`` into ``out`` (through ``K.matvec(x, out)`` when K offers it)."""
    matvec = getattr(K, "matvec", None)
    if matvec is not None and not sp.issparse(K):
        return matvec(x, out=out)
    out[:] = K @ x
    return out


def projected_cg(
    K,
    rhs: np.ndarray,
    x0: np.ndarray,
    project: Callable[[np.ndarray], None],
    precond: Preconditioner,
    rtol: float = 1e-12,
    max_iter: int = 2000,
) -> tuple[np.ndarray, int]:
    """Solve P K P x = P rhs on range(P) by preconditioned CG, started from P x0.

    ``K`` (n x n) is a sparse matrix or an object with ``matvec(x, out=...)``
    (:mod:`.spmv`); ``project(v)`` applies the orthogonal projector P to v **in place**.
    Stops when |P(rhs - K x)| <= rtol |P rhs|.  Raises :class:`ConvergenceError` if it
    does not converge in ``max_iter`` iterations.

    The iteration works in five preallocated vectors (no temporary of size n inside the
    loop: on 1M dofs a fresh temporary costs about as much as the arithmetic on it).
    """
    x = np.array(x0, dtype=np.float64, copy=True)
    project(x)
    r = np.empty_like(x)
    Pb = np.array(rhs, dtype=np.float64, copy=True)
    project(Pb)
    bnorm = np.sqrt(np.dot(Pb, Pb))
    if bnorm == 0.0:
        return np.zeros_like(x), 0
    tol = rtol * bnorm
    _product(K, x, r)
    np.subtract(rhs, r, out=r)
    project(r)
    if np.sqrt(np.dot(r, r)) <= tol:
        return x, 0
    z, Kp = Pb, np.empty_like(x)  # Pb is not needed any more: its memory serves z
    precond.apply(r, z)
    project(z)
    p = z.copy()
    rz = np.dot(r, z)
    for it in range(1, max_iter + 1):
        _product(K, p, Kp)
        project(Kp)
        alpha = rz / np.dot(p, Kp)
        _axpy(alpha, p, x)
        _axpy(-alpha, Kp, r)
        if np.sqrt(np.dot(r, r)) <= tol:
            return x, it
        precond.apply(r, z)
        project(z)
        rz_new = np.dot(r, z)
        p *= rz_new / rz
        p += z
        rz = rz_new
    raise ConvergenceError(f"conjugate gradients did not converge in {max_iter} iterations (rtol {rtol:g})")


def _axpy(a: float, x: np.ndarray, y: np.ndarray) -> None:
    """y += a x in place (BLAS daxpy, no temporary)."""
    _daxpy(x, y, a=a)
