"""What a mass variant does to the rigid-body properties of the body.

For every displacement component k, the moments of the variant's mass
``Q^k_pq = (e_k (x) p)^T M (e_k (x) q)`` for p, q in {1, x_1, ..., x_d} are compared
with those of the consistent mass, ``rho int_Omega p q``:

* ``mass_ratio`` = m / m_ref, m = Q_11 (total mass kept / consistent total mass);
* ``centre_shift`` = |c - c_ref| / D, c_i = Q_1i / m, D = the diagonal of the body's
  bounding box (a relative length);
* ``inertia_change`` = ||I - I_ref||_F / ||I_ref||_F, with the inertia tensor about
  the centre of mass I = tr(J) Id - J, with the second central moments
  J_ij = Q_{x_i x_j} - m c_i c_j; in 1D I = J.

Each figure is the worst over the components (a variant may treat the normal and
tangential components differently).  A variant *changes the physics* (a warning in
the run's summary) when |mass_ratio - 1| > :data:`MASS_TOLERANCE`, centre_shift >
:data:`CENTRE_TOLERANCE` or inertia_change > :data:`INERTIA_TOLERANCE`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ...fem.assembly import _element_data, part_value
from ...fem.dofmap import component
from ...fem.elements import reference_element
from ...fem.mesh import Mesh, over_blocks

#: relative change of the total mass above which a run warns
MASS_TOLERANCE = 1e-3
#: centre-of-mass shift, relative to the body's size, above which a run warns
CENTRE_TOLERANCE = 1e-3
#: relative change of the inertia tensor above which a run warns
INERTIA_TOLERANCE = 1e-2


def _monomials(mesh: Mesh) -> np.ndarray:
    """(n_nodes, d+1) nodal values of 1, x_1, ..., x_d, about the bounding box's centre."""
    x = mesh.points - 0.5 * (mesh.points.min(axis=0) + mesh.points.max(axis=0))
    return np.hstack([np.ones((mesh.n_nodes, 1)), x])


def consistent_moments(mesh: Mesh, rho: float | np.ndarray, chunk: int = 65536) -> np.ndarray:
    """(d+1, d+1) moments P^T M P of the consistent mass, from the element mass matrices.

    M_e = rho sum_q w_q |det J| N_a N_b (the matrices that assemble M; one shared matrix
    when the cells are translates of one another), Q = sum_e P_e^T M_e P_e over chunks of
    cells: no global matrix and no per-cell geometry beyond a chunk.  ``rho``: a number or
    one density per cell (n_cells,).
    """
    return over_blocks(mesh, lambda part, cut: _moments_one_type(part, part_value(rho, cut), chunk), sum)


def _moments_one_type(mesh: Mesh, rho: float | np.ndarray, chunk: int) -> np.ndarray:
    """:func:`consistent_moments` of a one-type mesh."""
    ref = reference_element(mesh.cell_type)
    wdet, _ = _element_data(mesh)
    Me = np.einsum("eq,qa,qb->eab", wdet, ref.N, ref.N)
    if np.ndim(rho) == 0:
        Me = rho * Me
    else:
        Me = np.broadcast_to(Me, (mesh.n_cells,) + Me.shape[1:])
    P = _monomials(mesh)
    Q = np.zeros((P.shape[1], P.shape[1]))
    for s in range(0, mesh.n_cells, chunk):
        Pc = P[mesh.cells[s : s + chunk]]  # (m, nv, d+1)
        Mc = Me if Me.shape[0] == 1 else Me[s : s + chunk]
        if np.ndim(rho):
            Mc = np.asarray(rho)[s : s + chunk, None, None] * Mc
        Y = np.matmul(Mc, Pc)  # (m, nv, d+1), M_e broadcast when shared
        Q += Pc.reshape(-1, Q.shape[0]).T @ Y.reshape(-1, Q.shape[0])
    return Q


def moments(M: sp.spmatrix, mesh: Mesh, P: np.ndarray | None = None) -> np.ndarray:
    """(d, d+1, d+1) moments Q^k of the vector mass ``M`` (node-major dofs), one per component; ``P`` (n_nodes,
    d+1) the nodal monomials (default the mesh's, :func:`_monomials`).

    ``M`` must not couple different components (true of every registered variant).
    """
    d = mesh.dim
    P = _monomials(mesh) if P is None else P
    # every registered variant is block diagonal in the components (no entry couples
    # component k of a node with component l != k of another): one product with the
    # monomials repeated on every component gives component k of Y = M_k P for all k at once
    Y = M @ np.repeat(P, d, axis=0)
    return np.stack([P.T @ Y[component(k, d)] for k in range(d)])


def rigid_body_properties(Q: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, centre (d,), inertia tensor about the centre (d, d)) from moments Q (d+1, d+1)."""
    m = float(Q[0, 0])
    d = Q.shape[0] - 1
    if m == 0.0:
        return 0.0, np.zeros(d), np.zeros((d, d))
    c = Q[0, 1:] / m
    J = Q[1:, 1:] - m * np.outer(c, c)
    inertia = J if d == 1 else np.trace(J) * np.eye(d) - J
    return m, c, inertia


def mass_effect(M: sp.spmatrix, mesh: Mesh, rho: float) -> dict:
    """The variant's effect on mass, centre of mass and inertia, against the consistent mass.

    Parameters
    ----------
    M : (d n, d n) the variant's vector mass matrix.
    mesh, rho : the body and its density [mass / length^d].

    Returns
    -------
    dict with ``mass_ratio``, ``centre_shift``, ``inertia_change`` (worst component),
    ``mass``, ``consistent_mass`` [mass] and ``changes_physics`` (bool).
    """
    return _effect(moments(M, mesh), mesh, rho)


def body_mass_effect(M, mesh: Mesh, nodes: np.ndarray, body: Mesh, rho: float | np.ndarray) -> dict:
    """:func:`mass_effect` of one body of ``mesh`` (``nodes`` (m,) sorted, ``body`` the mesh of that body alone,
    ``rho`` on its cells) from the whole mesh's vector mass ``M``, by products only (a distributed M, rows per
    rank, whose products gather over the ranks): M does not couple bodies, so M applied to the body's monomials
    (zero on the other bodies) is its own block's product."""
    P = np.zeros((mesh.n_nodes, mesh.dim + 1))
    P[nodes] = _monomials(body)
    return _effect(moments(M, mesh, P), body, rho)


def _effect(Qs: np.ndarray, mesh: Mesh, rho: float | np.ndarray) -> dict:
    """:func:`mass_effect` from the variant's moments ``Qs`` (d, d+1, d+1) of ``mesh``."""
    m0, c0, I0 = rigid_body_properties(consistent_moments(mesh, rho))
    size = float(np.linalg.norm(np.ptp(mesh.points, axis=0))) or 1.0
    scale = float(np.linalg.norm(I0)) or 1.0
    worst = {"mass_ratio": 1.0, "centre_shift": 0.0, "inertia_change": 0.0}
    kept = m0
    for Q in Qs:
        m, c, inertia = rigid_body_properties(Q)
        ratio = m / m0 if m0 else 1.0
        if abs(ratio - 1.0) >= abs(worst["mass_ratio"] - 1.0):
            worst["mass_ratio"], kept = ratio, m
        worst["centre_shift"] = max(worst["centre_shift"], float(np.linalg.norm(c - c0)) / size)
        worst["inertia_change"] = max(worst["inertia_change"], float(np.linalg.norm(inertia - I0)) / scale)
    worst = {k: float(v) for k, v in worst.items()}
    return {**worst, "mass": float(kept), "consistent_mass": float(m0), "changes_physics": bool(effect_warning(worst))}


def effect_warning(effect: dict) -> str | None:
    """A one-line warning when the effect exceeds the tolerances, else None."""
    parts = []
    if abs(effect["mass_ratio"] - 1.0) > MASS_TOLERANCE:
        parts.append(f"keeps {100 * effect['mass_ratio']:.4g}% of the body's mass")
    if effect["centre_shift"] > CENTRE_TOLERANCE:
        parts.append(f"moves the centre of mass by {100 * effect['centre_shift']:.3g}% of the body's size")
    if effect["inertia_change"] > INERTIA_TOLERANCE:
        parts.append(f"changes the inertia tensor by {100 * effect['inertia_change']:.3g}%")
    return "; ".join(parts) if parts else None
