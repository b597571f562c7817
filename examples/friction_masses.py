"""The mass variants with Coulomb friction (issue 23, item 5): the tables of docs/friction.md.

Run from the repository root: ``python3 examples/friction_masses.py [--quick]``.

The oblique impact: an elastic block 1 x 0.25 (E = 100, nu = 0.3, rho = 1, plane strain),
0.021 above the rigid plane y = 0, moving at (vt, -0.5) with vt = 0.3, Coulomb mu = 0.5
(part of the contact sticks, part slips), levels n = 1, 2, 4 (8n x 2n quads, dt = 0.002/n,
T = 0.12: one impact, the block leaves the plane at about t = 0.09).  Prints, for every mass
variant and for CN and BE:

* the per-step problem on the finest level: cond(W_nn), cond(W_tt) of the Delassus matrix
  W = H K^-1 H^T on all contact nodes in their frames, and the coupling number
  kappa = |W_nn^-1/2 W_nt W_tt^-1/2|_2 (mu kappa < 1 makes the Newton matrix of a sliding
  step diagonally dominant in the frame's scaling; the larger kappa, the sooner large mu
  loses uniqueness);
* the oscillation index of the normal and of the tangential contact force (1: one
  monotone rise and fall; docs/verification.md);
* CN: the largest energy rise above E^0 (relative), the number of steps whose frictional
  work is positive (the slip reversing under an averaged force) and their largest value
  relative to the total dissipation; BE: the largest per-step frictional work (<= 0);
* the self-convergence of the tangential impulse and of the final tangential velocity of
  the centre of mass: |q(n) - q(4)| for n = 1, 2 (differences to the finest level).
"""

from __future__ import annotations

import sys

import numpy as np
import scipy.sparse.linalg as spla

from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.model.mass import MASS_VARIANTS
from signorini.dynamics.model.problem import Problem, discretize
from signorini.dynamics.observe.diagnostics import oscillation_index
from signorini.dynamics.observe.observers import CentreOfMassRecorder
from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import rectangle

MU, VT, VN, GAP = 0.5, 0.3, 0.5, 0.021


def oblique(n: int) -> Problem:
    return Problem(
        mesh=rectangle(8 * n, 2 * n, 1.0, 0.25),
        material=IsotropicElastic.from_young(100.0, 0.3, 1.0),
        contact_tag="ymin",
        obstacle=PlaneObstacle([0.0, -GAP], [0.0, 1.0]),
        v0=[VT, -VN],
        friction=f"coulomb:{MU}",
    )


def delassus_numbers(n: int, mass: str, scheme: str) -> tuple[float, float, float]:
    """cond(W_nn), cond(W_tt), kappa of the step operator of ``scheme`` (CN: 4/dt^2 M + S, BE: 1/dt^2 M + S)."""
    disc = discretize(oblique(n), mass)
    dt = 0.002 / n
    c = 4.0 if scheme == "cn" else 1.0
    K = (c / dt**2 * disc.M + disc.S).tocsc()
    H = disc.contact.frame_matrix(disc.space.n_dofs)
    W = H @ spla.splu(K).solve(H.T.toarray())
    W = 0.5 * (W + W.T)
    Wnn, Wtt, Wnt = W[0::2, 0::2], W[1::2, 1::2], W[0::2, 1::2]

    def inv_sqrt(A):
        w, V = np.linalg.eigh(A)
        return V @ np.diag(w**-0.5) @ V.T

    kappa = float(np.linalg.norm(inv_sqrt(Wnn) @ Wnt @ inv_sqrt(Wtt), 2))
    return float(np.linalg.cond(Wnn)), float(np.linalg.cond(Wtt)), kappa


def one_run(n: int, mass: str, scheme: str):
    com = CentreOfMassRecorder([1.0, 0.0])
    H = simulate(oblique(n), scheme, dt=0.002 / n, T=0.12, mass=mass, observers=[com])
    return H, com


COLUMNS = (
    "mass", "scheme", "status", "cond W_nn", "cond W_tt", "kappa", "osc. normal", "osc. tangential",
    "energy rise / E0", "frictional work / E0", "steps with work > 0", "max step work / E0", "Newton it./step",
    "impulse_t diffs", "v_t diffs",
)  # fmt: skip


def row(mass: str, scheme: str, levels=(1, 2, 4)) -> dict:
    """The measurements of one mass variant and scheme (see the module docstring)."""
    runs = {}
    for n in levels:
        try:
            runs[n] = one_run(n, mass, scheme)
        except Exception as exc:  # noqa: BLE001 (a refusal is a result of the table)
            return {"mass": mass, "scheme": scheme, "status": f"refused: {str(exc)[:80]}"}
    H, _ = runs[levels[-1]]
    cnn, ctt, kappa = delassus_numbers(levels[-1], mass, scheme)
    E0 = abs(H.energy[0])
    work = np.diff(H.friction_work)
    positive = work > 1e-14 * E0
    imp_t = {n: float(-r[0].contact_force[:, 0].sum() * 0.002 / n) for n, r in runs.items()}
    v_t = {n: float(r[1].velocity[-1]) for n, r in runs.items()}
    return {
        "mass": mass,
        "scheme": scheme,
        "status": H.status,
        "cond W_nn": cnn,
        "cond W_tt": ctt,
        "kappa": kappa,
        "osc. normal": oscillation_index(None, H.contact_force[:, 1]),
        "osc. tangential": oscillation_index(None, H.contact_force[:, 0]),
        "energy rise / E0": float(np.max(H.energy - H.energy[0]) / E0),
        "frictional work / E0": float(H.friction_work[-1] / E0),
        "steps with work > 0": int(positive.sum()),
        "max step work / E0": float(work.max() / E0),
        "Newton it./step": H.counters["friction_iterations"] / max(int((H.active > 0).sum()), 1),
        "impulse_t diffs": [abs(imp_t[n] - imp_t[levels[-1]]) for n in levels[:-1]],
        "v_t diffs": [abs(v_t[n] - v_t[levels[-1]]) for n in levels[:-1]],
    }


def _cell(v) -> str:
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, list):
        return ", ".join(f"{x:.2e}" for x in v)
    return str(v)


def main(levels=(1, 2, 4)) -> list[dict]:
    print(f"oblique impact, Coulomb mu = {MU}, vt = {VT}, vn = {VN}; levels n = {levels}\n")
    print("| " + " | ".join(COLUMNS) + " |")
    print("|---" * len(COLUMNS) + "|")
    rows = []
    for mass in MASS_VARIANTS.names(aliases=False):
        for scheme in ("cn", "be"):
            r = row(mass, scheme, levels)
            rows.append(r)
            print("| " + " | ".join(_cell(r.get(c, "")) for c in COLUMNS) + " |")
    return rows


if __name__ == "__main__":
    main((1, 2) if "--quick" in sys.argv else (1, 2, 4))
