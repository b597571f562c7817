"""Mass matrices for dynamic contact, chosen by name from one registry.

=====================  =========================================================  ==============
name                   definition                                                 kernel
=====================  =========================================================  ==============
``standard``           M_ij = rho int_Omega phi_i . phi_j                         {0}
``lumped``             diag(sum_j M_ij)                                           {0}
``seed``               rho int over the elements that do not touch Gamma_C        all components
                       (the seed paper's M_mod, GetFEM ``singular_mass=1``)        of contact nodes
``seed-normal``        ``seed`` for the normal component, ``standard`` for the    normal comps
                       tangential ones, through the nodal frames (any obstacle;    of contact nodes
                       :func:`seed_normal_mass`): the tangential inertia that
                       friction acts on is kept
``moment-preserving``  contact rows/columns removed, the mass put back so that    all components
                       total mass, first and second moments are preserved          of contact nodes
                       (T^T M T, any mesh)
``moment-preserving-   the same constraints in tensor form on generated            all components
tensor``               structured grids (a different matrix in 2D/3D)              of contact nodes
``neighbour``          contact rows/columns removed; the mass of each contact      all components
                       node put on the diagonal of its non-contact neighbours      of contact nodes
                       in proportion to their coupling M_ij; total mass
                       preserved, PSD by construction (not Dabaghi et al.'s
                       weighted choices, which could not be recovered:
                       docs/literature/competing-schemes.md, section 4b)
``mass-free-surface``  cells touching Gamma_C integrate their mass with a nodal   all components
                       rule on their non-contact nodes (equal weights; Hager-      of contact nodes
                       Wohlmuth's mass-free surface elements); total mass kept
``mixed-velocity``     W^T C^-1 W: the kinetic energy of the velocity projected   ker W (not dofs)
                       on the P1/Q1 functions of the vertices that are not
                       contact nodes (:mod:`.mixed_velocity`; Hauret's
                       equivalent mass)
=====================  =========================================================  ==============

The moment-preserving matrix uses, per component, the scalar redistribution
``M_red = M_0 + Delta`` where ``M_0`` is ``M`` with the contact rows and columns zeroed
and ``Delta`` changes only entries between non-contact nodes near Gamma_C, chosen so
that ``p^T M_red q = p^T M q`` for all p, q in {1, x_1, ..., x_d}:

* ``moment-preserving`` (every mesh): ``M_red = T^T M T`` where T extrapolates the
  contact nodes' values from the non-contact nodes within two layers, exactly for
  affine functions (minimum-norm weights).  Moments are then preserved exactly and
  M_red is symmetric positive semi-definite by construction.  It depends on the
  geometry and connectivity only: a generated mesh and the same mesh read from a file
  give the same matrix, and rotating the mesh does not change it.
* ``moment-preserving-tensor`` (generated structured grids, contact on one full side):
  the 1D closed form below across the contact side, tensorized with the consistent 1D
  mass along the other directions, ``M = M_x (x) M_y (x) M_z``.  A different matrix in
  2D/3D (its extrapolation uses the nodes of the same grid line only).
* 1D P1, where both coincide: only the entries (1,1), (1,2), (2,2) next to the contact
  node change; three constraints, three unknowns.  For a uniform grid this gives
  M_11 = 8h/3, M_12 = -2h/3, M_22 = h (rho = 1), i.e. u_0 = 2 u_1 - u_2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ...errors import InputError
from ...fem.assembly import (
    assemble_vector,
    element_mass_matrices,
    hrz_lumped_mass,
    lumped_mass_matrix,
    part_value,
    scalar_mass_matrix,
    sum_of,
    vectorize,
)
from ...fem.dofmap import n_blocks
from ...fem.mesh import Mesh, over_blocks
from ...linalg.row_block import RowBlock
from ...linalg.sparse import count_per_row
from ...registry import Registry
from .extrapolation import extrapolation_operator, nearest_free_nodes
from .mixed_velocity import mass_of, mixed_velocity_scalar_mass, velocity_pairings

#: the mass variant of a run that names none: it keeps the total mass, the centre of mass
#: and the inertia of the body exactly, on any mesh (docs/design.md, "The default mass")
DEFAULT_MASS = "moment-preserving"
#: the variants written M_red = T^T M T with an affine extrapolation T (loads follow T)
EXTRAPOLATED = ("moment-preserving",)
#: the variants defined on quadratic cells only (refused by name on linear cells: :mod:`.mixed_velocity`)
QUADRATIC_ONLY = ("mixed-velocity",)
#: the variants that read a generated grid's node numbering (``Mesh.grid``): a renumbered grid cannot carry them
GRID_MASSES = ("moment-preserving-tensor",)


def _needs_contact(name: str, contact_nodes: np.ndarray | None) -> np.ndarray:
    if contact_nodes is None or len(contact_nodes) == 0:
        raise InputError(f"mass {name!r} needs contact nodes (a non-empty contact boundary)")
    return np.asarray(contact_nodes)


def _standard(mesh: Mesh, rho: float, contact_nodes=None, normals=None) -> sp.csr_matrix:
    return vectorize(scalar_mass_matrix(mesh, rho), mesh.dim)


def _lumped(mesh: Mesh, rho: float, contact_nodes=None, normals=None) -> sp.csr_matrix:
    if mesh.order == 2:  # the row sum is zero or negative at the vertices: HRZ
        return vectorize(hrz_lumped_mass(mesh, rho), mesh.dim)
    return vectorize(lumped_mass_matrix(scalar_mass_matrix(mesh, rho)), mesh.dim)


def _scalar_variant(name: str, build):
    """A variant that applies the scalar redistribution ``build`` to every component."""

    def variant(mesh: Mesh, rho: float, contact_nodes=None, normals=None) -> sp.csr_matrix:
        return vectorize(build(mesh, rho, _needs_contact(name, contact_nodes)), mesh.dim)

    return variant


def _seed_normal(mesh: Mesh, rho: float, contact_nodes=None, normals=None) -> sp.csr_matrix:
    return seed_normal_mass(mesh, rho, _needs_contact("seed-normal", contact_nodes), normals)


MASS_VARIANTS = Registry("mass")


def mass_matrix(
    name: str,
    mesh: Mesh,
    rho: float,
    contact_nodes: np.ndarray | None = None,
    normals: np.ndarray | None = None,
) -> sp.csr_matrix:
    """Vector mass matrix of variant ``name`` (node-major dofs, full space).

    Parameters
    ----------
    name : a name (or alias) of :data:`MASS_VARIANTS`.
    mesh : the mesh.
    rho : density [mass / length^d]: a number, or one per cell (n_cells,) for regions of
        different materials.
    contact_nodes : node indices on Gamma_C (needed by the redistributed variants).
    normals : (n_contact, d) outward unit normals at the contact nodes (``seed-normal``).
    """
    return MASS_VARIANTS.get(name).obj(mesh, rho, contact_nodes, normals)


@dataclass
class Redistribution:
    """A mass variant applied to a body: its matrix and how the body forces follow it.

    Attributes
    ----------
    name : the variant's registry name.
    M : (d n, d n) vector mass matrix (node-major dofs).
    T : (n, n) scalar affine extrapolation of the contact nodes for the variants
        M = T^T M_consistent T (:data:`EXTRAPOLATED`), else None.
    W : (d n_v, d n) the velocity space's pairing of ``mixed-velocity`` (M = W^T C^-1 W, ker M = ker W), else None.

    A body force follows the mass (:meth:`body_load`): a force per unit volume that is
    the same everywhere, f = rho g, is applied as ``M g`` (a load per unit mass: the
    body falls rigidly, without stress, with every variant, and its weight is the mass
    the variant keeps); a force varying in space through ``T^T F`` with the consistent
    load F (then ``T^T F = M g`` again for a uniform f); the other variants take F as it is.
    """

    name: str
    M: sp.csr_matrix
    T: sp.csr_matrix | None = None
    W: sp.csr_matrix | None = None

    def body_load(self, F: np.ndarray, uniform: np.ndarray | None, rho: float) -> np.ndarray:
        """The load applied for the consistent body load ``F`` (d n,) [force].

        ``uniform`` is the force density [force / length^d] when it is the same at every
        point (then the load is ``M (uniform / rho)``), else None.
        """
        if uniform is not None:
            d = uniform.size
            return self.M @ np.tile(uniform / rho, n_blocks(self.M.shape[0], d))
        if self.T is None:
            return F
        d = F.size // self.T.shape[0]
        return (self.T.T @ F.reshape(-1, d)).ravel()


def redistribute(
    name: str, mesh: Mesh, rho: float, contact_nodes: np.ndarray | None = None, normals: np.ndarray | None = None
) -> Redistribution:
    """The :class:`Redistribution` of variant ``name`` (arguments as :func:`mass_matrix`)."""
    name = MASS_VARIANTS.resolve(name)
    if name in EXTRAPOLATED:
        T = extrapolation_operator(mesh, _needs_contact(name, contact_nodes), name)
        M = (T.T @ scalar_mass_matrix(mesh, rho).tocsr() @ T).tocsr()
        M.eliminate_zeros()
        return Redistribution(name, vectorize(M, mesh.dim), T)
    if name == "mixed-velocity":  # W and C assembled once: the mass and the kernel's pairing
        W, C = velocity_pairings(mesh, rho, contact_nodes)
        return Redistribution(name, vectorize(mass_of(W, C), mesh.dim), W=vectorize(W, mesh.dim))
    return Redistribution(name, mass_matrix(name, mesh, rho, contact_nodes, normals))


def linear_cell_variants() -> list[str]:
    """The variants' names (no aliases) defined on linear cells: all but :data:`QUADRATIC_ONLY`."""
    return [n for n in MASS_VARIANTS.names(aliases=False) if n not in QUADRATIC_ONLY]


def massless_dofs(M: sp.spmatrix | RowBlock) -> np.ndarray:
    """Dofs whose row of ``M`` is identically zero (of every rank's rows, for a
    :class:`~signorini.linalg.row_block.RowBlock`)."""
    if isinstance(M, RowBlock):
        mine = massless_dofs(M.local) + M.lo
        return np.concatenate(M.comm.gather(mine)).astype(np.int64)
    M = sp.csr_matrix(M)
    return np.flatnonzero(count_per_row(M.data != 0.0, M.indptr) == 0)


# ----------------------------------------------------------------------------- seed
def touching_cells(mesh: Mesh, nodes: np.ndarray) -> np.ndarray:
    """Boolean mask of the cells that have at least one node in ``nodes``."""
    mark = np.zeros(mesh.n_nodes, dtype=bool)
    mark[nodes] = True
    return np.concatenate([mark[b.cells].any(axis=1) for b in mesh.blocks])


#: the variants that are not defined on quadratic cells, and why (a refusal by name, issue 54)
LINEAR_ONLY = {
    "seed": "it drops the cells touching the contact boundary, and on quadratic cells that also leaves the mid-side "
    "nodes inside them without mass",
    "seed-normal": "it drops the cells touching the contact boundary (normal part), and on quadratic cells that also "
    "leaves the mid-side nodes inside them without normal mass",
    "neighbour": "its shares M_ij / c_i have both signs on quadratic cells: the mass is indefinite (a negative "
    "eigenvalue of 7-24% of the largest on quad9, tetra10, hexahedron27)",
}


def _linear_only(mesh: Mesh, name: str) -> None:
    """InputError for a variant of :data:`LINEAR_ONLY` on a mesh of quadratic cells."""
    if mesh.order != 1:
        raise InputError(
            f"mass {name!r} is defined on linear cells only: {LINEAR_ONLY[name]}; use "
            "'moment-preserving' (the default), 'mass-free-surface', 'lumped' or 'standard'"
        )


def seed_scalar_mass(mesh: Mesh, rho: float, contact_nodes: np.ndarray) -> sp.csr_matrix:
    """M_mod: rho int over Omega_mod = union of cells K with K cap Gamma_C empty."""
    _linear_only(mesh, "seed")
    keep = ~touching_cells(mesh, contact_nodes)
    return scalar_mass_matrix(mesh, rho, cell_weight=keep.astype(float))


def seed_normal_mass(mesh: Mesh, rho: float, contact_nodes: np.ndarray, normals: np.ndarray | None) -> sp.csr_matrix:
    """The seed mass in the normal direction only, through the nodal frames (any obstacle).

    M = M_mod (x) I + sum over the cells K touching Gamma_C of P_K (M_K (x) I) P_K, with M_mod
    the ``seed`` scalar mass (cells not touching Gamma_C), M_K the scalar mass of cell K and
    P_K = blockdiag(I - n_a n_a^T) over K's nodes a: n_a the unit normal nu_a of a contact
    node, and for the other nodes of K the normalized mean of the normals of K's contact
    nodes.  Each term is a congruence of a positive semi-definite matrix (M is one), the
    normal component of every contact node is massless (M_mod has no row for it, P_K removes
    it) and its tangential components keep their standard inertia.  On a flat contact
    boundary (all n_a = n) it is M_mod (x) n n^T + M_std (x) (I - n n^T): the seed mass for the
    normal component, the standard mass for the tangential ones (and, for n = +-e_k, the
    construction of the seed paper's normal-only variant).  Normals are those of t = 0.
    """
    _linear_only(mesh, "seed-normal")
    d = mesh.dim
    if normals is None:
        raise InputError("mass 'seed-normal' needs the contact normals")
    nu = np.asarray(normals, dtype=float)
    out = vectorize(seed_scalar_mass(mesh, rho, contact_nodes), d)  # the seed part on the whole mesh

    def present(parts: list) -> sp.csr_matrix | None:
        parts = [m for m in parts if m is not None]
        return sum_of(parts) if parts else None

    # the projected part per cell type
    projected = over_blocks(
        mesh, lambda part, cut: _projected_mass(part, part_value(rho, cut), contact_nodes, nu), present
    )
    return out if projected is None else (out + projected).tocsr()


def _projected_mass(mesh: Mesh, rho, contact_nodes: np.ndarray, nu: np.ndarray) -> sp.csr_matrix | None:
    """sum over the cells K touching Gamma_C of P_K (M_K (x) I) P_K on a one-type mesh
    (:func:`seed_normal_mass`), made exactly symmetric; None when no cell touches Gamma_C."""
    d = mesh.dim
    cells = mesh.cells
    near = touching_cells(mesh, contact_nodes)
    if not near.any():
        return None
    # the unit normal of every contact node (n_nodes, d), zero elsewhere
    node_normal = np.zeros((mesh.n_nodes, d))
    node_normal[contact_nodes] = nu
    sub = cells[near]
    is_c = np.zeros(mesh.n_nodes, dtype=bool)
    is_c[contact_nodes] = True
    n_a = node_normal[sub]  # (m, nv, d)
    mean = n_a.sum(axis=1)
    norm = np.linalg.norm(mean, axis=1)
    first = n_a[np.arange(sub.shape[0]), np.argmax(is_c[sub], axis=1)]
    cell_n = np.where((norm > 1e-12)[:, None], mean / np.where(norm > 1e-12, norm, 1.0)[:, None], first)
    n_a = np.where(is_c[sub][:, :, None], n_a, cell_n[:, None, :])
    P = np.eye(d) - n_a[..., :, None] * n_a[..., None, :]  # (m, nv, d, d)
    Ke = element_mass_matrices(mesh, rho)[near]  # (m, nv, nv)
    Kv = Ke[:, :, :, None, None] * np.einsum("eaik,ebkj->eabij", P, P)
    near_part = assemble_vector(Mesh(mesh.points, sub, mesh.cell_type), Kv)
    return 0.5 * (near_part + near_part.T)  # exactly symmetric (P_a P_b vs P_b P_a round-off)


# ----------------------------------------------------------------------------- other redistributions
def neighbour_scalar_mass(mesh: Mesh, rho: float, contact_nodes: np.ndarray) -> sp.csr_matrix:
    """Zero the contact rows/columns and put the removed mass back on the diagonal.

    Contact node i loses its row sum m_i and its couplings c_i = sum_{k not in C} M_ik
    to non-contact nodes (their columns); R_i = m_i + c_i goes to each non-contact
    neighbour j in proportion M_ij / c_i.  In 1D P1: M_11 += M_00 + 2 M_01 = 2h/3.
    """
    _linear_only(mesh, "neighbour")
    M = scalar_mass_matrix(mesh, rho).tocsr()
    n = mesh.n_nodes
    is_c = np.zeros(n, dtype=bool)
    is_c[contact_nodes] = True
    keep = sp.diags((~is_c).astype(float))
    Mc = M[contact_nodes]  # rows of the contact nodes
    m = np.asarray(Mc.sum(axis=1)).ravel()
    toward = (Mc @ keep).tocsr()  # couplings to non-contact nodes only
    denom = np.asarray(toward.sum(axis=1)).ravel()
    alone = denom <= 0  # no non-contact neighbour (an edge of a body whose skin is all contact)
    # removed mass of node i: its row (m_i) and its column towards non-contact nodes
    scale = np.where(alone, 0.0, (m + denom) / np.where(alone, 1.0, denom))
    add = np.asarray((sp.diags(scale) @ toward).sum(axis=0)).ravel()
    if alone.any():  # its mass goes in equal shares to the nearest non-contact nodes
        seeds = sp.csr_matrix(
            (np.ones(int(alone.sum())), (np.arange(int(alone.sum())), contact_nodes[alone])), shape=(alone.sum(), n)
        )
        near = nearest_free_nodes(mesh, seeds, is_c, "neighbour")
        add += near.T @ m[alone]
    return (keep @ M @ keep + sp.diags(add)).tocsr()


def mass_free_surface_scalar_mass(mesh: Mesh, rho: float, contact_nodes: np.ndarray) -> sp.csr_matrix:
    """Consistent mass on cells away from Gamma_C; on cells touching it, the cell mass
    rho |K| split equally on the cell's non-contact nodes (diagonal)."""
    from ...fem.assembly import cell_volumes

    touch = touching_cells(mesh, contact_nodes)
    M = scalar_mass_matrix(mesh, rho, cell_weight=(~touch).astype(float))
    is_c = np.zeros(mesh.n_nodes, dtype=bool)
    is_c[contact_nodes] = True
    vols = (rho if np.ndim(rho) == 0 else np.asarray(rho)) * cell_volumes(mesh)
    diag = np.zeros(mesh.n_nodes)
    for b in mesh.blocks:  # one cell type at a time (one block unless the mesh is mixed)
        t = touch[b.start : b.stop]
        diag += _free_share(mesh, b.cells[t], is_c, vols[b.start : b.stop][t])
    return (M + sp.diags(diag)).tocsr()


def _free_share(mesh: Mesh, cells: np.ndarray, is_c: np.ndarray, vol: np.ndarray) -> np.ndarray:
    """The mass ``vol`` of each cell (k, nv) split equally on its non-contact nodes, as a
    diagonal (n_nodes,); a cell with every node on Gamma_C gives it to the nearest
    non-contact nodes."""
    free = ~is_c[cells]
    count = free.sum(axis=1)
    w = vol / np.maximum(count, 1)
    diag = np.bincount(cells[free], weights=np.repeat(w, count), minlength=mesh.n_nodes)
    closed = count == 0  # every node on Gamma_C: its mass goes to the nearest non-contact nodes
    if closed.any():
        k = cells.shape[1]
        c = cells[closed]
        seeds = sp.csr_matrix(
            (np.ones(c.size), (np.repeat(np.arange(len(c)), k), c.ravel())), shape=(len(c), mesh.n_nodes)
        )
        diag += nearest_free_nodes(mesh, seeds, is_c, "mass-free-surface").T @ vol[closed]
    return diag


# ----------------------------------------------------------------------------- moment preserving
def _mass_1d(x: np.ndarray, rho: float) -> sp.csr_matrix:
    """1D P1 consistent mass on the grid x (rho h/6 [[2,1],[1,2]] per element)."""
    h = np.diff(x)
    n = x.size
    main = np.zeros(n)
    main[:-1] += h / 3
    main[1:] += h / 3
    off = h / 6
    return sp.diags([off, main, off], [-1, 0, 1], format="csr") * rho


def moment_preserving_1d(x: np.ndarray, rho: float, end: str = "min") -> sp.csr_matrix:
    """1D P1 mass with the node at ``end`` ('min' or 'max') massless and its mass
    redistributed on the next two nodes so that int 1, int x, int x^2 are preserved.

    Unknowns: increments a, b, c of M_11, M_12 = M_21, M_22 (node 1, 2 = first and
    second neighbours).  Constraints, for (p, q) in {(1,1), (1,x), (x,x)}:
    ``a p1 q1 + b (p1 q2 + p2 q1) + c p2 q2 = p^T (M - M_0) q``.
    """
    n = x.size
    if n < 3:
        raise InputError("mass 'moment-preserving' needs at least 2 elements across the contact layer")
    M = _mass_1d(x, rho).tolil()
    i0, i1, i2 = (0, 1, 2) if end == "min" else (n - 1, n - 2, n - 3)
    Mf = M.tocsr()
    xc = x - x[i0]  # moments about the contact node (better conditioned)
    P = np.vstack([np.ones(n), xc])
    pairs = [(0, 0), (0, 1), (1, 1)]
    M0 = Mf.tolil()
    M0[i0, :] = 0
    M0[:, i0] = 0
    M0 = M0.tocsr()
    A = np.empty((3, 3))
    r = np.empty(3)
    for k, (p, q) in enumerate(pairs):
        pp, qq = P[p], P[q]
        A[k] = [pp[i1] * qq[i1], pp[i1] * qq[i2] + pp[i2] * qq[i1], pp[i2] * qq[i2]]
        r[k] = pp @ (Mf @ qq) - pp @ (M0 @ qq)
    a, b, c = np.linalg.solve(A, r)
    M0 = M0.tolil()
    M0[i1, i1] += a
    M0[i1, i2] += b
    M0[i2, i1] += b
    M0[i2, i2] += c
    return M0.tocsr()


def _structured_side(mesh: Mesh, contact_nodes: np.ndarray) -> tuple[int, str] | None:
    """(axis, 'min'|'max') if ``contact_nodes`` is exactly one full side of a structured grid."""
    if mesh.grid is None:
        return None
    shape = [g.size for g in mesh.grid]
    idx = np.arange(mesh.n_nodes).reshape(shape[::-1])  # [z, y, x]
    cset = np.sort(contact_nodes)
    for axis in range(mesh.dim):
        ax = mesh.dim - 1 - axis
        for end, sl in (("min", 0), ("max", -1)):
            side = np.sort(np.take(idx, sl, axis=ax).ravel())
            if side.size == cset.size and np.array_equal(side, cset):
                return axis, end
    return None


def moment_preserving_scalar_mass(mesh: Mesh, rho: float, contact_nodes: np.ndarray) -> sp.csr_matrix:
    """Scalar moment-preserving redistributed mass T^T M T, on every mesh (module docstring).

    The same matrix for a generated mesh and for the same mesh read from a file, and
    rotation invariant (the weights depend on the geometry only).
    """
    return _moment_preserving_general(mesh, rho, contact_nodes)


def moment_preserving_tensor_scalar_mass(mesh: Mesh, rho: float, contact_nodes: np.ndarray) -> sp.csr_matrix:
    """Tensor-product variant: the 1D closed form across the contact side, the consistent
    1D mass along the others, ``M = M_x (x) M_y (x) M_z``; structured line/quad/hexahedron
    grids made by :mod:`signorini.fem.mesh` with contact on one full side only."""
    side = _structured_side(mesh, contact_nodes)
    if side is None or mesh.cell_type not in ("line", "quad", "hexahedron"):
        raise InputError(
            "mass 'moment-preserving-tensor' needs a structured grid made by the interval, rectangle or box "
            "generator (line, quad or hexahedron cells) with the contact on one full side; "
            "use 'moment-preserving' on other meshes"
        )
    if np.ndim(rho) and np.ptp(rho) > 0:
        raise InputError(
            "mass 'moment-preserving-tensor' needs one density for the whole grid (its factors are 1D masses); "
            "with regions of different materials use 'moment-preserving'"
        )
    rho = float(np.max(rho))
    axis, end = side
    factors = [moment_preserving_1d(g, 1.0, end) if k == axis else _mass_1d(g, 1.0) for k, g in enumerate(mesh.grid)]
    out = factors[0]
    for f in factors[1:]:
        out = sp.kron(f, out, format="csr")  # node = i + nx (j + ny k)
    return (rho * out).tocsr()


def _moment_preserving_general(mesh: Mesh, rho: float, contact_nodes: np.ndarray) -> sp.csr_matrix:
    """M_red = T^T M T with the affine extrapolation T of :func:`extrapolation_operator`.

    For affine p, q (zero on nothing in particular) T p = p, hence
    p^T M_red q = p^T M q: mass, first and second moments are preserved exactly;
    M_red is symmetric positive semi-definite by construction and its kernel is exactly
    the contact nodes (T has zero columns there and M is definite).  In 1D P1 with the
    two nearest nodes this is u_0 = 2 u_1 - u_2 and gives the closed form 8h/3, -2h/3, h.
    """
    M = scalar_mass_matrix(mesh, rho).tocsr()
    T = extrapolation_operator(mesh, np.asarray(contact_nodes))
    out = (T.T @ M @ T).tocsr()
    out.eliminate_zeros()
    return out


# ----------------------------------------------------------------------------- registry
MASS_VARIANTS.register(
    "standard",
    _standard,
    "consistent mass rho int phi_i . phi_j (kernel {0}); with friction and CN the frictional work can be positive "
    "(docs/friction.md)",
)
MASS_VARIANTS.register("lumped", _lumped, "row-sum lumped consistent mass (kernel {0}); with friction: as standard")
MASS_VARIANTS.register(
    "seed",
    _scalar_variant("seed", seed_scalar_mass),
    "the paper's M_mod: mass integrated over the cells not touching Gamma_C; contact nodes massless",
)
MASS_VARIANTS.register(
    "seed-normal",
    _seed_normal,
    "seed for the normal component only, through the nodal frames (any obstacle): contact nodes keep their "
    "tangential inertia; kernel = their normal components; with friction its tangential force oscillates under CN "
    "(use a dissipative scheme)",
)
MASS_VARIANTS.register(
    "moment-preserving",
    _scalar_variant("moment-preserving", moment_preserving_scalar_mass),
    "contact mass removed, redistributed so that mass, first and second moments are preserved; recommended with "
    "friction (docs/friction.md)",
)
MASS_VARIANTS.register(
    "moment-preserving-tensor",
    _scalar_variant("moment-preserving-tensor", moment_preserving_tensor_scalar_mass),
    "moment-preserving in tensor form M_x (x) M_y (x) M_z on generated structured grids (contact on a full side)",
)
MASS_VARIANTS.register(
    "neighbour",
    _scalar_variant("neighbour", neighbour_scalar_mass),
    "contact mass lumped onto the non-contact neighbours in proportion to M_ij (total mass kept)",
)
MASS_VARIANTS.register(
    "mass-free-surface",
    _scalar_variant("mass-free-surface", mass_free_surface_scalar_mass),
    "cells touching Gamma_C lump their mass on their non-contact nodes (Hager-Wohlmuth)",
)
MASS_VARIANTS.register(
    "mixed-velocity",
    _scalar_variant("mixed-velocity", mixed_velocity_scalar_mass),
    "the kinetic energy of the velocity projected on the P1/Q1 functions of the vertices off Gamma_C (Hauret's "
    "equivalent mass W^T C^-1 W, C their consistent mass; dense: quadratic cells, meshes up to 1,500 nodes); its "
    "kernel is not a set of dofs; loses the contact vertices' share of the mass (docs/quadratic.md)",
)
