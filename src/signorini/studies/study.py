"""Error norms against exact (1D) solutions and observed convergence rates.

Relative norms (spec 0.6 and 7), with time integrals as rectangle sums over the time
levels t_1 .. t_N (as in GetFEM's 1D demo):

``u_H1``       |u_h - u|_{L2(0,T; H1_0)} / |u|_{L2(0,T; H1_0)}  (H1 seminorm)
``u_L2``       |u_h - u|_{L2(0,T; L2)} / |u|_{L2(0,T; L2)}
``v_L2``       |v_h - v|_{L2(0,T; L2)} / |v|_{L2(0,T; L2)}
``v_Linf``     max_n |v_h - v|_{L2} / max_n |v|_{L2}
``stress``     |lambda_h / w - sigma_n|_{L2(0,T)} / |sigma_n|_{L2(0,T)} at the contact point
``energy_L2``  |E_h - E|_{L2(0,T)} / (max E sqrt(T));   ``energy_Linf`` max |E_h - E| / max E
               (E(t) is constant unless the clamp or the obstacle moves)

Space integrals of the 1D errors use ``samples`` points per element (the exact
strain and velocity are piecewise constant with moving jumps).
"""

from __future__ import annotations

import numpy as np

from ..dynamics.history import History
from ..dynamics.problem import Problem
from ..studies.exact import ExactBar1D


def errors_1d(history: History, problem: Problem, exact: ExactBar1D, samples: int = 8) -> dict[str, float]:
    """Relative errors of a 1D run that stored snapshots at every step."""
    snaps = history.snapshots
    if not snaps or snaps["t"].size != history.t.size:
        raise ValueError("errors_1d needs simulate(..., snapshot_every=1)")
    x = problem.mesh.points[:, 0]
    h = np.diff(x)
    # sample points: midpoints of `samples` sub-intervals of every element
    frac = (np.arange(samples) + 0.5) / samples
    xs = (x[:-1, None] + h[:, None] * frac[None, :]).ravel()
    wts = np.repeat(h / samples, samples)
    t = history.t[1:]
    dt = history.t[1] - history.t[0]
    U = snaps["u"][1:]
    Vh = snaps["v"][1:]
    # FE fields at the sample points
    uh = U[:, :-1, None] * (1 - frac) + U[:, 1:, None] * frac
    uh = uh.reshape(t.size, -1)
    duh = np.repeat((np.diff(U, axis=1) / h), samples, axis=1)
    vh = (Vh[:, :-1, None] * (1 - frac) + Vh[:, 1:, None] * frac).reshape(t.size, -1)
    T_, X_ = np.meshgrid(t, xs, indexing="ij")
    ue, due, ve = exact.u(X_, T_), exact.u_x(X_, T_), exact.u_t(X_, T_)

    def l2x(f):
        return (f**2) @ wts

    def rel_l2t(err, ref):
        return float(np.sqrt(err.sum() / ref.sum()))

    out = {
        "u_H1": rel_l2t(l2x(duh - due), l2x(due)),
        "u_L2": rel_l2t(l2x(uh - ue), l2x(ue)),
        "v_L2": rel_l2t(l2x(vh - ve), l2x(ve)),
        "v_Linf": float(np.sqrt(l2x(vh - ve).max() / l2x(ve).max())),
    }
    sig_h = history.lam[1:, 0] / history.weights[0]
    sig = exact.contact_stress(t)
    out["stress"] = float(np.sqrt(np.sum((sig_h - sig) ** 2) / np.sum(sig**2)))
    E = exact.energy(t)  # constant (= energy0) unless the clamp or the obstacle moves
    scale = float(np.max(np.abs(E)))
    dE = history.energy[1:] - E
    out["energy_L2"] = float(np.sqrt(np.sum(dE**2) * dt / (t[-1])) / scale)
    out["energy_Linf"] = float(np.max(np.abs(dE)) / scale)
    return out


def observed_rates(errors: list[float], sizes: list[float]) -> list[float]:
    """Rates log(e_k / e_{k+1}) / log(h_k / h_{k+1}) between successive levels.

    A rate is undefined (nan) when one of its two errors is not a positive finite number
    (a zero error, a missing value); reports print such values as "n/a".
    """
    e, h = np.asarray(errors, float), np.asarray(sizes, float)
    ok = np.isfinite(e) & (e > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.log(e[:-1] / e[1:]) / np.log(h[:-1] / h[1:])
    return [float(x) if (a and b) else float("nan") for x, a, b in zip(r, ok[:-1], ok[1:], strict=True)]
