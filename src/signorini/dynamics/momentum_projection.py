"""The momentum projection of the energy-momentum scheme with finite strain (issue 41, docs/finite_strain.md).

What the scheme's balance leaks.  With the contact nodes massless (the mass redistribution) the rows with
mass are balanced with the discrete gradient f_alg(U^n, U^{n+1}) and the massless rows at t_{n+1} with
f(U^{n+1}); the scheme's contact impulse is dt lambda^{n+1} on rows of nodes with mass and
dt (lambda^n + lambda^{n+1})/2 on those of massless nodes, each level's multipliers through its own rows
(:mod:`~signorini.dynamics.schemes.energy_momentum`).  Over a step the bodies' momenta then change by

    dP = dt [sum_a (f_ext)_a - sum_a h_a],     dL = dt [sum_a x_mid,a x (f_ext)_a - sum_a x_mid,a x h_a]

where dt f_ext is the impulse from outside (the rigid obstacles' share of the contact impulse, the loads,
damping), x_mid = X + (U^n + U^{n+1})/2, and

    h = ((f^n + f^{n+1})/2 - f_alg) on the massless rows, 0 on the others, minus the pairs' share of the
        contact impulse / dt

(the massless rows' balances at t_n and t_{n+1} turn sum f_alg there into the mean of the contact forces
plus that difference).  Gonzalez's discrete gradient has sum_a f_alg,a = 0 and sum_a x_mid,a x f_alg,a = 0
(objective laws; a linear cell's S U_mid keeps the first only: its own non-objectivity, not corrected
here).  The massless part of h is third order in dU (the numerical term of the energy identity is
dU_l . h_l); the pairs' part has no resultant, and a moment from the lever arms of their two levels.

The projection.  After the step the velocities of the nodes with mass get the rigid field dV = a + w x (x - c)
(x = X + U^{n+1}) closest to zero in M's norm that gives the momenta back what h took:

    1^T M dV = dt sum_a h_a,     sum_a x_a x (M dV)_a = dt sum_a x_mid,a x h_a

(d + 1 unknowns in 2D, 6 in 3D: a small system with the bodies' rigid mass matrix).  Then the linear
and the angular momentum change only by the impulses of the forces from outside.  It is the orthogonal
projection of the projection methods of geometric integration (Hairer, Lubich, Wanner, Geometric
Numerical Integration, section IV.4), with M's metric, onto the step's momenta.  The kinetic energy it
changes, (V + dV/2) . M dV, is a term of the step's energy identity (its numerical part).
"""

from __future__ import annotations

import numpy as np


def rigid_fields(x: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """(N d, k) the rigid velocity fields at the points x (N, d), zero on the dofs not in ``keep`` (bool (N d,)):
    the d translations, then the rotations w x (x - c) about the points' centre c (1 in 2D, 3 in 3D)."""
    n, d = x.shape
    r = x - x.mean(axis=0)
    fields = []
    for k in range(d):
        e = np.zeros((n, d))
        e[:, k] = 1.0
        fields.append(e)
    if d == 2:
        fields.append(np.column_stack([-r[:, 1], r[:, 0]]))
    elif d == 3:
        for k in range(3):
            w = np.zeros(3)
            w[k] = 1.0
            fields.append(np.cross(w, r))
    G = np.stack([f.ravel() for f in fields], axis=1)
    G[~keep] = 0.0
    return G


def momenta(x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(k,) sum_a p_a and sum_a x_a x p_a (z only in 2D, none in 1D) of nodal forces or momenta p (N d,) at x (N, d)."""
    d = x.shape[1]
    p = p.reshape(-1, d)
    total = p.sum(axis=0)
    if d == 1:
        return total
    if d == 2:
        return np.concatenate([total, [float(x[:, 0] @ p[:, 1] - x[:, 1] @ p[:, 0])]])
    return np.concatenate([total, np.cross(x, p).sum(axis=0)])


def velocity_correction(M, X: np.ndarray, U0: np.ndarray, U1: np.ndarray, h: np.ndarray, dt: float,
                        massive: np.ndarray) -> np.ndarray:  # fmt: skip
    """dV (N d,): the rigid field on the dofs with mass (``massive``, bool) closest to 0 in M's norm with
    momenta(x1, M dV) = dt leak(x_mid, h) (module docstring); M (N d, N d) the mass matrix, X (N, d) the
    reference points, U0, U1 (N d,) the step's displacements, h (N d,) what its balance adds to f_alg."""
    d = X.shape[1]
    x1 = X + U1.reshape(-1, d)
    x_mid = X + 0.5 * (U0 + U1).reshape(-1, d)
    G = rigid_fields(x1, massive)
    MG = M @ G
    A = np.column_stack([momenta(x1, MG[:, j]) for j in range(G.shape[1])])
    b = dt * momenta(x_mid, h)  # what h took from the momenta
    a = np.linalg.lstsq(A, b, rcond=None)[0]  # the rigid mass matrix: singular only for collinear masses
    return G @ a
