"""Vectorized finite element assembly: stiffness, mass, loads, strain and stress.

Dof numbering of the vector space: node-major, ``dof = d * node + component``.

All element quantities are computed for every element at once with ``einsum``; global
matrices are assembled from the node-to-node sparsity pattern of the mesh, computed
once per mesh (and cached on it), by ``np.bincount`` of the element values onto the
pattern slots.  The vector matrices are built as block-sparse (BSR, d x d blocks on
the node pattern) and returned as CSR.  There is no Python loop over elements or nodes.

A mixed mesh (several cell types, :attr:`Mesh.blocks`) is assembled as the sum of its
one-type parts (:meth:`Mesh.parts`, a loop over the two or three cell types), each with
its cells' materials and weights; per-cell results are concatenated in the mesh's cell
numbering.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from ..errors import MeshError
from .dofmap import DofMap, blocked
from .elements import determinants, jacobians, reference_element
from .material import Material
from .mesh import Mesh, facet_type, one_type, over_blocks, tags_by_facet_type, uniform_cells


# ----------------------------------------------------------------------------- geometry
def geometry(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Quadrature weights times det J and physical shape gradients of every element.

    Returns
    -------
    wdet : (n_cells, nq) array, w_q |det J_e(xi_q)|  [length^d].
    grad : (n_cells, nq, nv, d) array, grad N_a at the quadrature points [1/length].
    """
    return mesh.cached("geometry", lambda: _geometry(mesh))


def _geometry(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    one_type(mesh, "geometry()")  # per-cell arrays of different quadrature sizes: per part
    ref = reference_element(mesh.cell_type)
    X = mesh.points[mesh.cells]  # (ne, nv, d)
    J = jacobians(ref.dN, X)  # J_ik = dx_i / dxi_k
    det = determinants(J) if mesh.dim > 1 else J[..., 0, 0]
    if not np.all(np.abs(det) > 0) or not np.all(np.isfinite(det)):
        bad = np.flatnonzero(~(np.abs(det) > 0).all(axis=1) | ~np.isfinite(det).all(axis=1))
        raise MeshError(f"{bad.size} degenerate element(s) (det J = 0 or not finite), e.g. cells {bad[:5].tolist()}")
    Jinv = np.linalg.inv(J) if mesh.dim > 1 else 1.0 / J
    grad = np.einsum("qak,eqki->eqai", ref.dN, Jinv)
    wdet = np.abs(det) * ref.weights[None, :]
    return wdet, grad


def quadrature_points(mesh: Mesh) -> np.ndarray:
    """Physical coordinates of the quadrature points, shape (n_cells, nq, d)."""
    ref = reference_element(mesh.cell_type)
    return np.einsum("qa,eai->eqi", ref.N, mesh.points[mesh.cells])


def cell_volumes(mesh: Mesh) -> np.ndarray:
    """Measure of every cell, shape (n_cells,)."""
    return over_blocks(mesh, lambda part, _: geometry(part)[0].sum(axis=1), np.concatenate)


def part_material(material: Material, cut: slice) -> Material:
    """The material of the cells ``cut`` of a mixed mesh's part (one material: itself)."""
    return material.take(cut) if hasattr(material, "take") else material


def part_value(value, cut: slice):
    """A number as it is, a per-cell array (n_cells,) restricted to the cells ``cut``."""
    return value if value is None or np.ndim(value) == 0 else np.asarray(value)[cut]


def _element_data(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """(wdet, grad) for all cells, or for the first cell only when cells are uniform."""
    if uniform_cells(mesh):
        sub = Mesh(mesh.points, mesh.cells[:1], mesh.cell_type)
        return geometry(sub)
    return geometry(mesh)


# ----------------------------------------------------------------------------- pattern
def node_pattern(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CSR node-to-node pattern and the slot of every element entry.

    Returns ``(indptr, indices, slot)`` where ``slot`` has shape (n_cells, nv, nv) and
    ``slot[e, a, b]`` is the position of the pair (cells[e,a], cells[e,b]) in ``indices``.
    """
    return mesh.cached("pattern", lambda: _node_pattern(mesh))


def _node_pattern(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    nn = mesh.n_nodes
    c = mesh.cells
    ne, nv = c.shape
    # node adjacency as a sparse product (element->node incidence)^T (element->node incidence)
    inc = sp.csr_matrix((np.ones(c.size), c.ravel(), np.arange(0, c.size + 1, nv)), shape=(ne, nn))
    adj = (inc.T @ inc).tocsr()
    adj.sort_indices()
    # 32-bit indices whenever they fit: scipy's conversions run several times faster
    itype = np.int32 if 9 * adj.nnz < 2**31 and 3 * nn < 2**31 else np.int64
    indptr = adj.indptr.astype(itype)
    indices = adj.indices.astype(itype)
    del adj, inc
    rows = np.repeat(np.arange(nn, dtype=np.int64), np.diff(indptr))
    pattern_keys = rows * nn + indices
    del rows
    slot = np.searchsorted(pattern_keys, (c[:, :, None] * nn + c[:, None, :]).ravel())  # intp: bincount takes it as is
    return indptr, indices, slot.reshape(c.shape[0], c.shape[1], c.shape[1])


def assemble_scalar(mesh: Mesh, Ke: np.ndarray) -> sp.csr_matrix:
    """Assemble element matrices ``Ke`` (n_cells, nv, nv) into a (n_nodes, n_nodes) CSR."""
    indptr, indices, slot = node_pattern(mesh)
    data = np.bincount(slot.ravel(), weights=Ke.ravel(), minlength=indices.size)
    return sp.csr_matrix((data, indices, indptr), shape=(mesh.n_nodes, mesh.n_nodes))


def assemble_nodal(mesh: Mesh, fe: np.ndarray) -> np.ndarray:
    """The node-major vector (n_nodes d,) of element vectors ``fe`` (n_cells, nv, d) summed over the cells
    (one ``np.bincount``, not ``np.add.at``)."""
    d = fe.shape[-1]
    idx = mesh.cached(f"nodal dofs {d}", lambda: DofMap.serial(mesh.n_nodes, d).dofs(mesh.cells.ravel()).ravel())
    return np.bincount(idx, weights=fe.ravel(), minlength=mesh.n_nodes * d)


def assemble_vector(mesh: Mesh, Ke: np.ndarray) -> sp.csr_matrix:
    """Assemble ``Ke`` of shape (n_cells, nv, nv, d, d) (node a, node b, comp i, comp j)
    into the (d n_nodes)^2 CSR matrix with node-major dof numbering."""
    indptr, indices, slot = node_pattern(mesh)
    d = Ke.shape[-1]
    flat = slot.ravel()
    # straight into CSR (no BSR and conversion): dof row (a, i) holds the d * len(a)
    # columns (b, j) of node row a, so entry (i, j) of node entry s (row a) lands at
    # ptr[d a + i] + d (s - indptr[a]) + j = d s + d (d - 1) indptr[a] + i d len(a) + j
    n_rows = mesh.n_nodes * d  # the dofs
    row_len = np.diff(indptr)
    itype = indices.dtype
    ptr = np.zeros(n_rows + 1, dtype=itype)
    np.cumsum(np.repeat(d * row_len, d), out=ptr[1:])
    dest = np.arange(0, d * indices.size, d, dtype=itype)
    dest += np.repeat(d * (d - 1) * indptr[:-1], row_len)
    step = np.repeat(d * row_len, row_len)
    col = d * indices
    data = np.empty(int(ptr[-1]))
    cols = np.empty(int(ptr[-1]), dtype=itype)
    weights = np.empty(Ke.shape[:3])  # one buffer for the d^2 components (no copy of each)
    for i in range(d):
        for j in range(d):
            np.copyto(weights, Ke[..., i, j])
            data[dest] = np.bincount(flat, weights=weights.ravel(), minlength=indices.size)
            cols[dest] = col
            dest += 1
            col += 1
        dest += step - d
        col -= d
    out = sp.csr_matrix((n_rows, n_rows))
    out.indptr, out.indices, out.data = ptr, cols, data  # set after construction: no check of the large arrays
    out.has_canonical_format = True  # sorted, one entry per pair of nodes: saves scipy's scans
    return out


# ----------------------------------------------------------------------------- operators
def per_cell(value: float | np.ndarray, ndim: int) -> float | np.ndarray:
    """A material datum as a factor of element arrays with ``ndim`` axes: a number as it is,
    a per-cell array (n_cells,) as (n_cells, 1, ..., 1)."""
    if np.ndim(value) == 0:
        return value
    return np.asarray(value, dtype=float).reshape((-1,) + (1,) * (ndim - 1))


def stiffness_matrix(mesh: Mesh, material: Material) -> sp.csr_matrix:
    """Elastic stiffness S_ij = a(phi_i, phi_j) = int sigma(phi_i) : eps(phi_j) dx.

    Element block for nodes a, b and components i, j::

        K[a,b,i,j] = int lam dN_a/dx_i dN_b/dx_j + mu (delta_ij grad N_a . grad N_b
                     + dN_a/dx_j dN_b/dx_i) dx

    In 1D: K[a,b] = int E N_a' N_b' dx.  Units: [force / length].  ``material``: one
    :class:`~signorini.fem.material.IsotropicElastic`, or a
    :class:`~signorini.fem.material.CellMaterial` (lam, mu per cell: regions of different materials).
    """
    return over_blocks(mesh, lambda part, cut: _stiffness(part, part_material(material, cut)), sum_of)


def _stiffness(mesh: Mesh, material: Material, factor: np.ndarray | None = None) -> sp.csr_matrix:
    """The stiffness of a one-type mesh (each element matrix times ``factor``, if given)."""
    Ke = element_stiffness_matrices(mesh, material)
    if factor is not None:
        Ke = Ke * per_cell(factor, Ke.ndim)
    if mesh.dim == 1:
        return assemble_scalar(mesh, Ke[..., 0, 0])
    return assemble_vector(mesh, Ke)


def scaled_stiffness(mesh: Mesh, material: Material, factor: np.ndarray) -> sp.csr_matrix:
    """sum_c factor_c S_c: the stiffness with each cell's element matrix times ``factor`` (n_cells,) (a
    stiffness-proportional damping per region) [force / length]."""
    return over_blocks(mesh, lambda part, cut: _stiffness(part, part_material(material, cut), factor[cut]), sum_of)


def sum_of(matrices) -> sp.csr_matrix:
    """The sum of a mixed mesh's parts' matrices (CSR, canonical)."""
    out = None
    for m in matrices:
        out = m if out is None else out + m
    out = sp.csr_matrix(out)
    out.sum_duplicates()
    out.sort_indices()
    return out


def element_stiffness_matrices(mesh: Mesh, material: Material) -> np.ndarray:
    """The element blocks K[e, a, b, i, j] of :func:`stiffness_matrix`, shape (n_cells, nv, nv, d, d)
    (a broadcast view of one cell's when the cells are translates of each other)."""
    wdet, G = _element_data(mesh)
    if mesh.dim == 1:
        Ke = per_cell(material.young, 3) * np.einsum("eq,eqa,eqb->eab", wdet, G[..., 0], G[..., 0])
        return np.broadcast_to(Ke, (mesh.n_cells,) + Ke.shape[1:])[..., None, None]
    e, q, nv, d = G.shape
    # K2[e, a, i, b, j] = sum_q w_q det J G[q, a, i] G[q, b, j], one batched matmul
    Gw = (G * wdet[:, :, None, None]).reshape(e, q, nv * d)
    K2 = np.matmul(Gw.transpose(0, 2, 1), G.reshape(e, q, nv * d)).reshape(e, nv, d, nv, d)
    lam, mu = per_cell(material.lam, 5), per_cell(material.mu, 5)
    Ke = lam * K2.transpose(0, 1, 3, 2, 4) + mu * K2.transpose(0, 1, 3, 4, 2)
    lap = np.einsum("eakbk->eab", K2)
    idx = np.arange(d)
    Ke[:, :, :, idx, idx] += per_cell(material.mu, 4) * lap[..., None]
    if Ke.shape[0] != mesh.n_cells:  # identical elements: one matrix for all
        Ke = np.broadcast_to(Ke, (mesh.n_cells,) + Ke.shape[1:])
    return Ke


def element_mass_matrices(mesh: Mesh, rho: float | np.ndarray = 1.0) -> np.ndarray:
    """rho int_K N_a N_b dx for every cell K, shape (n_cells, nv, nv) (a broadcast view of one
    cell's matrix when the cells are translates of each other and rho is one number);
    ``rho`` a number or one density per cell (n_cells,)."""
    ref = reference_element(mesh.cell_type)
    wdet, _ = _element_data(mesh)
    Ke = per_cell(rho, 3) * np.einsum("eq,qa,qb->eab", wdet, ref.N, ref.N)
    if Ke.shape[0] != mesh.n_cells:
        Ke = np.broadcast_to(Ke, (mesh.n_cells,) + Ke.shape[1:])
    return Ke


def scalar_mass_matrix(
    mesh: Mesh, rho: float | np.ndarray = 1.0, cell_weight: np.ndarray | None = None
) -> sp.csr_matrix:
    """Scalar consistent mass m_ab = int rho w_e N_a N_b dx, shape (n_nodes, n_nodes).

    ``cell_weight`` (n_cells,) multiplies each element's contribution (0 drops it; this
    is how the ``seed`` mass removes the elements touching the contact boundary).
    """

    def one(part: Mesh, cut: slice) -> sp.csr_matrix:
        Ke = element_mass_matrices(part, part_value(rho, cut))
        if cell_weight is not None:
            Ke = Ke * np.asarray(part_value(cell_weight, cut), dtype=float)[:, None, None]
        return assemble_scalar(part, Ke)

    return over_blocks(mesh, one, sum_of)


def vectorize(m: sp.spmatrix, dim: int) -> sp.csr_matrix:
    """Vector matrix m (x) I_d for node-major dofs (entries only on the diagonal of blocks).

    Entry s of node row a goes to dof row (a, i) at position s + (d - 1) indptr[a] +
    i len(a): d scatters of m's arrays, no per-entry index table (8x faster on 9M entries).
    """
    m = sp.csr_matrix(m)
    if dim == 1:
        return m
    m.sort_indices()
    canonical = m.has_canonical_format  # duplicates, if any, are kept as they are
    nn, nnz = m.shape[0], m.nnz
    itype = np.int32 if dim * max(nnz, m.shape[1]) < 2**31 else np.int64
    length = np.diff(m.indptr).astype(itype)
    n_rows = nn * dim  # the dofs
    ptr = np.zeros(n_rows + 1, dtype=itype)
    np.cumsum(np.repeat(length, dim), out=ptr[1:])
    dest = np.arange(nnz, dtype=itype)
    dest += np.repeat((dim - 1) * m.indptr[:-1].astype(itype), length)
    step = np.repeat(length, length)
    col = dim * m.indices.astype(itype)
    data = np.empty(dim * nnz, dtype=np.result_type(m.dtype, np.float64))
    cols = np.empty(dim * nnz, dtype=itype)
    for i in range(dim):  # the d components, not entries
        data[dest] = m.data
        cols[dest] = col
        if i + 1 < dim:
            dest += step
            col += 1
    out = sp.csr_matrix((dim * nn, dim * m.shape[1]), dtype=data.dtype)
    out.indptr, out.indices, out.data = ptr, cols, data  # set after construction: no check of the large arrays
    out.has_canonical_format = canonical
    out.has_sorted_indices = True
    return out


def mass_matrix(mesh: Mesh, rho: float | np.ndarray = 1.0) -> sp.csr_matrix:
    """Consistent vector mass matrix M = int rho phi_i . phi_j dx [mass] (``rho`` a number or
    one density per cell)."""
    return vectorize(scalar_mass_matrix(mesh, rho), mesh.dim)


def lumped_mass_matrix(M: sp.spmatrix) -> sp.dia_matrix:
    """Row-sum lumped mass: diag(sum_j M_ij)."""
    return sp.diags(np.asarray(M.sum(axis=1)).ravel(), format="csr")


def hrz_lumped_mass(mesh: Mesh, rho: float | np.ndarray = 1.0) -> sp.csr_matrix:
    """Scalar HRZ (Hinton-Rock-Zienkiewicz) lumped mass, (n_nodes, n_nodes) diagonal: each cell's consistent
    diagonal scaled to the cell's mass, m_a = sum_K m_K M^K_aa / sum_b M^K_bb.  Every nodal mass is positive on
    every cell type; on quadratic cells the row sum is not (a ``triangle6``'s vertices get 0, a ``tetra10``'s
    -1/20 of the cell); HRZ gives them 1/19 and 1/36 (spec section 16), a ``hexahedron27`` the Gauss-Lobatto
    (Simpson) weights 1/216, 4/216, 16/216, 64/216."""

    def one(part: Mesh, cut: slice) -> np.ndarray:
        wdet = geometry(part)[0] * np.reshape(per_cell(part_value(rho, cut), 2), (-1, 1))
        share = hrz_shares(wdet, reference_element(part.cell_type).N)
        return np.bincount(part.cells.ravel(), weights=share.ravel(), minlength=mesh.n_nodes)

    return sp.diags(over_blocks(mesh, one, lambda parts: np.sum(parts, axis=0)), format="csr")


def hrz_shares(wdet: np.ndarray, N: np.ndarray) -> np.ndarray:
    """(e, nv) each cell's (or facet's) measure sum_q wdet_eq shared by HRZ: in proportion to the diagonal of its
    consistent mass, sum_q wdet_eq N_qa^2 (``wdet`` (e, q) the weights times det J, or times rho too; ``N`` (q, nv)
    the shape functions at the points)."""
    diag = wdet @ N**2
    return diag * (wdet.sum(axis=1) / diag.sum(axis=1))[:, None]


def body_load(mesh: Mesh, f: np.ndarray | Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Load vector F_(a,i) = int f_i N_a dx for a body force density f [force/length^d].

    ``f`` is a constant vector of length d or a function of points (n, d) -> (n, d).
    """
    return over_blocks(mesh, lambda part, _: _body_load(part, f), sum)


def _body_load(mesh: Mesh, f) -> np.ndarray:
    """:func:`body_load` on a one-type mesh."""
    ref = reference_element(mesh.cell_type)
    wdet, _ = geometry(mesh)
    xq = quadrature_points(mesh)
    if callable(f):
        fq = np.asarray(f(xq.reshape(-1, mesh.dim)), dtype=float).reshape(xq.shape)
    else:
        fq = np.broadcast_to(np.asarray(f, dtype=float), xq.shape)
    fe = np.einsum("eq,qa,eqi->eai", wdet, ref.N, fq)
    F = np.zeros((mesh.n_nodes, mesh.dim))
    for i in range(mesh.dim):
        F[:, i] = np.bincount(mesh.cells.ravel(), weights=fe[..., i].ravel(), minlength=mesh.n_nodes)
    return F.ravel()


def facet_weights(mesh: Mesh, tag: str, positive: bool = False) -> np.ndarray:
    """Nodal boundary weights w_a = int_{Gamma_tag} N_a ds, shape (n_nodes,) [length^(d-1)].

    In 1D every tagged point has weight 1 (a unit cross-section).  Several tags: their union (each facet once;
    tags of several facet types, a mixed mesh's triangles and quads, summed type by type).  ``positive``: the
    weights of nodal contact,
    positive at every node of a facet: the integrals where the facet type's are all positive, else each facet's
    area shared by HRZ (:func:`hrz_shares`): ``triangle6`` facets, whose vertices' integral is 0 (HRZ: vertices
    1/19, edges 16/57, spec section 16), and ``quad8`` ones (serendipity: -1/12 of the area at a corner); on
    ``line3`` and ``quad9`` facets the integrals are positive (1/6, 2/3; 1/36, 1/9, 4/9 of a straight facet) and
    are the HRZ shares already.
    """
    if not isinstance(tag, str) and len(groups := tags_by_facet_type(mesh, tag)) > 1:
        return sum(facet_weights(mesh, group, positive) for group in groups)
    facets = mesh.facets_of(tag)
    if mesh.dim == 1:
        return np.bincount(facets.ravel(), minlength=mesh.n_nodes).astype(float)
    fref = reference_element(facet_type(facets, mesh.dim))
    X = mesh.points[facets]  # (nf, nfv, d)
    J = np.einsum("qak,fai->fqik", fref.dN, X)  # (nf, nq, d, d-1)
    area = np.sqrt(np.abs(np.linalg.det(np.einsum("fqik,fqil->fqkl", J, J))))
    if positive and not np.all(fref.weights @ fref.N > 0):
        we = hrz_shares(area * fref.weights, fref.N)
    else:
        we = np.einsum("fq,q,qa->fa", area, fref.weights, fref.N)
    return np.bincount(facets.ravel(), weights=we.ravel(), minlength=mesh.n_nodes)


def surface_load(mesh: Mesh, tag: str, traction: np.ndarray | Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Load vector of a traction t on the facets of ``tag``: F_(a,i) = int_Gamma t_i N_a ds.

    ``traction`` is a constant vector (exact: t_i w_a with the facet weights) or a
    function of points (n, d) -> (n, d) integrated with the facet quadrature rule.
    """
    if not callable(traction):
        w = facet_weights(mesh, tag)
        t = np.asarray(traction, dtype=float).reshape(1, -1)
        return (w[:, None] * t).ravel()
    facets = mesh.facets_of(tag)
    if mesh.dim == 1:
        x = mesh.points[facets[:, 0]]
        t = np.asarray(traction(x), dtype=float).reshape(len(facets), 1)
        F = np.zeros((mesh.n_nodes, 1))
        np.add.at(F, facets[:, 0], t)
        return F.ravel()
    fref = reference_element(facet_type(facets, mesh.dim))
    X = mesh.points[facets]  # (nf, nfv, d)
    J = np.einsum("qak,fai->fqik", fref.dN, X)
    area = np.sqrt(np.abs(np.linalg.det(np.einsum("fqik,fqil->fqkl", J, J))))  # (nf, nq)
    xq = np.einsum("qa,fai->fqi", fref.N, X)
    tq = np.asarray(traction(xq.reshape(-1, mesh.dim)), dtype=float).reshape(xq.shape)
    fe = np.einsum("fq,q,qa,fqi->fai", area, fref.weights, fref.N, tq)
    F = np.zeros((mesh.n_nodes, mesh.dim))
    for i in range(mesh.dim):
        F[:, i] = np.bincount(facets.ravel(), weights=fe[..., i].ravel(), minlength=mesh.n_nodes)
    return F.ravel()


def gradient_operator(cells: np.ndarray, grads: np.ndarray, n_nodes: int) -> sp.csr_matrix:
    """D (e d d, n_nodes d) [1/length] with (D U)_(e,i,J) = sum_a u_ai grads_eaJ, u_ai = U[d cells_ea + i]: each
    cell's displacement gradient from one set of shape gradients per cell, ``grads`` (e, nv, d) (a P1 cell's
    constant ones, or a cell's mean).  Rows numbered by (e, i, J) (the gradient's entries, not dofs); nv d
    nonzeros per row."""
    e, nv, d = grads.shape
    E, A, i, J = np.meshgrid(np.arange(e), np.arange(nv), np.arange(d), np.arange(d), indexing="ij")
    rows = np.ravel_multi_index((E.ravel(), i.ravel(), J.ravel()), (e, d, d))
    cols = blocked(cells[E, A].ravel(), d, None)[np.arange(E.size), i.ravel()]
    return sp.csr_matrix((grads[E, A, J].ravel(), (rows, cols)), shape=(e * d * d, n_nodes * d))


# ----------------------------------------------------------------------------- post-processing
def strain(mesh: Mesh, u: np.ndarray) -> np.ndarray:
    """Small strain eps = sym(grad u) at the quadrature points, shape (n_cells, nq, d, d)."""
    _, G = geometry(mesh)
    ue = np.asarray(u).reshape(mesh.n_nodes, mesh.dim)[mesh.cells]  # (ne, nv, d)
    gu = np.matmul(np.swapaxes(ue, 1, 2)[:, None], G)  # gu_eqij = sum_a ue_eai G_eqaj (batched matmul, 3.6x einsum)
    return 0.5 * (gu + np.swapaxes(gu, -1, -2))


def nodal_average(mesh: Mesh, cell_values: np.ndarray) -> np.ndarray:
    """Volume-weighted average at the nodes of per-cell values (n_cells, ...)."""
    vol = cell_volumes(mesh)
    flat = cell_values.reshape(mesh.n_cells, -1)
    out = np.zeros((mesh.n_nodes, flat.shape[1]))
    den = np.zeros(mesh.n_nodes)
    for b in mesh.blocks:  # one cell type at a time (one block unless the mesh is mixed)
        idx, nv = b.cells.ravel(), b.cells.shape[1]
        v = vol[b.start : b.stop]
        den += np.bincount(idx, weights=np.repeat(v, nv), minlength=mesh.n_nodes)
        for k in range(flat.shape[1]):
            out[:, k] += np.bincount(idx, weights=np.repeat(v * flat[b.start : b.stop, k], nv), minlength=mesh.n_nodes)
    out /= den[:, None]
    return out.reshape((mesh.n_nodes,) + cell_values.shape[1:])


def cell_means(
    mesh: Mesh, material: Material, u: np.ndarray, tensors: bool = True
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """The cell means (over the quadrature points, weighted by |J| w) of the von Mises stress (n_cells,) and, with
    ``tensors``, of the small strain and the Cauchy stress of ``u`` as 3D tensors (n_cells, 3, 3) each (plane
    strain in 2D: eps_zz = 0, sigma_zz = lam tr(eps); in 1D the bar's axial eps_xx and sigma_xx = E eps_xx, the
    other components 0) [Pa, -, Pa]; (vm, None, None) without.  One strain per quadrature point for all three."""

    def one(part: Mesh, cut: slice) -> np.ndarray:
        wdet, _ = geometry(part)
        eps = strain(part, u)
        mat = part_material(material, cut)
        vol = wdet.sum(axis=1)
        vm = ((mat.von_mises(eps) * wdet).sum(axis=1) / vol)[:, None]
        if not tensors:
            return vm
        d = eps.shape[-1]
        e3 = np.zeros(eps.shape[:-2] + (3, 3))
        e3[..., :d, :d] = eps
        mean = lambda a: (np.einsum("eq,eqij->eij", wdet, a) / vol[:, None, None]).reshape(-1, 9)  # noqa: E731
        return np.hstack([vm, mean(e3), mean(mat.stress3(eps))])

    out = over_blocks(mesh, one, np.concatenate)
    if not tensors:
        return out[:, 0], None, None
    return out[:, 0], out[:, 1:10].reshape(-1, 3, 3), out[:, 10:].reshape(-1, 3, 3)


def von_mises(mesh: Mesh, material: Material, u: np.ndarray, nodal: bool = True) -> np.ndarray:
    """von Mises stress of the displacement ``u``: per cell (mean over quadrature
    points) or, with ``nodal=True``, averaged at the nodes."""
    cell = cell_means(mesh, material, u, tensors=False)[0]
    return nodal_average(mesh, cell) if nodal else cell


def cell_tensors(mesh: Mesh, material: Material, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cell means of the small strain and of the Cauchy stress of ``u``, (n_cells, 3, 3) each [-, Pa]
    (:func:`cell_means`)."""
    _, eps, sig = cell_means(mesh, material, u)
    return eps, sig


def stress(mesh: Mesh, material: Material, u: np.ndarray, nodal: bool = True) -> np.ndarray:
    """Cauchy stress: cell means (n_cells, d, d) or nodal averages (n_nodes, d, d)."""
    d = mesh.dim
    cell = cell_means(mesh, material, u)[2][:, :d, :d]
    return nodal_average(mesh, cell) if nodal else cell
