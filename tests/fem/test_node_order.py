"""Node orders (:mod:`signorini.fem.node_order`): the Z-order renumbering of a run on
several ranks gives each rank a compact piece of a user's part, changes nothing that is
computed, and everything a run reports comes back in the user's node order."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from backends import gmsh_param
from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.model.owned_rows import rank_cells
from signorini.dynamics.model.problem import discretize, in_node_order
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.fem.mesh import box, interval, rectangle
from signorini.fem.node_order import (
    choose_order,
    in_order,
    morton_order,
    renumber,
    to_user_dofs,
    to_user_nodes,
    user_order_of,
)
from signorini.io.config import load_case

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _cylinder():
    return load_case(EXAMPLES / "cylinder_drop.toml").problem


def _refusals(problem) -> tuple[str, str]:
    """The messages of discretizing ``problem`` on the user's mesh and on the Z-ordered one
    (both must refuse, InputError)."""
    said = []
    for p in (problem, in_node_order(problem, "morton")):
        with pytest.raises(InputError) as err:
            discretize(p)
        said.append(str(err.value))
    return said[0], said[1]


def _cylinder_case(tmp_path, edit):
    """examples/cylinder_drop.toml with its mesh path made absolute, edited by ``edit`` (text -> text)."""
    text = (EXAMPLES / "cylinder_drop.toml").read_text().replace('"meshes/', f'"{EXAMPLES}/meshes/')
    path = tmp_path / "case.toml"
    path.write_text(edit(text))
    return load_case(path).problem


def _permutation_matrix(old_of_new: np.ndarray, d: int) -> sp.csr_matrix:
    """Q with (Q x)_new = x_old: row d*i + c of the renumbered dofs is dof d*old_of_new[i] + c."""
    cols = (d * old_of_new[:, None] + np.arange(d)).ravel()
    return sp.csr_matrix((np.ones(cols.size), (np.arange(cols.size), cols)), shape=(cols.size, cols.size))


def test_morton_order_is_a_stable_permutation_along_the_z_curve():
    # the 4 x 4 grid of unit points, listed row by row: the Z-order visits 2 x 2 quadrants
    x, y = np.meshgrid(np.arange(4.0), np.arange(4.0))
    pts = np.column_stack([x.ravel(), y.ravel()])
    order = morton_order(pts)
    assert order[:4].tolist() == [0, 1, 4, 5] and order[4:8].tolist() == [2, 3, 6, 7]
    assert np.array_equal(np.sort(order), np.arange(16))
    twice = np.vstack([pts, pts])  # equal points keep the mesh's order
    o2 = morton_order(twice)
    same = o2.reshape(-1, 2)
    assert np.all(same[:, 0] < same[:, 1]) and np.all(same[:, 1] - same[:, 0] == 16)
    assert morton_order(np.zeros((3, 3))).tolist() == [0, 1, 2]  # one point: the mesh's order
    assert morton_order(np.zeros((0, 2))).size == 0
    # 1D: 52 bits (2^63 - 1 is not a double: the far end's code would overflow to 0)
    assert morton_order(interval(8).points).tolist() == list(range(9))
    assert morton_order(interval(8).points[::-1]).tolist() == list(range(8, -1, -1))


@pytest.mark.parametrize("size", [2, 4, 8])
def test_morton_gives_each_rank_a_compact_piece_of_a_gmsh_part(size):
    """gmsh numbers the skin first: with the mesh's order, one rank touches (almost) every
    cell of the cylinder; in Z-order every rank touches at most 1.7 n_cells / P (measured
    1.16, 1.40, 1.69 on this 1,298-cell part; 1.05, 1.11, 1.18 on a 56,539-cell one)."""
    mesh = _cylinder().mesh
    ideal = mesh.n_cells / size
    assert max(rank_cells(mesh, size)) >= (2.7 if size > 2 else 1.9) * ideal
    assert max(rank_cells(in_order(mesh, "morton"), size)) <= 1.7 * ideal


def test_renumber_moves_points_cells_and_tags_together_and_composes():
    mesh = box(2, 2, 2, cell="tetra")
    rng = np.random.default_rng(3)
    p = rng.permutation(mesh.n_nodes)
    r = renumber(mesh, p)
    assert r.grid is None and np.array_equal(r.node_ids, p)
    assert np.array_equal(r.points, mesh.points[p])
    assert np.array_equal(r.node_ids[r.cells], mesh.cells)  # the same cells, in the user's numbers
    for tag in mesh.tags:
        assert np.array_equal(r.node_ids[r.facets[tag]], mesh.facets[tag])
    q = rng.permutation(mesh.n_nodes)
    rr = renumber(r, q)  # a second renumbering still knows the user's numbers
    assert np.array_equal(rr.points, mesh.points[rr.node_ids])
    assert rr.node_id(0) == int(p[q[0]]) and mesh.node_id(5) == 5
    with pytest.raises(ValueError, match="permutation"):
        renumber(mesh, np.zeros(mesh.n_nodes, dtype=int))


def test_to_user_order_inverts_the_renumbering():
    mesh = rectangle(3, 2)
    r = renumber(mesh, morton_order(mesh.points))
    assert np.array_equal(to_user_nodes(r, r.points), mesh.points)
    U = np.arange(2 * mesh.n_nodes, dtype=float)  # dof k of the user's mesh holds k
    Ur = _permutation_matrix(r.node_ids, 2) @ U
    assert np.array_equal(to_user_dofs(r, Ur), U)
    assert np.array_equal(to_user_dofs(r, np.vstack([Ur, 2 * Ur])), np.vstack([U, 2 * U]))
    nodes = np.array([0, 3, 5])
    assert np.all(np.diff(r.node_ids[nodes][user_order_of(r, nodes)]) > 0)
    assert to_user_nodes(mesh, U) is U  # the user's own mesh: nothing to do


def test_auto_is_morton_for_a_mesh_that_is_not_a_grid():
    grid, part = box(2, 2, 2), _cylinder().mesh
    assert choose_order("auto", part) == "morton" and choose_order("mesh", part) == "mesh"
    assert choose_order("auto", grid) == "mesh" and choose_order("morton", grid) == "morton"
    with pytest.raises(ValueError, match="auto, mesh, morton"):
        choose_order("hilbert", part)


def test_a_renumbered_part_discretizes_to_the_permuted_operators():
    """S, M (the default moment-preserving variant), the loads and the contact set on the
    renumbered cylinder are the user's, permuted: Q S Q^T, Q M Q^T, Q F."""
    problem = _cylinder()
    ren = renumber(problem.mesh, morton_order(problem.mesh.points))
    a = discretize(problem)
    b = discretize(type(problem)(**{**problem.__dict__, "mesh": ren}))
    Q = _permutation_matrix(ren.node_ids, 3)
    for A, B in ((a.S, b.S), (a.M, b.M)):
        diff = abs(Q @ A @ Q.T - B).max()
        assert diff <= 1e-13 * abs(A).max()  # measured 1.1e-15 relative
    Fa, Fb = a.load(0.0), b.load(0.0)
    assert np.allclose(Q @ Fa, Fb, rtol=0, atol=5e-14 * np.abs(Fa).max())  # measured 9.7e-16 relative
    assert np.array_equal(Q @ a.U0, b.U0) and np.array_equal(Q @ a.V0, b.V0)
    p = user_order_of(ren, b.contact.nodes)
    assert np.array_equal(ren.node_ids[b.contact.nodes[p]], a.contact.nodes)
    assert np.allclose(b.contact.normals[p], a.contact.normals, rtol=0, atol=1e-14)
    assert np.allclose(b.contact.weights[p], a.contact.weights, rtol=0, atol=1e-18)


def test_history_of_a_renumbered_run_comes_back_in_the_users_order():
    """The cylinder run on the renumbered mesh (serially, so that only the order differs)
    reports gaps, multipliers, coordinates and snapshots in the user's order."""
    problem = _cylinder()
    ren = type(problem)(**{**problem.__dict__, "mesh": in_order(problem.mesh, "morton")})
    kw = {"dt": 5e-5, "T": 4e-3, "snapshot_every": 40, "backend": "superlu"}
    a = simulate(problem, **kw)
    H = simulate(ren, **kw)
    nodes = discretize(ren).contact.nodes
    assert np.any(user_order_of(ren.mesh, nodes) != np.arange(nodes.size))  # the run's order is not the user's
    assert np.array_equal(H.coordinates, a.coordinates) and np.array_equal(H.weights, a.weights)
    assert np.array_equal(H.nodes, a.nodes) and np.array_equal(a.nodes, problem.mesh.nodes_of("skin"))
    gap = float(np.abs(a.gap).max())
    assert np.abs(H.gap - a.gap).max() <= 2e-12 * gap  # measured 4.6e-14 relative
    assert np.abs(H.lam - a.lam).max() <= 1e-9 * np.abs(a.lam).max()
    assert a.lam.min() < 0  # the part touched the plane: the multipliers were compared
    for k in ("u", "v"):
        assert np.abs(H.snapshots[k] - a.snapshots[k]).max() <= 5e-10 * np.abs(a.snapshots[k]).max()  # measured 5.1e-12


def test_messages_name_the_users_node():
    """A contact node inside the obstacle at t = 0 is named by the user's number, whatever
    the run's order: a plane through the cylinder's skin just past one node."""
    problem = _cylinder()
    n = np.array([1.0, 0.3, 0.2]) / np.linalg.norm([1.0, 0.3, 0.2])
    skin = problem.mesh.nodes_of("skin")
    node = int(skin[np.argmin(problem.mesh.points[skin] @ n)])
    plane = PlaneObstacle(problem.mesh.points[node] + 1e-6 * n, n)
    user, ordered = _refusals(dataclasses.replace(problem, obstacle=plane))
    assert f"node {node} " in user and user == ordered


@pytest.mark.parametrize("which", ["cylinder", gmsh_param("hertz3d"), "disc_on_ball"])
def test_every_mass_variant_is_the_users_permuted(which):
    """No variant depends on the node numbers (a tie broken by index would change the
    physics with the order): on the renumbered mesh, M is Q M Q^T, or the same refusal."""
    from signorini.contact.contact_set import ContactSet
    from signorini.dynamics.model.mass import linear_cell_variants, redistribute
    from signorini.fem.space import Constraints, VectorSpace
    from signorini.studies.benchmarks import get_benchmark

    if which == "hertz3d":
        problem = get_benchmark("hertz3d").problem(3, {})
    else:
        problem = load_case(EXAMPLES / f"{which if which != 'cylinder' else 'cylinder_drop'}.toml").problem
    ren = in_order(problem.mesh, "morton")
    Q = _permutation_matrix(ren.node_ids, problem.mesh.dim)

    def variant(mesh, name):
        space = VectorSpace(mesh)
        cons = Constraints(space, problem.dirichlet)
        c = ContactSet.from_tag(space, problem.contact_tag, problem.obstacle, cons, problem.contact_where)
        try:
            return redistribute(name, mesh, problem.material.rho, c.nodes, c.normals).M
        except InputError as exc:
            return str(exc)

    built = 0
    for name in linear_cell_variants():
        a, b = variant(problem.mesh, name), variant(ren, name)
        if isinstance(a, str):
            assert a == b, name
            continue
        assert abs(Q @ a @ Q.T - b).max() <= 1e-13 * abs(a).max(), name  # measured 1.1e-15 relative
        built += 1
    assert built >= len(linear_cell_variants()) - 1  # only the tensor form needs a grid


def test_nodal_initial_data_follow_the_renumbering():
    """u0 and v0 given as nodal arrays, (n_nodes, d) or (n_nodes d,), are permuted with the
    mesh: the renumbered problem's U0 and V0 are the user's, permuted."""
    problem = _cylinder()
    rng = np.random.default_rng(7)
    n, d = problem.mesh.n_nodes, problem.mesh.dim
    u0 = 1e-4 * rng.standard_normal((n, d))
    v0 = rng.standard_normal(n * d)
    user = dataclasses.replace(problem, u0=u0, v0=v0, obstacle=PlaneObstacle([0.0, 0.0, -1.0], [0.0, 0.0, 1.0]))
    ren = in_node_order(user, "morton")
    assert in_node_order(user, "mesh") is user
    a, b = discretize(user), discretize(ren)
    Q = _permutation_matrix(ren.mesh.node_ids, d)
    assert np.array_equal(Q @ a.U0, b.U0) and np.array_equal(Q @ a.V0, b.V0)
    const = in_node_order(dataclasses.replace(problem, v0=[0.0, 0.0, -1.0]), "morton")
    assert np.array_equal(np.asarray(const.v0), [0.0, 0.0, -1.0])  # a constant is not a nodal array


def test_conflicting_dirichlet_values_name_the_same_dof(tmp_path):
    def edit(text):
        text += '[[dirichlet]]\ntag = "bottom"\nvalue = [0.0, 0.0, 0.0]\n'
        text += '[[dirichlet]]\ntag = "skin"\nvalue = [0.0, 0.0, 1.0]\n'
        return text.replace('tag = "skin"\nobstacle', 'tag = "skin"\nwhere = "z > 0.05"\nobstacle')

    user, ordered = _refusals(_cylinder_case(tmp_path, edit))
    assert "prescribe different values" in user and user == ordered


def test_a_non_finite_expression_names_the_same_point(tmp_path):
    problem = _cylinder_case(
        tmp_path, lambda t: t.replace("velocity = [0.0, 0.0, -1.0]", 'velocity = [0.0, 0.0, "log(z)"]')
    )
    user, ordered = _refusals(problem)
    assert "not finite" in user and user == ordered


def test_an_untagged_penetration_names_the_same_node():
    """The side impact's untagged nodes enter the wall with penetrations equal up to
    round-off, which differs between node orders: the warning names the node the user
    numbered first among them, on the user's mesh and on the renumbered one alike."""
    problem = load_case(Path(__file__).parents[1] / "data" / "side_impact.toml").problem
    kw = {"dt": 0.005, "T": 0.15, "backend": "superlu"}
    a = simulate(problem, **kw)
    b = simulate(in_node_order(problem, "morton"), **kw)
    warned = [w for w in a.meta["warnings"] if "boundary node" in w]
    assert warned and warned == [w for w in b.meta["warnings"] if "boundary node" in w]
