"""Anderson acceleration of Newton's iterations with a kept operator (the scheme's own or a kept tangent).

With an operator A that is not the step's Jacobian, Newton's method is a fixed-point iteration

    X_{k+1} = X_k + d_k,   d_k = A^{-1} (-r(X_k) + B^T lambda_{k+1})   (the contact problem of the step),

which contracts at the rate of |I - A^{-1} J| (measured: 0.08-0.1 per iteration on ``hertz3d`` with Neo-Hookean,
where the massless contact skin's strain is a tenth).  Anderson's mixing (Walker and Ni 2011, type II) with the
last m differences DX_j = X_{j+1} - X_j and DF_j = d_{j+1} - d_j takes

    gamma = argmin |d_k - DF gamma|_2,   X_{k+1} = X_k + d_k - (DX + DF) gamma,   lambda_{k+1} = lambda - DL gamma

(DL_j the differences of the solves' multipliers): on a linear map it is GMRES preconditioned by A, so that the
iterations cost one solve each as before and contract as a Krylov method does.  Each X_j satisfies the rows held
at their bound, B_A X_j = bound_A, and the weights of the combination sum to one, so the accelerated iterate does
too; it is used only while the active set is the same over the history and no friction acts (the caller checks
the free rows and the multipliers' signs, :meth:`Anderson.mix`)."""

from __future__ import annotations

import numpy as np

#: the most differences kept (m); measured in docs/finite_strain.md
DEPTH = 5
#: the least-squares problem's cut-off: singular values of DF below this times the largest are dropped (``lstsq``'s
#: ``rcond``; nearly dependent differences, as the iterates converge)
RCOND = 1e-10


class Anderson:
    """The history of one step's iterates X_j, directions d_j and multipliers lambda_j (the module docstring).

    ``free`` (n_free,) the dofs the least-squares problem measures (the Dirichlet dofs' directions are prescribed).
    """

    def __init__(self, free: np.ndarray, depth: int = DEPTH):
        self.free, self.depth = free, depth
        self._last: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None  # (X, d, lambda, active)
        self._dX: list[np.ndarray] = []
        self._dF: list[np.ndarray] = []
        self._dL: list[np.ndarray] = []
        #: the accelerated iterates taken (summary.json counters.accelerated_iterations)
        self.taken = 0

    def reset(self, keep_last: bool = False) -> None:
        """Forget the history (the operator changed, the active set changed); ``keep_last``: keep the last point
        recorded (an accelerated iterate that did not lower the residual: the plain one is taken from there)."""
        if not keep_last:
            self._last = None
        self._dX, self._dF, self._dL = [], [], []

    def mix(
        self, X: np.ndarray, d: np.ndarray, lam: np.ndarray, agree=lambda x: x
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """Record (X_k, d_k, lambda_{k+1}) and return the accelerated (d, lambda) (the step from X_k and the
        multiplier of the new iterate), or None when the history is empty or was just reset by a change of the
        active set.  ``agree``: the weights gamma taken on rank 0's values (several ranks)."""
        active = lam < 0.0
        last = self._last
        self._last = (X, d, lam, active)
        if last is None:
            return None
        if not agree(bool(np.array_equal(active, last[3]))):  # on rank 0's values: every rank mixes, or none
            self.reset(keep_last=True)
            return None
        self._dX.append(X - last[0])
        self._dF.append(d - last[1])
        self._dL.append(lam - last[2])
        if len(self._dX) > self.depth:
            del self._dX[0], self._dF[0], self._dL[0]
        f = self.free
        DF = np.stack([c[f] for c in self._dF], axis=1)
        gamma = agree(np.linalg.lstsq(DF, d[f], rcond=RCOND)[0])
        if not np.all(np.isfinite(gamma)):
            self.reset()
            return None
        step = d - sum(g * (a + b) for g, a, b in zip(gamma, self._dX, self._dF, strict=True))
        mult = lam - sum(g * c for g, c in zip(gamma, self._dL, strict=True))
        return step, mult
