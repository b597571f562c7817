"""Linear complementarity problems with a symmetric positive definite matrix.

Problem (LCP): find mu >= 0 with r = q + W mu >= 0 and r . mu = 0, W SPD (n x n).
It is the optimality system of min 1/2 mu^T W mu + q^T mu over mu >= 0.

Default method: primal-dual active set (= semismooth Newton on the NCP function
``mu = max(0, mu - c r)``, Hintermueller-Ito-Kunisch), warm-started from a given
active set.  If it cycles or exceeds its iteration budget the problem is solved by
Lawson-Hanson non-negative least squares on the Cholesky factor (finite, exact):
with W = L L^T, the QP equals min |L^T mu + L^{-1} q|^2 / 2 over mu >= 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from scipy.optimize import nnls


@dataclass
class LCPResult:
    mu: np.ndarray  # (n,) >= 0
    r: np.ndarray  # (n,) = q + W mu >= 0
    active: np.ndarray  # (n,) bool, mu > 0 or r == 0 chosen active
    iterations: int
    fallback: bool
    residual: float  # max |min(r, c mu)| / scale


def complementarity_residual(mu: np.ndarray, r: np.ndarray, c: float, scale: float) -> float:
    """max_i |min(r_i, c mu_i)| / scale (0 exactly at a solution)."""
    if mu.size == 0:
        return 0.0
    return float(np.max(np.abs(np.minimum(r, c * mu)))) / scale


def solve_lcp(
    W: np.ndarray,
    q: np.ndarray,
    active: np.ndarray | None = None,
    max_iter: int = 50,
    scale: float | None = None,
) -> LCPResult:
    """Solve the LCP (W, q) by primal-dual active set, with an NNLS fallback.

    Parameters
    ----------
    W : (n, n) SPD matrix [length / force].
    q : (n,) [length]; here q = gap of the unconstrained step.
    active : initial active-set guess (e.g. the previous time step's).
    scale : length scale of the residual (default max(|q|_inf, tiny)).
    """
    n = q.size
    if n == 0:
        return LCPResult(np.zeros(0), np.zeros(0), np.zeros(0, bool), 0, False, 0.0)
    c = 1.0 / float(np.mean(np.diag(W)))  # mu * c has length units
    scale = scale if scale is not None else max(float(np.max(np.abs(q))), 1e-300)
    A = np.zeros(n, dtype=bool) if active is None else active.copy()
    seen = set()
    mu = np.zeros(n)
    it = 0
    for it in range(1, max_iter + 1):
        mu = np.zeros(n)
        if A.any():
            WA = W[np.ix_(A, A)]
            try:
                mu[A] = sla.solve(WA, -q[A], assume_a="pos", check_finite=False)
            except (np.linalg.LinAlgError, sla.LinAlgError):
                break
        r = q + W @ mu
        if A.any():
            r[A] = 0.0  # exact on the active set (removes round-off)
        A_new = (mu - c * r) > 0
        if np.array_equal(A_new, A):
            res = complementarity_residual(mu, q + W @ mu, c, scale)
            return LCPResult(mu, r, A, it, False, res)
        key = A_new.tobytes()
        if key in seen:
            break
        seen.add(key)
        A = A_new
    # robust fallback: NNLS on the Cholesky factor
    L = np.linalg.cholesky(W)
    b = -sla.solve_triangular(L, q, lower=True)
    mu, _ = nnls(L.T, b, maxiter=50 * n)
    r = q + W @ mu
    A = mu > 0
    res = complementarity_residual(mu, r, c, scale)
    return LCPResult(mu, r, A, it, True, res)  # the active-set iterations actually made before the fallback
