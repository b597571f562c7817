"""The per-step exact contact solve on a matrix factorized once per run.

Each step solves::

    K U = b + B^T lambda,   B U <= g,   lambda <= 0,   (B U - g) . lambda = 0

with K = a M + S SPD.  Condensation onto the contact dofs: with Z = K^-1 B^T
(n x nc, one solve per contact node at set-up) and the Delassus matrix W = B Z,

    U = U_free + Z lambda,     U_free = K^-1 b,

and mu = -lambda solves the LCP  r = (g - B U_free) + W mu >= 0, mu >= 0, r.mu = 0
(see :mod:`signorini.complementarity`).  A step therefore costs one forward/backward
substitution, a small dense LCP warm-started from the previous active set, and one
product with the active columns of Z.  If Z does not fit in ``memory_budget`` bytes
it is not stored and a second solve is made on steps with contact.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .complementarity import solve_lcp
from .linalg import factorize


@dataclass
class StepInfo:
    iterations: int
    fallback: bool
    residual: float
    active: np.ndarray


class ContactStepper:
    """Factor ``K`` once, condense the contact problem, solve steps exactly."""

    def __init__(
        self,
        K: sp.spmatrix,
        B: sp.csr_matrix,
        gaps: np.ndarray,
        backend: str = "superlu",
        memory_budget: float = 2e9,
    ):
        import time

        t0 = time.perf_counter()
        self.factor = factorize(K, backend)
        t1 = time.perf_counter()
        self.B = sp.csr_matrix(B)
        self.gaps = np.asarray(gaps, dtype=float)
        nc, n = self.B.shape
        self.store_Z = n * nc * 8 <= memory_budget
        if nc:
            Z = self.factor.solve(self.B.T.toarray())
            Z = Z.reshape(n, nc)
            W = self.B @ Z
            self.W = 0.5 * (W + W.T)
            self.Z = Z if self.store_Z else None
        else:
            self.W = np.zeros((0, 0))
            self.Z = np.zeros((n, 0))
        self.active = np.zeros(nc, dtype=bool)
        self.gap_scale = max(float(np.max(np.abs(self.gaps))) if nc else 0.0, 1e-300)
        self.timings = {"factorization": t1 - t0, "condensation": time.perf_counter() - t1}

    def solve(self, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, StepInfo]:
        """Return (U, lambda, info) for the right-hand side ``b``."""
        U = self.factor.solve(b)
        if self.gaps.size == 0:
            return U, np.zeros(0), StepInfo(0, False, 0.0, self.active)
        q = self.gaps - self.B @ U
        scale = max(self.gap_scale, float(np.max(np.abs(q))))
        res = solve_lcp(self.W, q, self.active, scale=scale)
        lam = -res.mu
        A = lam != 0.0
        if A.any():
            if self.Z is not None:
                U = U + self.Z[:, A] @ lam[A]
            else:
                U = U + self.factor.solve(self.B.T @ lam)
        self.active = res.active
        return U, lam, StepInfo(res.iterations, res.fallback, res.residual, res.active)
