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
strain and velocity are piecewise constant with moving jumps): the midpoints of equal sub-intervals of the
reference cell, where the element's own shape functions give u_h, v_h and du_h/dx (``line`` or ``line3``).
"""

from __future__ import annotations

import numpy as np

from ..dynamics.model.problem import Problem
from ..dynamics.observe.history import History
from ..fem.elements import shape_functions
from .exact import ExactBar1D

#: sample values per block of time levels in :func:`errors_1d` (bounded memory)
ERROR_BLOCK = 2_000_000


def errors_1d(history: History, problem: Problem, exact: ExactBar1D, samples: int = 8) -> dict[str, float]:
    """Relative errors of a 1D run that stored snapshots at every step."""
    snaps = history.snapshots
    if not snaps or snaps["t"].size != history.t.size:
        raise ValueError("errors_1d needs simulate(..., snapshot_every=1)")
    mesh = problem.mesh
    frac = (np.arange(samples) + 0.5) / samples
    N, dN = shape_functions(mesh.cell_type, frac[:, None])  # (samples, nv), (samples, nv, 1)
    cells = mesh.cells
    xc = mesh.points[cells, 0]  # (cells, nv)
    J = xc @ dN[:, :, 0].T  # dx/dxi (cells, samples)
    xs = (xc @ N.T).ravel()
    wts = (np.abs(J) / samples).ravel()
    t = history.t[1:]
    dt = history.t[1] - history.t[0]
    U = snaps["u"][1:]
    Vh = snaps["v"][1:]

    def at(F: np.ndarray, shapes: np.ndarray) -> np.ndarray:
        """The levels' fields F (levels, nodes) at the sample points: (levels, cells * samples)."""
        return (F[:, cells] @ shapes.T).reshape(F.shape[0], -1)

    def l2x(f):
        return (f**2) @ wts

    # time levels in blocks of about ERROR_BLOCK sample values: the same sums, in bounded
    # memory (all levels at once held ~10 arrays of steps x samples x cells: 4.8 GB at n = 1000)
    sums = dict.fromkeys(("du", "due", "u", "ue", "v", "ve"), 0.0)
    v_err_max = v_ref_max = 0.0
    rows = max(1, ERROR_BLOCK // max(xs.size, 1))
    for k in range(0, t.size, rows):
        sl = slice(k, k + rows)
        Uk, Vk = U[sl], Vh[sl]
        uh, vh = at(Uk, N), at(Vk, N)
        duh = at(Uk, dN[:, :, 0]) / J.ravel()
        T_, X_ = np.meshgrid(t[sl], xs, indexing="ij")
        ue, due, ve = exact.u(X_, T_), exact.u_x(X_, T_), exact.u_t(X_, T_)
        ev, rv = l2x(vh - ve), l2x(ve)
        sums["du"] += l2x(duh - due).sum()
        sums["due"] += l2x(due).sum()
        sums["u"] += l2x(uh - ue).sum()
        sums["ue"] += l2x(ue).sum()
        sums["v"] += ev.sum()
        sums["ve"] += rv.sum()
        v_err_max, v_ref_max = max(v_err_max, float(ev.max())), max(v_ref_max, float(rv.max()))

    def rel(err: str, ref: str) -> float:
        return float(np.sqrt(sums[err] / sums[ref]))

    out = {
        "u_H1": rel("du", "due"),
        "u_L2": rel("u", "ue"),
        "v_L2": rel("v", "ve"),
        "v_Linf": float(np.sqrt(v_err_max / v_ref_max)),
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
