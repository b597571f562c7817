"""Preconditioned conjugate gradients on a subspace (no factorization)."""

from __future__ import annotations

import importlib.util
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

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


class JacobiPreconditioner(Preconditioner):
    """P^-1 r = r / diag(K)."""

    def __init__(self, K: sp.csr_matrix, nodes: np.ndarray | None = None):
        self._dinv = 1.0 / K.diagonal()

    def __call__(self, r: np.ndarray) -> np.ndarray:
        return self._dinv * r


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


def projected_cg(
    K: sp.csr_matrix,
    rhs: np.ndarray,
    x0: np.ndarray,
    project: Callable[[np.ndarray], np.ndarray],
    precond: Preconditioner,
    rtol: float = 1e-12,
    max_iter: int = 2000,
) -> tuple[np.ndarray, int]:
    """Solve P K P x = P rhs on range(P) by preconditioned CG, started from P x0.

    ``project`` applies the orthogonal projector P.  Stops when |P(rhs - K x)| <=
    rtol |P rhs|.  Raises :class:`ConvergenceError` if it does not converge in
    ``max_iter`` iterations.
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
    raise ConvergenceError(f"conjugate gradients did not converge in {max_iter} iterations (rtol {rtol:g})")
