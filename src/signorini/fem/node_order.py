"""Node orders for a distributed run: a locality order, and the way back to the user's.

On the distributed backends rank r owns an even split [a_r, a_{r+1}) of the node
numbers (:mod:`signorini.dynamics.model.owned_rows`) and assembles the cells that touch them.
That saves memory only when consecutive numbers are close in space.  Generated grids
are (slabs); mesh generators are not: gmsh numbers the nodes of the boundary entities
first, so on a part with its whole skin tagged one rank touches every cell
(``rank_cells``, docs/parallel.md).

``morton`` renumbers the nodes along the Z-order (Morton) curve of their coordinates:
the coordinates are quantized on a 2^b grid of the bounding box's largest side
(isotropic) and their bits interleaved (x, y, z, x, y, z, ...), b = 63 // d (52 in 1D,
where 2^63 - 1 is not a double); nodes in one grid cell keep the mesh's order.  Any even
split of a Z-order is a set of compact pieces of the part, so the cells a rank touches
are about n_cells / P plus its interfaces (measured against reverse Cuthill-McKee and
PT-Scotch's partition in docs/parallel.md).  The order does not depend on P.

A renumbered mesh remembers the user's number of every node (``Mesh.node_ids``); the
run maps what it writes back (:func:`to_user_nodes`), and its messages name the user's
numbers (``Mesh.node_id``).
"""

from __future__ import annotations

import numpy as np

from .mesh import Mesh

#: the node orders of a distributed run (solver option ``node_order``)
NODE_ORDERS = ("auto", "mesh", "morton")


def morton_order(points: np.ndarray) -> np.ndarray:
    """Node indices (n,) sorted along the Z-order curve of ``points`` (n, d).

    Returns ``old_of_new``: entry i is the node that comes i-th.  Stable: nodes with
    the same quantized coordinates keep their relative order.
    """
    points = np.asarray(points, dtype=float)
    n, d = points.shape
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    bits = min(63 // d, 52)  # 2^bits - 1 exact in a double (1D: 52, not 63)
    lo = points.min(axis=0)
    span = float((points.max(axis=0) - lo).max())
    if span <= 0.0:
        return np.arange(n, dtype=np.int64)
    scale = (2.0**bits - 1) / span
    q = np.minimum(np.floor((points - lo) * scale), 2.0**bits - 1).astype(np.uint64)  # (n, d)
    code = np.zeros(n, dtype=np.uint64)
    one = np.uint64(1)
    position = np.arange(bits * d, dtype=np.uint64).reshape(bits, d)  # where bit b of coordinate k goes
    for b in range(bits):  # bit b of every coordinate, interleaved: O(63 n), no loop over nodes
        for k in range(d):
            code |= ((q[:, k] >> np.uint64(b)) & one) << position[b, k]
    return np.argsort(code, kind="stable").astype(np.int64)


def renumber(mesh: Mesh, old_of_new: np.ndarray) -> Mesh:
    """``mesh`` with its nodes renumbered: node i of the result is node ``old_of_new[i]``.

    Points, cells and tagged facets follow (cells keep their order, so the regions too); the generator's
    ``grid`` is dropped (its formula reads the old numbers).  ``node_ids`` carries the
    user's number of every node (composed when ``mesh`` was already renumbered).
    """
    old_of_new = np.asarray(old_of_new, dtype=np.int64)
    n = mesh.n_nodes
    if old_of_new.shape != (n,) or not np.array_equal(np.sort(old_of_new), np.arange(n)):
        raise ValueError(f"a renumbering of {n} nodes must be a permutation of 0..{n - 1}")
    new_of_old = np.empty(n, dtype=np.int64)
    new_of_old[old_of_new] = np.arange(n)
    ids = old_of_new if mesh.node_ids is None else mesh.node_ids[old_of_new]
    return Mesh(
        mesh.points[old_of_new],
        new_of_old[mesh.cells],
        mesh.cell_type,
        {tag: new_of_old[f] for tag, f in mesh.facets.items()},
        None,
        ids,
        mesh.regions,
    )


def choose_order(name: str, mesh: Mesh) -> str:
    """The order a distributed run uses: ``auto`` is ``morton`` for a mesh that is not a
    generated grid (a grid's own numbering is already slabs), else ``mesh``.  On any number
    of ranks, 1 included: the order then does not depend on P, and the products are faster
    in it (petsc-cg on one rank: 806 against 1,160 ms per step on a 232k-dof gmsh part)."""
    if name not in NODE_ORDERS:
        raise ValueError(f"node order must be one of {', '.join(NODE_ORDERS)}, got {name!r}")
    if name == "auto":
        return "morton" if mesh.grid is None and mesh.n_nodes > 1 else "mesh"
    return name


def in_order(mesh: Mesh, name: str) -> Mesh:
    """``mesh`` in the order ``name`` (``mesh``: itself)."""
    return renumber(mesh, morton_order(mesh.points)) if name == "morton" else mesh


def to_user_nodes(mesh: Mesh, a: np.ndarray, axis: int = 0) -> np.ndarray:
    """An array indexed by ``mesh``'s nodes along ``axis``, in the user's node order."""
    if mesh.node_ids is None:
        return a
    a = np.asarray(a)
    out = np.empty_like(a)
    index = [slice(None)] * a.ndim
    index[axis] = mesh.node_ids
    out[tuple(index)] = a
    return out


def to_user_dofs(mesh: Mesh, U: np.ndarray) -> np.ndarray:
    """Node-major dof vectors (..., d n) of ``mesh`` in the user's node order."""
    if mesh.node_ids is None:
        return U
    U = np.asarray(U)
    shape = U.shape
    nodes = U.reshape(*shape[:-1], mesh.n_nodes, mesh.dim)
    return to_user_nodes(mesh, nodes, axis=nodes.ndim - 2).reshape(shape)


def user_order_of(mesh: Mesh, nodes: np.ndarray) -> np.ndarray:
    """The permutation that sorts ``nodes`` (of ``mesh``) by the user's numbers: a sorted
    node list of the renumbered mesh, taken in this order, is the user's sorted list."""
    ids = np.asarray(nodes) if mesh.node_ids is None else mesh.node_ids[nodes]
    return np.argsort(ids, kind="stable")
