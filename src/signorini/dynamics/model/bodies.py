"""The bodies of a run (the connected components of its mesh): what each one is and does.

``summary.json`` ``bodies``: one object per body, numbered in the order of their first node,

* ``regions``: the mesh's region tags with cells in the body (sorted), ``nodes`` (count),
  ``mass`` [mass] (1^T M 1 along x, the mass the run uses) and
  ``mass_effect`` (:func:`~signorini.dynamics.model.mass_effect.mass_effect` of the body's own
  block of M against its consistent mass: what the mass variant does to *this* body);
* at the last level, ``momentum`` (d,) = 1_k^T M V over the body's dofs [mass x length / time]
  and ``kinetic_energy`` 1/2 V_b . M_bb V_b [energy].

``summary.json`` ``regions``: one object per region tag of the mesh (sorted, the numbering of
the XDMF cell data ``region``): ``tag``, ``id`` (k + 1), ``cells`` and the ``material`` of its
cells (``E``, ``nu``, ``rho``; ``listed``: whether ``[material] regions`` names it).

The mass variants never couple two bodies (their neighbourhoods follow the cells), so M is
block diagonal over the bodies and these add up to the run's totals.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ...fem.dofmap import DofMap, component
from ...fem.mesh import Mesh, bodies
from .mass_effect import body_mass_effect, mass_effect


def body_meshes(mesh: Mesh) -> list[tuple[np.ndarray, np.ndarray, Mesh]]:
    """(nodes, cells, mesh of that body alone) per body; a single body is the mesh itself."""
    label = bodies(mesh)
    if label.max(initial=0) == 0:
        return [(np.arange(mesh.n_nodes), np.arange(mesh.n_cells), mesh)]
    out = []
    cell_body = label[mesh.first_nodes()]
    for b in range(int(label.max()) + 1):
        nodes = np.flatnonzero(label == b)
        renum = np.full(mesh.n_nodes, -1)
        renum[nodes] = np.arange(nodes.size)
        cells = np.flatnonzero(cell_body == b)
        types, arrays = [], []
        for blk in mesh.blocks:  # the body's cells of each type (a body may be of one type, or several)
            mine = cells[(cells >= blk.start) & (cells < blk.stop)] - blk.start
            if mine.size:
                types.append(blk.cell_type)
                arrays.append(renum[blk.cells[mine]])
        out.append((nodes, cells, Mesh(mesh.points[nodes], arrays, types)))
    return out


def region_summaries(mesh: Mesh, default, materials: dict) -> list[dict]:
    """``summary.json`` ``regions`` (see the module docstring)."""
    out = []
    for k, tag in enumerate(sorted(mesh.regions)):
        m = materials.get(tag, default)
        out.append(
            {
                "tag": tag,
                "id": k + 1,
                "cells": int(mesh.regions[tag].size),
                "material": {
                    "E": float(m.young),
                    "nu": float(m.poisson),
                    "rho": float(m.rho),
                    "listed": tag in materials,
                },
            }
        )
    return out


def body_summaries(mesh: Mesh, M, rho: float | np.ndarray, V: np.ndarray | None) -> list[dict]:
    """``summary.json`` ``bodies`` (see the module docstring); ``M`` the run's vector mass
    (a sparse matrix, or a distributed one, whose products are reductions over the ranks: the per-body
    ``mass_effect`` then by products, :func:`~.mass_effect.body_mass_effect`), ``rho`` the
    density (a number or one per cell), ``V`` the last level's velocity (None: no level)."""
    d = mesh.dim
    out = []
    local = sp.issparse(M)
    MV = M @ V if V is not None else None  # a distributed M (rows per rank): one reduction over the ranks
    # in the order of each body's first node in the user's numbering: the same on every rank count and node order
    # (a renumbered mesh, :mod:`~signorini.fem.node_order`, finds its bodies in its own order)
    ids = np.arange(mesh.n_nodes) if mesh.node_ids is None else np.asarray(mesh.node_ids)
    parts = sorted(body_meshes(mesh), key=lambda part: int(ids[part[0]].min()))
    dofmap = DofMap.serial(mesh.n_nodes, d)
    body_dofs = [dofmap.dofs(nodes).ravel() for nodes, _, _ in parts]
    if not local:  # the mass of each body from one product with the bodies' indicators (n, bodies)
        E = np.zeros((M.shape[0], len(parts)))
        for k, dofs in enumerate(body_dofs):
            E[dofs, k] = 1.0
        ME = M @ E
    in_body = np.zeros(mesh.n_cells, dtype=bool)
    for k, ((nodes, cells, sub), dofs) in enumerate(zip(parts, body_dofs, strict=True)):
        in_body[:] = False
        in_body[cells] = True
        regions = sorted(t for t, c in mesh.regions.items() if c.size and in_body[c].any())
        entry: dict = {"regions": regions, "nodes": int(nodes.size)}
        if local:
            Mb = M[dofs][:, dofs].tocsr()
            entry["mass"] = float(Mb[component(0, d)].sum())
            entry["mass_effect"] = mass_effect(Mb, sub, rho if np.ndim(rho) == 0 else np.asarray(rho)[cells])
        else:  # sum over the body's x rows of M 1_body (the first component's); the effect by products with M
            entry["mass"] = float(ME[dofs[component(0, d)], k].sum())
            entry["mass_effect"] = body_mass_effect(
                M, mesh, nodes, sub, rho if np.ndim(rho) == 0 else np.asarray(rho)[cells]
            )
        if MV is not None:
            entry["momentum"] = [float(MV[dofs][component(k, d)].sum()) for k in range(d)]
            entry["kinetic_energy"] = 0.5 * float(V[dofs] @ MV[dofs])
        out.append(entry)
    return out
