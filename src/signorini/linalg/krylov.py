"""Preconditioned conjugate gradients on a subspace (no factorization)."""

from __future__ import annotations

import importlib.util
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from ..errors import ConvergenceError, InputError


def has_pyamg() -> bool:
    return importlib.util.find_spec("pyamg") is not None


class Preconditioner:
    """Jacobi (``kind='jacobi'``), or smoothed-aggregation AMG with pyamg (``'amg'``)."""

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
