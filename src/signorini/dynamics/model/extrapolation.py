"""Affine extrapolation of the contact nodes from the other nodes, on any mesh.

The conserving mass variants remove the inertia of the contact nodes and put it back on
the others.  ``moment-preserving`` writes this as ``M_red = T^T M T`` where T keeps the
values of the non-contact nodes and extrapolates those of the contact nodes,

    (T u)_c = sum_j w_cj u_j,   sum_j w_cj = 1,   sum_j w_cj (x_j - x_c) = 0,

so that T reproduces every affine function: then p^T M_red q = p^T M q for p, q in
{1, x_1, ..., x_d} (total mass, first and second moments exact), M_red is symmetric
positive semi-definite and its kernel is the contact dofs.  The weights of node c are the
minimum-norm solution over a neighbourhood N(c) of non-contact nodes,
w_c = A_c^+ e_1 = A_c^T (A_c A_c^T)^{-1} e_1 with A_c = [1; (x_j - x_c) / h_c]_{j in N(c)}
(the scale h_c = max_j |x_j - x_c| changes the conditioning, not the solution; computed
by the SVD of A_c, accurate to cond(A_c) x machine precision).

**The neighbourhood grows until the fit is well posed** (:func:`neighbourhoods`):

1. the non-contact nodes within two rings of the node graph (the first, historical choice:
   the paper's bar and every node with interior neighbours nearby; within the ring, the
   2(d+1) nearest are tried first, :data:`COMPACT`, which changed the bars' matrices:
   bar2d's by 15% of its largest entry);
2. further rings, up to :data:`MAX_RING`, for nodes on rims, edges and corners of a
   body whose whole skin is in contact;
3. the k nearest non-contact nodes in space (k doubling), for bodies whose interior is
   several rings away.

A neighbourhood is *well posed* when A_c has rank d+1 with condition number at most
:data:`MAX_CONDITION` (ratio of its extreme singular values).
When even all the non-contact nodes do not span d+1 affinely independent points (a
plate one cell thick with its whole skin in contact) no affine extrapolation exists:
:class:`~signorini.errors.InputError` says how many contact nodes, where, and what to do.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ...errors import InputError
from ...fem.mesh import Mesh

#: largest number of node-graph rings searched before the nearest nodes in space
MAX_RING = 6
#: largest condition number of the scaled affine-fit matrix A_c accepted: it bounds the
#: weights (|w|_1 <= 12 on the parts of docs/verification.md).  With 1e3, rim nodes of a
#: cylinder got weights up to 128 and the redistributed mass added elastic modes at 19 Hz
#: below the consistent mass's 106 Hz; with 30 the lowest is 87 Hz (docs/design.md)
MAX_CONDITION = 30.0
#: the limit of a second growth for nodes that cannot meet MAX_CONDITION (reported by
#: ``mass_effect['max_extrapolation_weight']``)
RELAXED_CONDITION = 1e3
#: a neighbourhood first tries the COMPACT (d+1) nearest of its candidates (ties kept):
#: a sparser M = T^T M T (0: every candidate of the ring, the former choice)
COMPACT = 2


def node_graph(mesh: Mesh) -> sp.csr_matrix:
    """(n, n) boolean adjacency of the nodes (two nodes adjacent when they share a cell), diagonal included."""
    rows = np.concatenate([np.repeat(b.cells, b.cells.shape[1], axis=1).ravel() for b in mesh.blocks])
    cols = np.concatenate([np.tile(b.cells, (1, b.cells.shape[1])).ravel() for b in mesh.blocks])
    A = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(mesh.n_nodes, mesh.n_nodes))
    A.data[:] = 1
    return A


def _fit(points: np.ndarray, centres: np.ndarray, cand: np.ndarray, valid: np.ndarray, limit: float):
    """Minimum-norm affine weights and conditioning for padded candidate lists.

    points (n, d); centres (m, d); cand, valid (m, k).  Returns (weights (m, k), ok (m,)).
    """
    m, k = cand.shape
    d = points.shape[1]
    dx = (points[cand] - centres[:, None, :]) * valid[..., None]  # (m, k, d)
    h = np.sqrt((dx**2).sum(axis=2).max(axis=1))
    h[h == 0] = 1.0
    A = np.empty((m, d + 1, k))
    A[:, 0, :] = valid
    A[:, 1:, :] = np.moveaxis(dx / h[:, None, None], 2, 1)
    # minimum-norm solution by the SVD A = U S V^T: w = V S^-1 U^T e_1 (accurate to cond(A) eps,
    # where the normal equations would lose cond(A)^2 eps)
    U, s, Vt = np.linalg.svd(A, full_matrices=False)
    ok = (valid.sum(axis=1) >= d + 1) & (s[:, -1] > s[:, 0] / limit)
    w = np.zeros((m, k))
    if ok.any():
        w[ok] = np.einsum("cik,ci->ck", Vt[ok], U[ok, 0, :] / s[ok])
    return w, ok


def _nearest(points, centres, cand, valid, k):
    """The k nearest of each row's valid candidates, and every candidate as near as the k-th
    (ties kept, so that a symmetric mesh keeps symmetric weights): (cand, valid), padded."""
    dist = np.where(valid, np.sqrt(((points[cand] - centres[:, None, :]) ** 2).sum(axis=2)), np.inf)
    k = min(k, cand.shape[1])
    kth = np.sort(dist, axis=1)[:, k - 1 : k]
    keep = valid & (dist <= kth * (1 + 1e-9))
    order = np.argsort(~keep, axis=1, kind="stable")  # kept candidates first, in their order
    width = max(int(keep.sum(axis=1).max(initial=1)), 1)
    order = order[:, :width]
    return np.take_along_axis(cand, order, axis=1), np.take_along_axis(keep, order, axis=1)


def _padded(R: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray]:
    """The column indices of each row of R, padded: (cand, valid), each (m, kmax)."""
    counts = np.diff(R.indptr)
    kmax = max(int(counts.max(initial=0)), 1)
    pos = np.arange(kmax)[None, :]
    valid = pos < counts[:, None]
    idx = np.where(valid, R.indptr[:-1, None] + np.minimum(pos, np.maximum(counts[:, None] - 1, 0)), 0)
    cand = R.indices[idx] if R.nnz else np.zeros_like(idx)
    return np.where(valid, cand, 0), valid


def _impossible(name: str, mesh: Mesh, nodes: np.ndarray, is_c: np.ndarray) -> InputError:
    e = mesh.first_by_id(nodes)
    label = body_labels(mesh)
    which = ""
    n_free = int(np.count_nonzero(~is_c))
    if label.max(initial=0) > 0:  # several bodies: name the one (its regions), count and box its own nodes
        b = int(label[nodes[e]])
        nodes = nodes[label[nodes] == b]
        e = mesh.first_by_id(nodes)
        in_b = np.zeros(mesh.n_cells, dtype=bool)
        in_b[np.flatnonzero(label[mesh.first_nodes()] == b)] = True
        regions = sorted(t for t, c in mesh.regions.items() if c.size and in_b[c].any())
        which = f" of body {b}" + (f" (regions {', '.join(regions)})" if regions else "")
        n_free = int(np.count_nonzero(~is_c & (label == b)))
    pts = mesh.points[nodes]
    lo, hi = np.round(pts.min(axis=0), 6).tolist(), np.round(pts.max(axis=0), 6).tolist()
    return InputError(
        f"mass {name!r}: {nodes.size} contact node(s){which} in the box {lo} .. {hi} (e.g. node "
        f"{mesh.node_id(nodes[e])} at {np.round(pts[e], 6).tolist()}) cannot be extrapolated: the body's {n_free} "
        "non-contact nodes do not "
        f"span {mesh.dim + 1} affinely independent points; refine the mesh through the thickness, restrict the "
        "contact nodes ([contact] where = ...), or choose the mass 'seed' or 'standard'"
    )


def extrapolation_operator(mesh: Mesh, contact_nodes: np.ndarray, name: str = "moment-preserving") -> sp.csr_matrix:
    """T (n, n): identity on the non-contact nodes, affine extrapolation on the contact nodes.

    Parameters
    ----------
    mesh : the mesh; contact_nodes : (nc,) node indices of Gamma_C.
    name : the mass variant, for the error messages.

    Returns
    -------
    T with ``T @ p == p`` for every affine nodal field p (to round-off), zero columns on
    the contact nodes, and rows ``w_c`` on them (see the module docstring).
    """
    n = mesh.n_nodes
    contact_nodes = np.asarray(contact_nodes, dtype=np.int64)
    is_c = np.zeros(n, dtype=bool)
    is_c[contact_nodes] = True
    keep = np.flatnonzero(~is_c)
    rows, cols, vals = [keep], [keep], [np.ones(keep.size)]
    for c, cand, w in neighbourhoods(mesh, contact_nodes, is_c, name):
        rows.append(np.repeat(c, cand.shape[1]))
        cols.append(cand.ravel())
        vals.append(w.ravel())
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    T.eliminate_zeros()
    return T


def neighbourhoods(mesh: Mesh, contact_nodes: np.ndarray, is_c: np.ndarray, name: str):
    """Yield (nodes (m,), candidates (m, k), weights (m, k)) until every contact node has its fit.

    The whole growth (rings, then nearest nodes in space) runs with the condition limit
    :data:`MAX_CONDITION`; nodes it leaves without a fit get a second growth with
    :data:`RELAXED_CONDITION` (affinely degenerate neighbourhoods stay refused).
    """
    todo = np.arange(contact_nodes.size)
    for limit in (MAX_CONDITION, RELAXED_CONDITION):
        todo = yield from _grow(mesh, contact_nodes, is_c, todo, limit)
        if todo.size == 0:
            return
    raise _impossible(name, mesh, contact_nodes[todo], is_c)


def _grow(mesh: Mesh, contact_nodes: np.ndarray, is_c: np.ndarray, todo: np.ndarray, limit: float):
    """One growth of the neighbourhoods of ``contact_nodes[todo]``; returns the nodes left without a fit."""
    pts, d = mesh.points, mesh.dim
    A = node_graph(mesh)
    drop = sp.diags((~is_c).astype(float))
    R = A[contact_nodes[todo]]
    for _ring in range(2, MAX_RING + 1):  # two rings first: the historical choice
        R = (R @ A).tocsr()
        F = (R @ drop).tocsr()
        F.eliminate_zeros()
        F.sort_indices()
        cand, valid = _padded(F)
        centres = pts[contact_nodes[todo]]
        ok = np.zeros(todo.size, dtype=bool)
        if COMPACT:  # first the COMPACT (d+1) nearest candidates of the ring: a sparser T^T M T
            near, nvalid = _nearest(pts, centres, cand, valid, COMPACT * (d + 1))
            w, ok = _fit(pts, centres, near, nvalid, limit)
            if ok.any():
                yield contact_nodes[todo[ok]], near[ok], w[ok]
        rest = ~ok
        if rest.any():
            w, ok2 = _fit(pts, centres[rest], cand[rest], valid[rest], limit)
            if ok2.any():
                yield contact_nodes[todo[rest][ok2]], cand[rest][ok2], w[ok2]
            ok[np.flatnonzero(rest)[ok2]] = True
        todo, R = todo[~ok], R[~ok]
        if todo.size == 0:
            return todo
        R.data[:] = 1
    # the nearest non-contact nodes in space, of the contact node's own body only (a mass
    # variant never couples two bodies: M stays block diagonal over them)
    label = body_labels(mesh)
    left = []
    for b in np.unique(label[contact_nodes[todo]]):
        mine = todo[label[contact_nodes[todo]] == b]
        free = np.flatnonzero(~is_c & (label == b))
        if free.size < d + 1:
            left.append(mine)
            continue
        from scipy.spatial import cKDTree

        tree = cKDTree(pts[free])
        k = min(free.size, 4 * (d + 1))
        while mine.size:
            _, idx = tree.query(pts[contact_nodes[mine]], k=k)
            cand = free[np.asarray(idx).reshape(mine.size, -1)]
            w, ok = _fit(pts, pts[contact_nodes[mine]], cand, np.ones(cand.shape, dtype=bool), limit)
            if ok.any():
                yield contact_nodes[mine[ok]], cand[ok], w[ok]
            mine = mine[~ok]
            if k == free.size:
                break
            k = min(free.size, 2 * k)
        left.append(mine)
    return np.sort(np.concatenate(left)) if left else todo[:0]


def body_labels(mesh: Mesh) -> np.ndarray:
    """The body (connected component) of every node, computed once per mesh."""
    from ...fem.mesh import bodies

    return mesh.cached("bodies", lambda: bodies(mesh))


def nearest_free_nodes(mesh: Mesh, seeds: sp.csr_matrix, is_c: np.ndarray, name: str) -> sp.csr_matrix:
    """Row-stochastic (m, n): for each row of ``seeds`` (a set of nodes), equal shares on
    the non-contact nodes of the first node-graph ring around the set that has any.

    Used by the ``neighbour`` and ``mass-free-surface`` variants for a contact node (or
    a cell) with no non-contact node next to it: its mass goes to the nearest ones.
    """
    A = node_graph(mesh)
    drop = sp.diags((~is_c).astype(float))
    R = sp.csr_matrix(seeds, dtype=float)
    out = sp.lil_matrix((R.shape[0], mesh.n_nodes))
    todo = np.arange(R.shape[0])
    for _ in range(4 * MAX_RING):
        R = (R @ A).tocsr()
        R.data[:] = 1.0
        F = (R @ drop).tocsr()
        F.eliminate_zeros()
        counts = np.diff(F.indptr)
        got = counts > 0
        if got.any():
            out[todo[got]] = sp.diags(1.0 / counts[got]) @ F[got]
        todo, R = todo[~got], R[~got]
        if todo.size == 0:
            return out.tocsr()
    from scipy.spatial import cKDTree  # far from every non-contact node in the graph: the nearest in space

    seeds_c = sp.csr_matrix(seeds)[todo]
    counts = np.maximum(np.diff(seeds_c.indptr), 1)
    centres = (seeds_c @ mesh.points) / counts[:, None]
    label = body_labels(mesh)
    row_body = label[seeds_c.indices[seeds_c.indptr[:-1]]]  # each set's body (its first node's)
    for b in np.unique(row_body):
        mine = np.flatnonzero(row_body == b)
        free = np.flatnonzero(~is_c & (label == b))  # of the same body: never across two bodies
        if free.size == 0:
            raise InputError(
                f"mass {name!r}: every node of body {int(b)} is a contact node: no node of it can carry their mass"
            )
        _, idx = cKDTree(mesh.points[free]).query(centres[mine], k=1)
        out[todo[mine], free[np.asarray(idx).ravel()]] = 1.0
    return out.tocsr()
