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

from ..contact.complementarity import complementarity_residual, solve_lcp
from ..linalg.backends import Preconditioner, choose_backend, factorize, projected_cg


def _best_time(op, n: int, repeats: int = 3) -> float:
    """Best of ``repeats`` timings of ``op`` on a random vector of length n [s]."""
    import time

    x = np.random.default_rng(0).normal(size=n)
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        op(x)
        best = min(best, time.perf_counter() - t0)
    return best


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
        self.name = self.factor.name
        self.B = sp.csr_matrix(B)
        self.gaps = np.asarray(gaps, dtype=float)
        nc, n = self.B.shape
        self.store_Z = n * nc * 8 <= memory_budget
        if nc:
            # Z = K^-1 B^T in column blocks, to bound the dense temporaries
            Z = np.empty((n, nc))
            Bt = self.B.T.tocsc()
            for j in range(0, nc, 64):
                Z[:, j : j + 64] = self.factor.solve(Bt[:, j : j + 64].toarray()).reshape(n, -1)
            W = self.B @ Z
            self.W = 0.5 * (W + W.T)
            self.Z = Z if self.store_Z else None
        else:
            self.W = np.zeros((0, 0))
            self.Z = np.zeros((n, 0))
        self.active = np.zeros(nc, dtype=bool)
        self.gap_scale = max(float(np.max(np.abs(self.gaps))) if nc else 0.0, 1e-300)
        self.timings = {"factorization": t1 - t0, "condensation": time.perf_counter() - t1}
        self.timings["bare_solve"] = _best_time(lambda x: self.factor.solve(x), n)
        self.factor_bytes = self.factor.nbytes

    def solve(self, b: np.ndarray, gaps: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, StepInfo]:
        """Return (U, lambda, info) for the right-hand side ``b``; ``gaps`` replaces the
        constraint's right-hand side g for this step (two-step schemes)."""
        U = self.factor.solve(b)
        if self.gaps.size == 0:
            return U, np.zeros(0), StepInfo(0, False, 0.0, self.active)
        q = (self.gaps if gaps is None else gaps) - self.B @ U
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


class IterativeContactStepper:
    """Active-set (semismooth Newton) contact solve on top of projected PCG, no factor.

    For an active set A the constraint nu_i . u_i = g_i (i in A) is imposed exactly by
    writing U = u_p + P w with u_p = B_A^T g_A and the orthogonal projector
    P = I - B_A^T B_A (rows of B are orthonormal); ``P K P w = P (b - K u_p)`` is solved
    by CG warm-started from the previous step.  Then lambda_A = B_A (K U - b), the gaps
    are checked and A is updated by the rule A = {i : -lambda_i - c gap_i > 0} until it
    no longer changes.
    """

    def __init__(
        self,
        K: sp.spmatrix,
        B: sp.csr_matrix,
        gaps: np.ndarray,
        preconditioner: str | None = None,
        rtol: float = 1e-12,
        max_newton: int = 30,
    ):
        import time

        t0 = time.perf_counter()
        self.K = sp.csr_matrix(K)
        self.B = sp.csr_matrix(B)
        self.gaps = np.asarray(gaps, dtype=float)
        # Jacobi by default: with dt ~ h, K = a M + S is spectrally close to a M and CG
        # needs a mesh-independent number of iterations (AMG was 4x slower per step here)
        kind = preconditioner or "jacobi"
        self.precond = Preconditioner(self.K, kind)
        self.name = f"cg+{kind}"
        self.rtol = rtol
        self.max_newton = max_newton
        self.c = float(np.mean(self.K.diagonal()))
        self.active = np.zeros(self.B.shape[0], dtype=bool)
        self.U_prev = np.zeros(self.K.shape[0])
        self.gap_scale = max(float(np.max(np.abs(self.gaps))) if self.gaps.size else 0.0, 1e-300)
        self.cg_iterations = 0
        self.timings = {"factorization": time.perf_counter() - t0, "condensation": 0.0}
        self.timings["bare_spmv"] = _best_time(lambda x: self.K @ x, self.K.shape[0])
        self.factor_bytes = 0

    def solve(self, b: np.ndarray, gaps: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, StepInfo]:
        A = self.active.copy()
        B, g = self.B, (self.gaps if gaps is None else gaps)
        seen = set()
        for it in range(1, self.max_newton + 1):  # noqa: B007 (it is reported after the loop)
            BA = B[A]

            def project(x, BA=BA):
                return x - BA.T @ (BA @ x) if BA.shape[0] else x

            up = BA.T @ g[A] if BA.shape[0] else np.zeros_like(b)
            w, n_cg = projected_cg(self.K, b - self.K @ up, self.U_prev - up, project, self.precond, self.rtol)
            self.cg_iterations += n_cg
            U = up + w
            lam = np.zeros(g.size)
            if A.any():
                lam[A] = BA @ (self.K @ U - b)
            gap = g - B @ U
            A_new = (-lam - self.c * gap) > 0
            if np.array_equal(A_new, A):
                break
            key = A_new.tobytes()
            if key in seen:
                raise RuntimeError("active-set iteration cycles; reduce the time step or use a direct backend")
            seen.add(key)
            A = A_new
        else:
            raise RuntimeError(f"active-set iteration did not converge in {self.max_newton} iterations")
        self.active = A
        self.U_prev = U
        gap_scale = max(self.gap_scale, float(np.max(np.abs(gap))) if gap.size else 0.0)
        res = complementarity_residual(-lam, gap, 1.0 / self.c, gap_scale) if g.size else 0.0
        return U, lam, StepInfo(it, False, res, A)


def make_stepper(
    K: sp.spmatrix,
    B: sp.csr_matrix,
    gaps: np.ndarray,
    backend: str = "auto",
    dim: int = 3,
    memory_budget: float | None = None,
):
    """The contact stepper for ``backend`` (``auto`` chooses by estimated factor size)."""
    from ..errors import InputError
    from ..linalg.backends import BACKENDS

    if backend not in BACKENDS:
        raise InputError(f"unknown linear solver backend {backend!r}; allowed: {', '.join(BACKENDS)}")
    if backend == "auto":
        backend = choose_backend(K.shape[0], dim, memory_budget)
    if backend == "cg":
        return IterativeContactStepper(K, B, gaps)
    return ContactStepper(K, B, gaps, backend=backend)
