"""S and every mass variant by rows (:mod:`signorini.dynamics.model.owned_rows`): each simulated
rank's rows, built from the cells near its nodes, equal the whole mesh's matrices' rows,
on generated bars, the Hertz ball's curved contact, and gmsh parts with their whole skin
in contact (tetrahedra, triangles)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp

from backends import gmsh_param
from signorini.contact.contact_set import ContactSet
from signorini.dynamics.model.mass import MASS_VARIANTS, redistribute
from signorini.dynamics.model.owned_rows import cells_near, dof_bounds, mass_rows, rank_cells, stiffness_rows
from signorini.fem.assembly import stiffness_matrix
from signorini.fem.node_order import in_order
from signorini.fem.space import Constraints, VectorSpace
from signorini.io.config import load_case
from signorini.studies.benchmarks import get_benchmark

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


def _problem(which: str):
    if which.endswith("@morton"):  # the Z-order of a run on several ranks (fem/node_order.py)
        problem = _problem(which.removesuffix("@morton"))
        return dataclasses.replace(problem, mesh=in_order(problem.mesh, "morton"))
    if which.endswith(".toml"):
        return load_case(EXAMPLES / which).problem
    name, n = which.split(":")
    return get_benchmark(name).problem(int(n), {})


def _contact(problem):
    space = VectorSpace(problem.mesh)
    cons = Constraints(space, problem.dirichlet)
    return ContactSet.from_tag(space, problem.contact_tag, problem.obstacle, cons, problem.contact_where)


CASES = [
    "bar2d:6",
    "bar3d:3",
    gmsh_param("hertz2d:4"),
    gmsh_param("hertz3d:3@morton"),
    "block3d_tetra.toml",
    "cylinder_drop.toml",
    "cylinder_drop.toml@morton",
]


def _with_size(case, size: int):
    """(case, size), keeping the case's gmsh guard."""
    if hasattr(case, "values"):
        return pytest.param(case.values[0], size, id=f"{case.values[0]}-{size}", marks=case.marks)
    return (case, size)


def _each_rank(size: int):
    return [SimpleNamespace(rank=r, size=size) for r in range(size)]


def _rank_rows(problem, variant, contact, ranks):
    """The stacked rows of every simulated rank (S, M) and the first rank's extrapolation."""
    S = sp.vstack([stiffness_rows(problem.mesh, problem.material, c).local for c in ranks]).tocsr()
    reds = [mass_rows(variant, problem.mesh, problem.material.rho, contact.nodes, contact.normals, c) for c in ranks]
    return S, sp.vstack([r.M.local for r in reds]).tocsr(), reds[0].T


#: 6 and 8 ranks on the meshes whose sub-meshes cut a closed contact skin (the neighbour
#: search's reach, docs/parallel.md) and on a bar
PAIRS = [_with_size(w, p) for w in CASES for p in (2, 3)] + [
    (w, p) for w in ("block3d_tetra.toml", "cylinder_drop.toml", "cylinder_drop.toml@morton", "bar3d:3") for p in (6, 8)
]


@pytest.mark.parametrize(("which", "size"), PAIRS)
def test_every_variant_by_rows_equals_the_whole_matrix(which, size):
    problem = _problem(which)
    mesh, rho = problem.mesh, problem.material.rho
    contact = _contact(problem)
    S_whole = stiffness_matrix(mesh, problem.material)
    for variant in [e.name for e in MASS_VARIANTS]:
        try:
            whole = redistribute(variant, mesh, rho, contact.nodes, contact.normals)
        except Exception as exc:  # noqa: BLE001 - a variant that refuses this mesh must refuse it by rows too
            with pytest.raises(type(exc)):
                _rank_rows(problem, variant, contact, _each_rank(size))
            continue
        S, M, T = _rank_rows(problem, variant, contact, _each_rank(size))
        scale = abs(whole.M).max()
        assert M.shape == whole.M.shape and S.shape == S_whole.shape
        assert abs(M - whole.M).max() <= 1e-13 * scale, (which, variant)
        assert abs(S - S_whole).max() <= 1e-13 * abs(S_whole).max(), which
        assert (T is None) == (whole.T is None)


def test_the_rows_of_a_rank_cover_its_nodes_dofs_and_its_halo_is_small():
    mesh = get_benchmark("bar3d").problem(4, {}).mesh
    b = dof_bounds(mesh, 3)
    assert b[0] == 0 and b[-1] == 3 * mesh.n_nodes and np.all(b % 3 == 0)
    own = np.arange(b[1] // 3, b[2] // 3)
    one, two = cells_near(mesh, own, 1), cells_near(mesh, own, 2)
    assert set(one) < set(two) and two.size < mesh.n_cells  # a slab and its neighbours, not the mesh
    touching = np.flatnonzero(np.isin(mesh.cells, own).any(axis=1))
    np.testing.assert_array_equal(one, touching)


@pytest.mark.parametrize("which", ["bar3d:3", "cylinder_drop.toml"])
@pytest.mark.parametrize("size", [1, 2, 3])
def test_rank_cells_counts_the_cells_touching_each_ranks_nodes(which, size):
    mesh = _problem(which).mesh
    b = dof_bounds(mesh, size) // mesh.dim
    expected = [cells_near(mesh, np.arange(b[r], b[r + 1]), 1).size for r in range(size)]
    assert rank_cells(mesh, size) == expected
    assert sum(expected) >= mesh.n_cells
