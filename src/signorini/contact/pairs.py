"""Contact between two deformable surfaces: node-to-facet rows of B for a (slave, master) pair.

A :class:`ContactPair` names two facet tags.  Every slave node s is projected at t = 0 onto
the closest master facet (candidates from a KD-tree over the facet centres, then the exact
closest point of each candidate: a vertex in 1D, a segment in 2D, a triangle or a bilinear
quadrilateral in 3D).  With n_m the master facet's outward unit normal at the projection
p = sum_j N_j(xi) x_j, the discrete condition of the node is

    g_s - B_s u >= 0,   g_s = (x_s - p) . n_m,
    B_s u = -n_m . u_s + sum_j N_j(xi) n_m . u_j        (j: the master facet's nodes)

the linearized gap of small deformations: the relative normal displacement of the slave
node against the master surface at the point it faces.  The pairing (facet, xi, n_m) is
frozen at t = 0 (small sliding without re-pairing; docs/bodies.md says where this holds).
A slave node whose closest point lies outside the master surface (laterally off it by more
than 1e-6 of the pair's size) faces nothing: it gets no row (counted as ``inactive``).

Sign conventions as for a rigid obstacle (:mod:`signorini.contact.obstacles`): the row's
normal nu_s = -n_m points out of the slave body, lambda_s <= 0 is the normal force on the
slave node (and -N_j lambda_s n_m its share on master node j): the pair's forces balance,
so that the total momentum of the bodies is kept.

With friction, the tangential rows are the relative slip of the slave node against the same
master point, t^T u_s - sum_j N_j(xi) t^T u_j with t the tangents of the frame of nu_s
(:func:`~signorini.contact.frames.tangent_frames`), and a pair has its own law
(:attr:`ContactPair.friction`; None: the ``[contact] friction`` of the run).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..errors import InputError
from ..fem.assembly import facet_weights
from ..fem.dofmap import DofMap
from ..fem.elements import reference_element, shape_functions
from ..fem.mesh import Mesh, facet_type, facet_vertices
from .friction import Friction, make_friction

#: master facets tried per slave node (the nearest centres); more cost more, fewer may miss
#: the closest facet of a coarse master next to a fine slave
CANDIDATES = 8
#: a slave node laterally off the master surface by more than this x the pair's size is inactive
OFF_SURFACE = 1e-6


@dataclass(frozen=True)
class ContactPair:
    """Two facet tags in contact: the nodes of ``slave`` against the facets of ``master``.

    ``friction``: the pair's contact law, in any spelling of
    :func:`~signorini.contact.friction.make_friction` (``"coulomb:0.3"``, ``{"law": "tresca",
    "threshold": 0.01}``, a :class:`~signorini.contact.friction.Friction`), normalized to a
    Friction; None (default): the run's ``[contact] friction``.  The frictional rows of a run
    share one law kind, each its own coefficient or threshold (:func:`~signorini.dynamics.model.problem.run_friction`).
    """

    slave: str
    master: str
    friction: Friction | str | dict | None = None

    def __post_init__(self) -> None:
        for name in ("slave", "master"):
            v = getattr(self, name)
            if not isinstance(v, str) or not v:
                raise InputError(f"contact pair {name} must be a facet tag (a non-empty string), got {v!r}")
        if self.slave == self.master:
            raise InputError(f"contact pair: slave and master are the same tag {self.slave!r}")
        if self.friction is not None:
            where = f"contact pair {self.slave!r} / {self.master!r} friction"
            object.__setattr__(self, "friction", make_friction(self.friction, where))

    @property
    def label(self) -> str:
        """``slave / master`` (the tags), as error messages name the pair."""
        return f"{self.slave!r} / {self.master!r}"


@dataclass
class PairRows:
    """The discrete condition of one pair (see the module docstring)."""

    nodes: np.ndarray  # (m,) slave nodes with a row
    normals: np.ndarray  # (m, d) nu_s = -n_m, out of the slave body
    gaps: np.ndarray  # (m,) g_s at t = 0 [length]
    weights: np.ndarray  # (m,) slave contact areas
    B: sp.csr_matrix  # (m, n_dofs)
    facet: np.ndarray  # (m,) index of the master facet in the master tag's facets
    xi: np.ndarray  # (m, nfv) the master facet's shape functions at the projection
    facet_nodes: np.ndarray  # (m, nfv) the master facet's nodes, in the order of xi
    master_nodes: np.ndarray  # (k,) every node of the master tag (their inertia is redistributed too)
    inactive: int  # slave nodes that face no master facet


def facet_owner_normals(mesh: Mesh, facets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit normals (nf, d) of boundary facets and the facets' nodes in the owning
    cell's outward orientation (nf, nfv), whatever the orientation they were given in.

    Each facet is matched (as a set of nodes) to the face of the one cell it bounds; the
    reference element lists faces outward (:class:`~signorini.fem.elements.ReferenceElement`).
    """
    blocks = [b for b in mesh.blocks if len(reference_element(b.cell_type).facets[0]) == facets.shape[1]]
    if not blocks:
        raise InputError(f"contact pair: facets of {facets.shape[1]} nodes are faces of no cell of the mesh")
    b = blocks[0] if len(blocks) == 1 else None
    if b is None:  # 2D triangles and quads (edges alike): faces of every block, with their cells
        loc = None
        faces = np.vstack(
            [
                blk.cells[:, np.array(reference_element(blk.cell_type).facets)].reshape(-1, facets.shape[1])
                for blk in blocks
            ]
        )
    else:
        loc = np.array(reference_element(b.cell_type).facets)
        faces = b.cells[:, loc].reshape(-1, loc.shape[1])  # every cell face, outward order
    nv = facet_vertices(facets, mesh.dim).shape[1]  # a quadratic facet is told apart by its vertices
    key_faces = _keys(faces[:, :nv], mesh.n_nodes)
    key_tag = _keys(facets[:, :nv], mesh.n_nodes)
    order = np.argsort(key_faces, kind="stable")
    pos = np.searchsorted(key_faces[order], key_tag)
    pos = np.minimum(pos, order.size - 1)
    found = key_faces[order][pos] == key_tag
    if not found.all():
        i = int(np.flatnonzero(~found)[0])
        raise InputError(f"contact pair: facet {facets[i].tolist()} is not a face of any cell of the mesh")
    oriented = faces[order[pos]]
    X = mesh.points
    d = mesh.dim
    if d == 1:  # a vertex: outward is away from the other node of its cell (1D: one block)
        cell = order[pos] // loc.shape[0]
        other = b.cells[cell][:, :2].sum(axis=1) - oriented[:, 0]  # (a line3's mid-side node is not a vertex)
        n = np.sign(X[oriented[:, 0], 0] - X[other, 0])[:, None]
        return n.astype(float), oriented
    if d == 2:
        t = X[oriented[:, 1]] - X[oriented[:, 0]]
        n = np.column_stack([t[:, 1], -t[:, 0]])
    else:  # the vertices' normal (a quadratic facet's is the same at its vertices' plane)
        a, b, c = X[oriented[:, 0]], X[oriented[:, 1]], X[oriented[:, nv - 1]]
        n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    return n, oriented


def _normal_at(P: np.ndarray, N: np.ndarray, kind: str, outward: np.ndarray) -> np.ndarray:
    """The unit normal (m, d) of facets P (m, nfv, d) at the points of shape functions N (m, nfv), outward as the
    facets' normals ``outward`` (m, d): that of a bilinear or curved face at the point, a flat facet's own."""
    if kind == "quad":
        n = _quad_normal(P, N)
    elif kind in CURVED:
        n = _curved_normals(P, N, kind)
    else:
        return outward
    return n * np.sign(np.einsum("md,md->m", n, outward))[:, None]


def _keys(f: np.ndarray, nn: int) -> np.ndarray:
    """One sortable value per facet (:func:`signorini.fem.mesh.face_keys`: no overflow at any size)."""
    from ..fem.mesh import face_keys

    return face_keys(f, nn)


#: the quadratic (curved) facets and the linear facet of their vertices (from the element registry)
CURVED = {kind: reference_element(kind).linear for kind in ("line3", "triangle6", "quad8", "quad9")}
#: Gauss-Newton iterations of a projection on a curved facet (it stops when no point moves by 1e-14)
CURVED_ITERATIONS = 30


def _closest_on_facets(x: np.ndarray, P: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Closest points (m, d) of points x (m, d) on facets P (m, nfv, d) and the facets' shape
    functions there (m, nfv): a vertex, a segment, a triangle or a bilinear quadrilateral, or their
    quadratic (curved) forms (:func:`_closest_on_curved`)."""
    if kind in CURVED:
        return _closest_on_curved(x, P, kind)
    if kind == "vertex":
        return P[:, 0], np.ones((x.shape[0], 1))
    if kind == "line":
        a, b = P[:, 0], P[:, 1]
        e = b - a
        s = np.clip(np.einsum("md,md->m", x - a, e) / np.einsum("md,md->m", e, e), 0.0, 1.0)
        return a + s[:, None] * e, np.column_stack([1 - s, s])
    if kind == "triangle":
        return _closest_on_triangles(x, P)
    return _closest_on_quads(x, P)


def _closest_on_curved(x: np.ndarray, P: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Closest points on quadratic facets P (m, nfv, d): projected Gauss-Newton on the facet's parameters s
    (x(s) = sum_j N_j(s) P_j; s in [0, 1], the reference triangle or [-1, 1]^2), started at the closest point
    of the linear facet of its vertices.  At its fixed point the residual x - x(s) is orthogonal to the facet
    (or s on the parameters' boundary): the exact closest point of the curved facet."""
    ref = reference_element(kind)
    nv = ref.n_vertices
    _, N0 = _closest_on_facets(x, P[:, :nv], CURVED[kind])
    s = N0 @ reference_element(CURVED[kind]).nodes  # the linear guess's parameters (m, k)
    for _ in range(CURVED_ITERATIONS):
        N, dN = shape_functions(kind, s)
        r = x - np.einsum("mj,mjd->md", N, P)
        J = np.einsum("mjk,mjd->mdk", dN, P)  # dx/ds (m, d, k)
        step = np.linalg.solve(np.einsum("mdk,mdl->mkl", J, J), np.einsum("mdk,md->mk", J, r)[..., None])[..., 0]
        new = _into_parameters(s + step, CURVED[kind])
        moved = float(np.abs(new - s).max(initial=0.0))
        s = new
        if moved <= 1e-14:
            break
    N, _ = shape_functions(kind, s)
    return np.einsum("mj,mjd->md", N, P), N


def _into_parameters(s: np.ndarray, linear: str) -> np.ndarray:
    """Parameters s (m, k) moved into the reference domain of a facet whose vertices make a ``linear`` facet."""
    if linear == "line":
        return np.clip(s, 0.0, 1.0)
    if linear == "quad":
        return np.clip(s, -1.0, 1.0)
    s = np.maximum(s, 0.0)  # the reference triangle: beyond the hypotenuse, onto it, then into [0, 1]
    over = np.maximum(s.sum(axis=1) - 1.0, 0.0)
    return np.clip(s - over[:, None] / 2.0, 0.0, 1.0)


def _curved_normals(P: np.ndarray, N: np.ndarray, kind: str) -> np.ndarray:
    """Unit normals (m, d) of quadratic facets P (m, nfv, d) at the points of shape functions N (m, nfv), by the
    facets' node order as :func:`_facet_normals` (the parameters recovered as s = N @ the reference nodes: the
    shape functions reproduce linear functions)."""
    s = N @ reference_element(kind).nodes
    _, dN = shape_functions(kind, s)
    J = np.einsum("mjk,mjd->mdk", dN, P)
    n = np.column_stack([J[:, 1, 0], -J[:, 0, 0]]) if P.shape[2] == 2 else np.cross(J[:, :, 0], J[:, :, 1])
    return n / np.linalg.norm(n, axis=1)[:, None]


def _closest_on_triangles(x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a, b, c = P[:, 0], P[:, 1], P[:, 2]
    e1, e2 = b - a, c - a
    G = np.stack(
        [
            np.stack([np.einsum("md,md->m", e1, e1), np.einsum("md,md->m", e1, e2)], -1),
            np.stack([np.einsum("md,md->m", e2, e1), np.einsum("md,md->m", e2, e2)], -1),
        ],
        -2,
    )
    r = np.stack([np.einsum("md,md->m", x - a, e1), np.einsum("md,md->m", x - a, e2)], -1)
    st = np.linalg.solve(G, r[..., None])[..., 0]
    N = np.column_stack([1 - st.sum(axis=1), st[:, 0], st[:, 1]])
    inside = (N >= 0).all(axis=1)
    best = np.einsum("mk,mkd->md", N, P)
    if not inside.all():  # outside: the closest point of the three edges
        dist = np.full(x.shape[0], np.inf)
        for i, j in ((0, 1), (1, 2), (2, 0)):
            p, w = _closest_on_facets(x, P[:, [i, j]], "line")
            dd = np.linalg.norm(x - p, axis=1)
            better = ~inside & (dd < dist)
            dist[better] = dd[better]
            best[better] = p[better]
            Nn = np.zeros_like(N)
            Nn[:, i], Nn[:, j] = w[:, 0], w[:, 1]
            N[better] = Nn[better]
    return best, N


def _closest_on_quads(x: np.ndarray, P: np.ndarray, iterations: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Projected Gauss-Newton on (xi, eta) in [-1, 1]^2 of the bilinear map
    x(xi, eta) = c0 + c1 xi + c2 eta + c3 xi eta (exact for a parallelogram in one step; a
    warped face converges in a few); it stops when no point moves by more than 1e-14 in
    (xi, eta)."""
    c0 = 0.25 * (P[:, 0] + P[:, 1] + P[:, 2] + P[:, 3])
    c1 = 0.25 * (-P[:, 0] + P[:, 1] + P[:, 2] - P[:, 3])
    c2 = 0.25 * (-P[:, 0] - P[:, 1] + P[:, 2] + P[:, 3])
    c3 = 0.25 * (P[:, 0] - P[:, 1] + P[:, 2] - P[:, 3])
    xi, eta = np.zeros(x.shape[0]), np.zeros(x.shape[0])
    for _ in range(iterations):
        ja = c1 + c3 * eta[:, None]  # dx/dxi (m, d)
        jb = c2 + c3 * xi[:, None]  # dx/deta
        r = x - (c0 + c1 * xi[:, None] + c2 * eta[:, None] + c3 * (xi * eta)[:, None])
        aa, ab, bb = (ja * ja).sum(axis=1), (ja * jb).sum(axis=1), (jb * jb).sum(axis=1)
        ra, rb = (ja * r).sum(axis=1), (jb * r).sum(axis=1)
        det = aa * bb - ab * ab
        new_xi = np.clip(xi + (bb * ra - ab * rb) / det, -1.0, 1.0)
        new_eta = np.clip(eta + (aa * rb - ab * ra) / det, -1.0, 1.0)
        moved = max(float(np.abs(new_xi - xi).max(initial=0.0)), float(np.abs(new_eta - eta).max(initial=0.0)))
        xi, eta = new_xi, new_eta
        if moved <= 1e-14:
            break
    N = 0.25 * np.column_stack([(1 - xi) * (1 - eta), (1 + xi) * (1 - eta), (1 + xi) * (1 + eta), (1 - xi) * (1 + eta)])
    p = c0 + c1 * xi[:, None] + c2 * eta[:, None] + c3 * (xi * eta)[:, None]
    return p, N


@dataclass
class FacetRows:
    """Nodes projected on facets (:func:`node_to_facet_rows`): the rows of those on the surface."""

    nodes: np.ndarray  # (m,) the nodes whose closest point lies on the surface
    normals: np.ndarray  # (m, d) n_m, the facets' outward unit normals at the projections
    gaps: np.ndarray  # (m,) (x - p) . n_m [length]
    B: sp.csr_matrix  # (m, n_dofs): -n_m . u_node + sum_j N_j n_m . u_j
    facet: np.ndarray  # (m,) index of the facet in ``facets``
    xi: np.ndarray  # (m, nfv) the facet's shape functions at the projection
    facet_nodes: np.ndarray  # (m, nfv) the facet's nodes, outward orientation
    inactive: int  # nodes laterally off the surface at t = 0 (no row, unless ``every``)


def node_to_facet_rows(
    mesh: Mesh, nodes: np.ndarray, facets: np.ndarray, n_dofs: int, every: bool = False
) -> FacetRows:
    """The linearized gap rows of ``nodes`` against the surface of ``facets`` (boundary facets
    of the mesh) at t = 0 (the module docstring): closest facet among the :data:`CANDIDATES`
    nearest centres, exact closest point, the facet's outward normal there; nodes laterally
    off the surface by more than :data:`OFF_SURFACE` of the size get no row (``every``: they get one too, at
    their closest point: finite strain, whose pairing follows the current configuration)."""
    d = mesh.dim
    normals_f, oriented = facet_owner_normals(mesh, facets)
    X = mesh.points
    P = X[oriented]  # (nf, nfv, d)
    centres = P.mean(axis=1)
    kind = facet_type(oriented, d)
    k = min(CANDIDATES, len(facets))
    d_centre, cand = cKDTree(centres).query(X[nodes], k=k)
    d_centre, cand = np.asarray(d_centre).reshape(nodes.size, k), np.asarray(cand).reshape(nodes.size, k)
    # prune: a candidate whose lower bound |x - centre| - radius exceeds the distance to the
    # nearest vertex of any candidate cannot hold the closest point (vertices are on the facets)
    radius = np.linalg.norm(P - centres[:, None, :], axis=2).max(axis=1)
    to_vertex = np.linalg.norm(P[cand] - X[nodes][:, None, None, :], axis=3).min(axis=(1, 2))
    keep = d_centre - radius[cand] <= to_vertex[:, None] * (1 + 1e-12)
    keep[:, 0] = True  # the nearest centre always (its lower bound is the smallest)
    row, col = np.nonzero(keep)
    xs = X[nodes][row]
    p, N = _closest_on_facets(xs, P[cand[row, col]], kind)
    dist = np.linalg.norm(xs - p, axis=1)
    size = float(np.linalg.norm(np.ptp(np.vstack([X[nodes], centres]), axis=0))) or 1.0
    first = _closest(row, dist, centres[cand[row, col]], size, xs)
    facet, p, N = cand[row[first], col[first]], p[first], N[first]
    normals_m = _normal_at(P[facet], N, kind, normals_f[facet])
    delta = X[nodes] - p
    gaps = np.einsum("md,md->m", delta, normals_m)
    lateral = np.linalg.norm(delta - gaps[:, None] * normals_m, axis=1)
    size = float(np.linalg.norm(np.ptp(np.vstack([X[nodes], centres]), axis=0))) or 1.0
    facing = lateral <= OFF_SURFACE * size
    on = facing | every
    nodes, facet, N, normals_m, gaps = nodes[on], facet[on], N[on], normals_m[on], gaps[on]
    m, nfv = nodes.size, oriented.shape[1]
    rows = np.repeat(np.arange(m), d * (1 + nfv))
    master = oriented[facet]  # (m, nfv)
    nodes_all = np.concatenate([nodes[:, None], master], axis=1)  # (m, 1 + nfv)
    coef = np.concatenate([-np.ones((m, 1)), N], axis=1)  # (m, 1 + nfv)
    dofs = DofMap.serial(mesh.n_nodes, d).dofs(nodes_all.ravel()).reshape(m, (1 + nfv) * d)
    vals = (coef[:, :, None] * normals_m[:, None, :]).reshape(m, (1 + nfv) * d)
    B = sp.csr_matrix((vals.ravel(), (rows, dofs.ravel())), shape=(m, n_dofs))
    B.sum_duplicates()
    return FacetRows(nodes, normals_m, gaps, B, facet, N, master, int((~facing).sum()))


#: closest points within this fraction of the pair's size are a tie (a node on a vertex or edge
#: shared by facets: their distances differ by round-off only)
TIE = 1e-12


def _closest(row: np.ndarray, dist: np.ndarray, centres: np.ndarray, size: float, x: np.ndarray) -> np.ndarray:
    """For each node (``row``, sorted; at ``x`` (m, d), one per candidate) the position of its
    closest candidate facet; a tie (to :data:`TIE` x size: a node on a vertex or an edge that
    facets share) goes to the facet whose centre is nearest to the node, then to the one whose
    centre is first in (x, y, z) order: rules of the geometry, so that the pairing does not
    depend on the mesh's numbering."""
    q = np.round(dist / (TIE * size))
    qc = np.round(np.linalg.norm(centres - x, axis=1) / (TIE * size))
    keys = tuple(centres[:, k] for k in range(centres.shape[1] - 1, -1, -1)) + (qc, q, row)
    order = np.lexsort(keys)
    return order[np.r_[0, np.flatnonzero(np.diff(row[order])) + 1]]


def pair_rows(mesh: Mesh, pair: ContactPair, n_dofs: int, every: bool = False) -> PairRows:
    """The rows of B, gaps, normals and weights of ``pair`` (see the module docstring); ``every``: a row for every
    slave node (:func:`node_to_facet_rows`)."""
    slave = mesh.nodes_of(pair.slave)
    facets = mesh.facets_of(pair.master)
    if np.intersect1d(slave, np.unique(facets)).size:
        raise InputError(
            f"contact pair {pair.slave!r} / {pair.master!r}: the two tags share nodes; a pair is two "
            "surfaces that can touch (of two bodies, or two parts of one body's boundary)"
        )
    r = node_to_facet_rows(mesh, slave, facets, n_dofs, every)
    weights = facet_weights(mesh, pair.slave, positive=True)[r.nodes]
    return PairRows(
        r.nodes, -r.normals, r.gaps, weights, r.B, r.facet, r.xi, r.facet_nodes, np.unique(facets), r.inactive
    )


def _quad_normal(P: np.ndarray, N: np.ndarray) -> np.ndarray:
    """Unit normal of bilinear faces P (m, 4, 3) at the points of shape functions N (m, 4)."""
    ref = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    # recover (xi, eta) from N: N_1 + N_2 - N_0 - N_3 = xi (bilinear), N_2 + N_3 - N_0 - N_1 = eta
    xi = N[:, 1] + N[:, 2] - N[:, 0] - N[:, 3]
    eta = N[:, 2] + N[:, 3] - N[:, 0] - N[:, 1]
    dxi = np.einsum("mk,mkd->md", 0.25 * ref[:, 0] * (1 + eta[:, None] * ref[:, 1]), P)
    deta = np.einsum("mk,mkd->md", 0.25 * ref[:, 1] * (1 + xi[:, None] * ref[:, 0]), P)
    n = np.cross(dxi, deta)
    return n / np.linalg.norm(n, axis=1)[:, None]


# ----------------------------------------------------------------------------- small sliding
#: a slave node has left its master facet when its orthogonal projection on the deformed facet
#: lies outside it by more than this in the facet's parameters (hysteresis at a shared edge)
LEAVE = 1e-9


def _outside(x: np.ndarray, P: np.ndarray, kind: str, leave: float = LEAVE) -> np.ndarray:
    """Whether the orthogonal projection of x (m, d) on the facets P (m, nfv, d) (their plane,
    or the bilinear surface) lies outside them by more than ``leave`` in their parameters."""
    if kind == "vertex":
        return np.zeros(x.shape[0], dtype=bool)
    if kind == "line":
        a, e = P[:, 0], P[:, 1] - P[:, 0]
        s = ((x - a) * e).sum(axis=1) / (e * e).sum(axis=1)
        return (s < -leave) | (s > 1 + leave)
    if kind == "triangle":
        a, e1, e2 = P[:, 0], P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
        g11, g12, g22 = (e1 * e1).sum(axis=1), (e1 * e2).sum(axis=1), (e2 * e2).sum(axis=1)
        r1, r2 = ((x - a) * e1).sum(axis=1), ((x - a) * e2).sum(axis=1)
        det = g11 * g22 - g12 * g12
        s, t = (g22 * r1 - g12 * r2) / det, (g11 * r2 - g12 * r1) / det
        return (s < -leave) | (t < -leave) | (s + t > 1 + leave)
    # bilinear quadrilateral: unclipped Gauss-Newton for (xi, eta), outside [-1, 1]^2
    c0 = 0.25 * (P[:, 0] + P[:, 1] + P[:, 2] + P[:, 3])
    c1 = 0.25 * (-P[:, 0] + P[:, 1] + P[:, 2] - P[:, 3])
    c2 = 0.25 * (-P[:, 0] - P[:, 1] + P[:, 2] + P[:, 3])
    c3 = 0.25 * (P[:, 0] - P[:, 1] + P[:, 2] - P[:, 3])
    xi, eta = np.zeros(x.shape[0]), np.zeros(x.shape[0])
    for _ in range(8):
        ja, jb = c1 + c3 * eta[:, None], c2 + c3 * xi[:, None]
        r = x - (c0 + c1 * xi[:, None] + c2 * eta[:, None] + c3 * (xi * eta)[:, None])
        aa, ab, bb = (ja * ja).sum(axis=1), (ja * jb).sum(axis=1), (jb * jb).sum(axis=1)
        ra, rb = (ja * r).sum(axis=1), (jb * r).sum(axis=1)
        det = aa * bb - ab * ab
        dxi, deta = (bb * ra - ab * rb) / det, (aa * rb - ab * ra) / det
        xi, eta = xi + dxi, eta + deta
        if max(float(np.abs(dxi).max(initial=0.0)), float(np.abs(deta).max(initial=0.0))) <= 1e-14:
            break
    return (np.abs(xi) > 1 + 2 * leave) | (np.abs(eta) > 1 + 2 * leave)


@dataclass
class SlidRows:
    """The new condition of the pair rows whose slave node left its master facet."""

    rows: np.ndarray  # (m,) the contact rows re-paired
    normals: np.ndarray  # (m, d) nu_s = -n_m of the new facet (reference configuration)
    gaps: np.ndarray  # (m,) (x_s - p) . n_m at the new projection p (reference configuration)
    facet: np.ndarray  # (m,) the new facet (index in the master tag's facets)
    xi: np.ndarray  # (m, nfv) its shape functions at the deformed slave node's projection
    facet_nodes: np.ndarray  # (m, nfv) its nodes, outward orientation


def master_geometry(mesh: Mesh, pair: ContactPair) -> tuple[np.ndarray, np.ndarray]:
    """(outward unit normals (nf, d), facets' nodes in outward order (nf, nfv)) of the pair's
    master tag (:func:`facet_owner_normals`; constant over a run: computed once)."""
    return facet_owner_normals(mesh, mesh.facets_of(pair.master))


def slid_rows(
    mesh: Mesh,
    pair: ContactPair,
    rows: np.ndarray,
    slave: np.ndarray,
    facet: np.ndarray,
    U: np.ndarray,
    geometry: tuple[np.ndarray, np.ndarray] | None = None,
) -> SlidRows | None:
    """Small sliding of one pair: the rows ``rows`` (slave nodes ``slave``, current facets
    ``facet``) whose slave node's projection left its facet in the configuration X + U are
    projected again, in that configuration, on the closest master facet; their new row is
    the linearized gap of that facet about the reference configuration,

        g = (x_s - sum_j N_j x_j) . n_m,   B u = -n_m . u_s + sum_j N_j n_m . u_j,

    with N_j at the deformed projection and n_m the reference normal there, so that
    g - B u = n_m . ((x_s + u_s) - sum_j N_j (x_j + u_j)): the current normal gap.  None when
    no row left its facet.  ``geometry``: :func:`master_geometry` of the pair (computed when None)."""
    d = mesh.dim
    if d == 1 or rows.size == 0:
        return None
    normals_f, oriented = master_geometry(mesh, pair) if geometry is None else geometry
    u = U.reshape(-1, d)

    def deformed(nodes: np.ndarray) -> np.ndarray:  # X + U at these nodes only (every level: no whole-mesh copy)
        return mesh.points[nodes] + u[nodes]

    kind = facet_type(oriented, d)
    # a curved facet: its vertices' facet says whether the node left it (the projection on it is the curved one)
    nv = facet_vertices(oriented, d).shape[1]
    left = _outside(deformed(slave), deformed(oriented[facet][:, :nv]), CURVED.get(kind, kind))
    if not left.any():
        return None
    Xd = mesh.points + u
    rows, slave = rows[left], slave[left]
    Pd = Xd[oriented]
    centres = Pd.mean(axis=1)
    k = min(CANDIDATES, len(oriented))
    _, cand = cKDTree(centres).query(Xd[slave], k=k)
    cand = np.asarray(cand).reshape(slave.size, k)
    xs = np.repeat(Xd[slave], k, axis=0)
    p, N = _closest_on_facets(xs, Pd[cand.ravel()], kind)
    dist = np.linalg.norm(xs - p, axis=1)
    size = float(np.linalg.norm(np.ptp(centres, axis=0))) or 1.0
    pick = _closest(np.repeat(np.arange(slave.size), k), dist, centres[cand.ravel()], size, xs)
    new, N = cand.ravel()[pick], N[pick]
    moved = new != facet[left]  # still the closest: beyond the master surface's edge, the row stays
    if not moved.any():
        return None
    rows, slave, new, N = rows[moved], slave[moved], new[moved], N[moved]
    P = mesh.points[oriented[new]]
    n_m = _normal_at(P, N, kind, normals_f[new])
    gaps = np.einsum("md,md->m", mesh.points[slave] - np.einsum("mk,mkd->md", N, P), n_m)
    return SlidRows(rows, -n_m, gaps, new, N, oriented[new])


# ----------------------------------------------------------------------------- current configuration
def _facet_normals(P: np.ndarray, N: np.ndarray, kind: str) -> np.ndarray:
    """Unit normals (m, d) of facets P (m, nfv, d) at the points of shape functions N (m, nfv), by the facets'
    node order (a segment's (t_y, -t_x), a triangle's (P1 - P0) x (P2 - P0), a bilinear face's at N)."""
    if kind in CURVED:
        return _curved_normals(P, N, kind)
    if kind == "line":
        t = P[:, 1] - P[:, 0]
        n = np.column_stack([t[:, 1], -t[:, 0]])
    elif kind == "triangle":
        n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    else:
        return _quad_normal(P, N)
    return n / np.linalg.norm(n, axis=1)[:, None]


@dataclass
class CurrentProjection:
    """Slave nodes projected on the master surface of one pair in the current configuration X + U."""

    facet: np.ndarray  # (m,) the closest master facet (index in the master tag's facets)
    xi: np.ndarray  # (m, nfv) its shape functions at the projection
    normals: np.ndarray  # (m, d) n_m, the deformed facet's outward unit normal there
    gaps: np.ndarray  # (m,) (x_s - p) . n_m in the current configuration [length]
    facet_nodes: np.ndarray  # (m, nfv) the facet's nodes, outward orientation
    scale: float  # the size of the coordinates the gaps are computed from [length]
    facing: np.ndarray  # (m,) whether the node faces the surface (not beyond its rim): the others get no contact


#: in the current configuration a slave node keeps its facet while its orthogonal projection lies on the facet
#: extended by this fraction of its parameters (a hysteresis at the kinks of the deformed master surface)
KEEP_FACET = 0.05


class CurrentPairing:
    """The projections of a pair's slave nodes in the current configuration (finite strain: large sliding).

    Each call searches the closest deformed master facet among the :data:`CANDIDATES` nearest centres (as
    at t = 0, ties by the same geometric rules) and gives its current outward normal: the facets' node
    order gives a normal up to a sign fixed once per facet against the reference outward normal."""

    def __init__(self, mesh: Mesh, pair: ContactPair):
        self.mesh = mesh
        normals_f, self.oriented = master_geometry(mesh, pair)
        d = mesh.dim
        self.kind = facet_type(self.oriented, d)
        #: the vertices of the facets (a curved facet's chord: whether a node left it)
        self.nv = facet_vertices(self.oriented, d).shape[1]
        P = mesh.points[self.oriented]
        centre = (
            reference_element(self.kind).N.mean(axis=0, keepdims=True).repeat(len(P), axis=0)
            if (self.kind in CURVED)
            else np.full(self.oriented.shape, 1.0 / self.oriented.shape[1])
        )
        self.sign = np.sign(np.einsum("md,md->m", _facet_normals(P, centre, self.kind), normals_f))
        # the master surface's rim: the vertices (2D) or the nodes of the edges (3D) of only one master facet (a
        # quadratic facet's edge: its two vertices and its mid-side node)
        vertices = self.oriented[:, : self.nv]
        self.rim = np.zeros(mesh.n_nodes, dtype=bool)
        if d == 2:
            nodes, count = np.unique(vertices, return_counts=True)
            self.rim[nodes[count == 1]] = True
        else:
            edges = np.sort(np.stack([vertices, np.roll(vertices, -1, axis=1)], -1), axis=2)  # (nf, nv, 2)
            _, inverse, count = np.unique(edges.reshape(-1, 2), axis=0, return_inverse=True, return_counts=True)
            once = (count[inverse.ravel()] == 1).reshape(vertices.shape)  # (nf, nv): edge k of facet f is on the rim
            self.rim[edges[once].ravel()] = True
            if self.kind in CURVED:  # the edge's mid-side node (listed after the vertices, in edge order)
                self.rim[self.oriented[:, self.nv : 2 * self.nv][once]] = True

    def _normals(self, P: np.ndarray, N: np.ndarray, facet: np.ndarray) -> np.ndarray:
        """The outward unit normals (m, d) of the master facets ``facet`` at their points P (m, nfv, d), at the
        shape functions N (m, nfv)."""
        return self.sign[facet][:, None] * _facet_normals(P, N, self.kind)

    def gap_gradient(self, local: np.ndarray, facet: np.ndarray) -> np.ndarray:
        """The gradient (m, (1 + nfv) d) of the normal gap g = (x_s - p) . n_m of slave points on their facets,
        from local coordinates ``local`` (m, 1 + nfv, d): the slave point, then the facet's nodes in its outward
        order (``oriented[facet]``): (n_m, -N_1 n_m, ..., -N_k n_m) at the closest point."""
        x, P = local[:, 0], local[:, 1:]
        _, N = _closest_on_facets(x, P, self.kind)
        n = self._normals(P, N, facet)
        return np.concatenate([n[:, None, :], -N[:, :, None] * n[:, None, :]], axis=1).reshape(x.shape[0], -1)

    def __call__(self, slave: np.ndarray, U: np.ndarray, facet: np.ndarray | None = None) -> CurrentProjection:
        """The projections at X + U; ``facet``: the slave nodes' facets so far, kept while the orthogonal
        projection stays on them within :data:`KEEP_FACET` of their parameters (at a kink of the deformed
        master surface the closest facet would alternate between Newton iterates)."""
        d = self.mesh.dim
        X = self.mesh.points + np.asarray(U).reshape(-1, d)
        Pd = X[self.oriented]
        centres = Pd.mean(axis=1)
        size = float(np.linalg.norm(np.ptp(centres, axis=0))) or 1.0
        stay = (  # a curved facet: judged on its chord (its vertices), as small sliding does
            np.zeros(slave.size, dtype=bool)
            if facet is None
            else ~_outside(X[slave], Pd[facet][:, : self.nv], CURVED.get(self.kind, self.kind), KEEP_FACET)
        )
        new = np.array(facet, copy=True) if facet is not None else np.zeros(slave.size, dtype=np.int64)
        N = np.zeros((slave.size, self.oriented.shape[1]))
        p = np.zeros((slave.size, d))
        if stay.any():
            p[stay], N[stay] = _closest_on_facets(X[slave[stay]], Pd[facet[stay]], self.kind)
        search = np.flatnonzero(~stay)
        if search.size:
            k = min(CANDIDATES, len(self.oriented))
            _, cand = cKDTree(centres).query(X[slave[search]], k=k)
            cand = np.asarray(cand).reshape(search.size, k)
            xs = np.repeat(X[slave[search]], k, axis=0)
            pc, Nc = _closest_on_facets(xs, Pd[cand.ravel()], self.kind)
            dist = np.linalg.norm(xs - pc, axis=1)
            pick = _closest(np.repeat(np.arange(search.size), k), dist, centres[cand.ravel()], size, xs)
            new[search], N[search], p[search] = cand.ravel()[pick], Nc[pick], pc[pick]
        facet = new
        scale = float(np.abs(X[np.unique(np.concatenate([slave, self.oriented.ravel()]))]).max(initial=0.0))
        n = self._normals(Pd[facet], N, facet)
        delta = X[slave] - p
        gaps = np.einsum("md,md->m", delta, n)
        # a node whose closest point is on the master surface's rim and off its normal faces nothing there
        lateral = np.linalg.norm(delta - gaps[:, None] * n, axis=1)
        on_rim = np.all(self.rim[self.oriented[facet]] | (N <= 1e-12), axis=1)
        facing = ~(on_rim & (lateral > OFF_SURFACE * size))
        return CurrentProjection(facet, N, n, gaps, self.oriented[facet], scale, facing)


#: a slave side whose facets are this many times larger than the master's gets a warning
COARSER_SLAVE_RATIO = 1.5
#: facets whose unit normals agree to this (1 - |n_i . n_j|) make a flat surface
FLAT_TOLERANCE = 1e-8


def facet_sizes_and_normals(mesh: Mesh, tag: str) -> tuple[np.ndarray, np.ndarray]:
    """(m,) root mean square of each facet's edges (its size [length]) and (m, d) unit normals
    (up to sign) of the facets of ``tag``: a segment's perpendicular, a polygon's (first
    three vertices' for a triangle, the diagonals' cross product for a quadrilateral)."""
    f = mesh.facets_of(tag)
    f = facet_vertices(f, mesh.dim)  # a quadratic facet's size and plane: its vertices'
    x = mesh.points[f]  # (m, k, d)
    edges = np.roll(x, -1, axis=1) - x
    size = np.sqrt(np.mean(np.sum(edges**2, axis=2), axis=1))
    d = mesh.dim
    if d == 1:
        return size, np.ones((f.shape[0], 1))
    if d == 2:
        t = x[:, 1] - x[:, 0]
        n = np.stack([-t[:, 1], t[:, 0]], axis=1)
    else:
        a, b = (x[:, 2] - x[:, 0], x[:, 1] - x[:, 0]) if f.shape[1] == 3 else (x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
        n = np.cross(a, b)
    return size, n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def _is_flat(normals: np.ndarray) -> bool:
    return bool(normals.shape[0] < 2 or np.min(np.abs(normals @ normals[0])) >= 1.0 - FLAT_TOLERANCE)


def pair_side_warning(mesh: Mesh, pair: ContactPair) -> str:
    """A warning when the pair's slave side is the worse choice for node to facet: coarser
    than the master (:data:`COARSER_SLAVE_RATIO`), or flat against a curved master (the
    curved side's nodes then cross the flat facets between the slave nodes); "" otherwise."""
    hs, ns = facet_sizes_and_normals(mesh, pair.slave)
    hm, nm = facet_sizes_and_normals(mesh, pair.master)
    swap = f"swap them (slave = {pair.master!r}, master = {pair.slave!r})"
    if float(np.mean(hs)) > COARSER_SLAVE_RATIO * float(np.mean(hm)):
        return (
            f"contact pair {pair.slave!r} / {pair.master!r}: the slave side is the coarser one (facets "
            f"{np.mean(hs):.3g} against {np.mean(hm):.3g}); node to facet enforces contact at the slave nodes "
            f"only, so the master's finer nodes may cross between them: {swap} (docs/bodies.md)"
        )
    if mesh.dim > 1 and _is_flat(ns) and not _is_flat(nm):
        return (
            f"contact pair {pair.slave!r} / {pair.master!r}: the slave side is flat and the master curved; the "
            f"curved side touches between the slave nodes, which node to facet does not see (a shorter, "
            f"stiffer contact): {swap} (docs/bodies.md)"
        )
    return ""
