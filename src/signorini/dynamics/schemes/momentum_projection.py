"""The momentum projection of the energy-momentum scheme with finite strain (issue 41, docs/finite_strain.md).

What the scheme's balance leaks.  With the contact nodes massless (the mass redistribution) the rows with
mass are balanced with the discrete gradient f_alg(U^n, U^{n+1}) and the massless rows at t_{n+1} with
f(U^{n+1}); the scheme's contact impulse is dt lambda^{n+1} on rows of nodes with mass and
dt (lambda^n + lambda^{n+1})/2 on those of massless nodes, each level's multipliers through its own rows
(:mod:`~signorini.dynamics.schemes.energy_momentum`).  Over a step a group of bodies' momenta then change by

    dP = dt [sum_a (f_ext)_a - sum_a h_a],     dL = dt [sum_a x_mid,a x (f_ext)_a - sum_a x_mid,a x h_a]

where dt f_ext is the impulse from outside (the rigid obstacles' share of the contact impulse, friction
against them, the loads), x_mid = X + (U^n + U^{n+1})/2, and

    h = ((f^n + f^{n+1})/2 - f_alg - R0/2) on the massless rows, 0 on the others, minus the pairs' share of the
        contact impulse / dt

(the massless rows' balances at t_n and t_{n+1} turn sum f_alg there into the mean of the contact forces
plus that difference; R0, only at t = 0, is how far the massless rows start out of equilibrium, an
imbalance and not a force).  Gonzalez's discrete gradient has sum_a f_alg,a = 0 and
sum_a x_mid,a x f_alg,a = 0 (objective laws; a linear cell's S U_mid keeps the first only: its own
non-objectivity, not corrected here).  The massless part of h is third order in dU (dU_l . h_l is the
numerical term of the energy identity): O(dt^2) over a run.  The pairs' part has no resultant; its moment
is that of the pair's forces, -lambda n_m at the slave node and N_j lambda n_m at the master nodes, with the
midpoint's arms.  It does not vanish with dt: a slave node kept on its facet while its projection is up
to 5% past the facet's end (``KEEP_FACET``, docs/finite_strain.md) is pushed along a line the master's
force, at the clamped projection, is not on (measured: 1e-3 of the angular momentum over the sliding
blocks' contact at every dt from 4e-4 to 5e-5; an adversarial review, 2026-12-05).  The projection gives
it back too, so that contact between bodies never spins them.

The groups.  A group is a set of bodies (connected components of the mesh) joined by a contact pair row
that acts at t_n or t_{n+1}; a body alone is its own group.  Each group gets its own correction from its own
h, so that bodies apart do not trade momentum.

The projection.  After the step the velocities of a group's nodes with mass get the rigid field
dV = a + w x (x - c) (x = X + U^{n+1}, c the group's centre of mass) closest to zero in M's norm that gives
the momenta back what h took:

    1^T M dV = dt sum_a h_a,     sum_a x_a x (M dV)_a = dt sum_a x_mid,a x h_a

(d + 1 unknowns in 2D, 6 in 3D).  About the centre of mass a rotation has no linear momentum, so the
translation is exact whatever the masses and the rotation is solved in least squares (exact unless the
masses are collinear).  Then the linear and the angular momentum change only by the impulses from outside.
It is the orthogonal projection of the projection methods of geometric integration (Hairer, Lubich, Wanner,
Geometric Numerical Integration, section IV.4), with M's metric, onto the step's momenta.  The kinetic
energy it changes, (V + dV/2) . M dV, is a term of the step's energy identity (its numerical part).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.csgraph  # noqa: F401  (sp.csgraph)


def applies(scheme, ctx) -> bool:
    """Whether a run's steps get the projection: a scheme that declares it (``momentum_projection``), finite
    strain, solver option ``momentum_projection`` (on by default), bodies without a prescribed motion (whose
    reactions change the momenta anyway)."""
    wanted = ctx.solver_options.get("momentum_projection", True)
    return bool(scheme.momentum_projection and ctx.elastic.finite and wanted and not ctx.has_fixed)


def rigid_fields(x: np.ndarray, keep: np.ndarray, centre: np.ndarray | None = None) -> np.ndarray:
    """(N d, k) the rigid velocity fields at the points x (N, d), zero on the dofs not in ``keep`` (bool (N d,)):
    the d translations, then the rotations w x (x - c) about ``centre`` (default: the points' mean; 1 in 2D,
    3 in 3D)."""
    n, d = x.shape
    r = x - (x.mean(axis=0) if centre is None else centre)
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
    """(k,) sum_a p_a and sum_a x_a x p_a (:func:`moment`) of nodal forces or momenta
    p (N d,) at x (N, d)."""
    return np.concatenate([p.reshape(-1, x.shape[1]).sum(axis=0), moment(x, p)])


def groups(labels: np.ndarray, joined: np.ndarray) -> list[np.ndarray]:
    """The groups of bodies (module docstring): ``labels`` (N,) each node's body, ``joined`` (k, 2) pairs of
    bodies a pair row joins; returns each group's nodes (bool (N,))."""
    n_bodies = int(labels.max(initial=0)) + 1
    if not len(joined):
        return [labels == b for b in range(n_bodies)]
    a, b = np.asarray(joined).T
    graph = sp.coo_matrix((np.ones(a.size), (a, b)), shape=(n_bodies, n_bodies))
    _, group_of = sp.csgraph.connected_components(graph, directed=False)
    node_group = group_of[labels]
    return [node_group == g for g in range(int(group_of.max()) + 1)]


def velocity_correction(
    M,
    X: np.ndarray,
    U0: np.ndarray,
    U1: np.ndarray,
    h: np.ndarray,
    dt: float,
    massive: np.ndarray,
    nodes: list[np.ndarray] | None = None,
) -> np.ndarray:
    """dV (N d,): per group of ``nodes`` (bool (N,) each; default one group), the rigid field on its dofs with
    mass (``massive``, bool (N d,)) closest to 0 in M's norm with momenta(x1, M dV) = dt momenta(x_mid, h) over
    the group (module docstring); M (N d, N d) the mass matrix, X (N, d) the reference points, U0, U1 (N d,)
    the step's displacements, h (N d,) what its balance adds to f_alg."""
    d = X.shape[1]
    x1 = X + U1.reshape(-1, d)
    x_mid = X + 0.5 * (U0 + U1).reshape(-1, d)
    m = np.asarray(M @ np.ones(M.shape[0])).reshape(-1, d)[:, 0]  # each node's mass (M 1: row sums)
    dV = np.zeros(U1.size)
    for group in [np.ones(X.shape[0], dtype=bool)] if nodes is None else nodes:
        keep = massive & np.repeat(group, d)
        mass = float(m[group].sum())
        if not keep.any() or mass <= 0.0:
            continue
        centre = (m[group] @ x1[group]) / mass
        G = rigid_fields(x1, keep, centre)
        MG = M @ G
        A = np.column_stack([momenta(x1, MG[:, j]) for j in range(G.shape[1])])
        b = dt * momenta(x_mid[group], h.reshape(-1, d)[group].ravel())  # what h took from the group's momenta
        a = np.zeros(G.shape[1])
        a[:d] = b[:d] / mass  # the translation, exact: rotations about the centre of mass carry no momentum
        if G.shape[1] > d:
            rhs = b[d:] - A[d:, :d] @ a[:d]
            a[d:] = np.linalg.lstsq(A[d:, d:], rhs, rcond=1e-12)[0]  # singular only for collinear masses
        dV += G @ a
    return dV


def moment(x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """sum_a x_a x p_a of nodal vectors p (N d,) at the points x (N, d): (3,) in 3D, (1,) (z) in 2D, (0,) in 1D."""
    d = x.shape[1]
    if d == 1:
        return np.zeros(0)
    p = p.reshape(-1, d)
    if d == 2:
        return np.array([float(x[:, 0] @ p[:, 1] - x[:, 1] @ p[:, 0])])
    return np.cross(x, p).sum(axis=0)
