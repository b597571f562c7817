"""Contact pairs (contact/pairs.py): the node-to-facet rows, and two bars colliding in 2D/3D.

The 2D/3D bars (nu = 0, so the 1D wave speed sqrt(E/rho)) are checked against the exact
collision of collision1d; measured with CN + moment-preserving (n = 2 and 3 across, h = w/3
for the non-matching pair): duration +0 to +1.7%, plateau force -1 to +2%, final
velocities within 1.8% of v, energy within 3e-4, momentum to 1e-13.
"""

import numpy as np
import pytest

from signorini.contact.pairs import ContactPair, _closest_on_facets, pair_rows
from signorini.dynamics.model.problem import Problem
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import box, interval, join, rectangle
from signorini.studies.collision import CollisionMeasure, exact

L, GAP, V, W = 1.0, 0.1, 0.5, 0.1
PARAMS = {"L": L, "gap": GAP, "velocity": V, "E": 1.0, "rho": 1.0}


def bars(dim: int, na: int, nb: int, **kw) -> Problem:
    """Two equal bars along the last axis, the first moving at V towards the second."""
    if dim == 1:
        a, b = interval(10 * na, L), interval(10 * nb, L)
    elif dim == 2:
        a, b = rectangle(na, 10 * na, W, L), rectangle(nb, 10 * nb, W, L)
    else:
        a, b = box(na, na, 10 * na, W, W, L), box(nb, nb, 10 * nb, W, W, L)
    b.points = b.points.copy()
    b.points[:, -1] += L + GAP
    m = join({"left": a, "right": b})
    ax = "xyz"[dim - 1]
    e = np.eye(dim)[-1]
    return Problem(m, IsotropicElastic.from_young(1.0, 0.0, 1.0), None, None, u0=0.0,
                   v0=lambda x: np.where(x[:, -1] < L + GAP / 2, V, 0.0)[:, None] * e,
                   pairs=[ContactPair(f"right_{ax}min", f"left_{ax}max")], **kw)  # fmt: skip


@pytest.mark.parametrize("mass", ["standard", "seed"])
def test_matching_3d_bars_are_the_1d_discrete_collision(mass):
    """Q1 bars with nu = 0 and matching faces move as the P1 bar of the same h (every node of
    a cross-section alike): the total force per area and the gaps equal the 1D run's."""
    h = W / 2
    H3 = simulate(bars(3, 2, 2), "cn", h / 2, 3.0, mass=mass)
    H1 = simulate(bars(1, 2, 2), "cn", h / 2, 3.0, mass=mass)
    assert H1.lam.min() < 0
    scale = np.abs(H1.lambda_sum).max()
    assert np.abs(H3.lambda_sum / W**2 - H1.lambda_sum).max() <= 1e-9 * scale
    # measured 3e-12 with the standard mass (CN's oscillating contact amplifies round-off)
    assert np.abs(H3.gap.min(axis=1) - H1.gap[:, 0]).max() <= 1e-10 * L


@pytest.mark.parametrize("dim, na, nb", [(2, 2, 2), (2, 2, 3), (3, 2, 2), (3, 2, 3)])
def test_2d_3d_bars_collide_as_the_exact_solution(dim, na, nb):
    """Matching and non-matching faces (nb != na: every slave node of the finer side falls
    inside a master facet), CN with the default mass."""
    h = W / max(na, nb)
    H = simulate(bars(dim, na, nb), "cn", h / 2, 4.2)
    assert H.status == "finished"
    s, ex = CollisionMeasure(PARAMS).summary(H)["collision"], exact(PARAMS)
    area = W ** (dim - 1)
    assert abs(s["contact_duration"] / ex["contact_duration"] - 1) <= 0.03
    assert abs(s["mean_force_middle"] / area / ex["contact_force"] - 1) <= 0.03
    vel = [b["momentum"][-1] / b["mass"] for b in H.meta["bodies"]]
    assert abs(vel[0]) <= 0.03 * V and abs(vel[1] - V) <= 0.03 * V
    assert abs(H.energy[-1] / H.energy[0] - 1) <= 1e-3
    P = H.momentum[:, -1]
    assert np.abs(P - P[0]).max() <= 1e-11 * abs(P[0])
    assert H.gap.min() >= -1e-12


def test_closest_points_on_the_facet_kinds():
    x = np.array([[0.25, 0.5, 1.0], [2.0, 2.0, 0.3]])
    tri = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]] * 2)
    p, N = _closest_on_facets(x, tri, "triangle")
    assert np.allclose(p, [[0.25, 0.5, 0.0], [0.5, 0.5, 0.0]], rtol=0, atol=1e-12) and np.allclose(
        N.sum(axis=1), 1, rtol=0, atol=1e-12
    )
    assert np.allclose(np.einsum("mk,mkd->md", N, tri), p, rtol=0, atol=1e-12)
    quad = np.array([[[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0], [0.0, 1.0, 0.0]]] * 2)
    p, N = _closest_on_facets(x, quad, "quad")
    assert np.allclose(p, [[0.25, 0.5, 0.0], [2.0, 1.0, 0.0]], rtol=0, atol=1e-12) and np.allclose(
        np.einsum("mk,mkd->md", N, quad), p, rtol=0, atol=1e-12
    )
    seg = np.array([[[0.0, 0.0], [1.0, 0.0]]])
    p, N = _closest_on_facets(np.array([[0.3, 2.0]]), seg, "line")
    assert np.allclose(p, [[0.3, 0.0]], rtol=0, atol=1e-12) and np.allclose(N, [[0.7, 0.3]], rtol=0, atol=1e-12)


def test_the_rows_balance_and_a_node_off_the_master_is_inactive():
    """Each row sums to zero per component (the forces on the two bodies balance); a slave
    face wider than the master leaves its outer nodes inactive."""
    a, b = rectangle(2, 4, 0.1, 1.0), rectangle(4, 4, 0.3, 1.0)
    b.points = b.points.copy()
    b.points[:, 1] += 1.05
    b.points[:, 0] -= 0.1
    m = join({"a": a, "b": b})
    r = pair_rows(m, ContactPair("b_ymin", "a_ymax"), 2 * m.n_nodes)
    assert np.allclose(
        np.asarray(r.B[:, 1::2].sum(axis=1)).ravel(), 0.0, rtol=0, atol=1e-15
    )  # y components: -1 + sum N_j = 0
    assert r.inactive == 4 and r.nodes.size == 1  # b's bottom nodes x = -0.1, -0.025, 0.125, 0.2: off [0, 0.1]
    assert np.allclose(r.gaps, 0.05, rtol=0, atol=1e-12) and np.allclose(r.normals, [0.0, -1.0], rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    "change, message",
    [({"friction": "tresca:0.01", "pairs": [("right_ymin", "left_ymax"), ("left_ymax", "right_ymin", "coulomb:0.3")]},
      "share one law"),
     ({"pairs": [("left_ymax", "left_ymax")]}, "same tag"),
     ({"pairs": [("right_ymin", "nope")]}, "unknown boundary tag"),
     ({"pairs": [("left_ymax", "left_xmax")]}, "share nodes")],
)  # fmt: skip
def test_refusals(change, message):
    import dataclasses

    with pytest.raises(InputError, match=message):
        if "pairs" in change:
            change = {**change, "pairs": [ContactPair(*p) for p in change["pairs"]]}
        p = dataclasses.replace(bars(2, 1, 1), **change)
        simulate(p, "cn", 0.01, 0.02)


def test_seed_normal_is_refused_with_pairs():
    with pytest.raises(InputError, match="seed-normal"):
        simulate(bars(2, 1, 1), "cn", 0.025, 0.05, mass="seed-normal")


@pytest.mark.parametrize("mass", ["moment-preserving", "neighbour", "mass-free-surface", "seed"])
def test_no_mass_variant_couples_two_bodies(mass):
    """A tetrahedral ball over a thin plate whose whole top is the master (examples/meshes/
    ball_on_plate.msh): near the plate's edges the affine fit falls back to the nearest
    non-contact nodes in space, which must be of the node's own body.  Before the fix, 265
    entries of T linked the bodies (the plate kept 97.4% of its mass, the ball 100.66%);
    now no entry of M couples them and each body keeps its own mass (measured 1 to 7e-16)."""
    from pathlib import Path

    from signorini.dynamics.model.bodies import body_summaries
    from signorini.dynamics.model.problem import discretize
    from signorini.fem.mesh import bodies, read_mesh
    from signorini.fem.space import Dirichlet

    m = read_mesh(Path(__file__).parents[2] / "examples" / "meshes" / "ball_on_plate.msh")
    p = Problem(m, IsotropicElastic.from_young(100, 0.3, 1), None, None, dirichlet=[Dirichlet("plate_sides")],
                pairs=[ContactPair("ball_skin", "plate_top")])  # fmt: skip
    label = np.repeat(bodies(m), 3)
    D = discretize(p, mass)
    assert D.M[np.flatnonzero(label == 0)][:, np.flatnonzero(label == 1)].nnz == 0
    if mass != "seed":  # seed removes the cells touching the contact nodes: less mass, by design
        for b in body_summaries(m, D.M, D.material.rho, None):
            assert abs(b["mass_effect"]["mass_ratio"] - 1) <= 1e-13


def test_body_summaries_in_the_users_order_and_by_products():
    """summary.json ``bodies``: in the order of each body's first node in the user's numbering, whatever the
    run's node order (on 2 ranks the Z-ordered mesh listed the blocks of examples/block_on_block.toml the
    other way round), and each body's ``mass_effect`` from products with M alone (a distributed M) equal to
    the one from its block (serial)."""
    from pathlib import Path

    from signorini.dynamics.model.bodies import body_summaries
    from signorini.dynamics.model.problem import discretize
    from signorini.fem.mesh import read_mesh
    from signorini.fem.node_order import renumber
    from signorini.fem.space import Dirichlet

    class ProductsOnly:  # a stand-in for a distributed matrix: products, nothing else
        def __init__(self, M):
            self.M, self.shape = M, M.shape

        def __matmul__(self, x):
            return self.M @ x

    m = read_mesh(Path(__file__).parents[2] / "examples" / "meshes" / "ball_on_plate.msh")
    flipped = renumber(m, np.arange(m.n_nodes)[::-1].copy())  # the other body's nodes first
    out = {}
    for label, mesh in (("mesh", m), ("flipped", flipped)):
        p = Problem(mesh, IsotropicElastic.from_young(100, 0.3, 1), None, None, dirichlet=[Dirichlet("plate_sides")],
                    pairs=[ContactPair("ball_skin", "plate_top")])  # fmt: skip
        D = discretize(p, "moment-preserving")
        out[label] = body_summaries(mesh, D.M, D.material.rho, None)
        out[label + " products"] = body_summaries(mesh, ProductsOnly(D.M), D.material.rho, None)
    order = [b["regions"] for b in out["mesh"]]
    assert len(order) == 2 and all([b["regions"] for b in x] == order for x in out.values())
    for x in out.values():
        for a, b in zip(out["mesh"], x, strict=True):
            assert b["nodes"] == a["nodes"] and abs(b["mass"] - a["mass"]) <= 1e-12 * a["mass"]
            ea, eb = a["mass_effect"], b["mass_effect"]
            assert abs(eb["mass_ratio"] - ea["mass_ratio"]) <= 1e-12 and abs(eb["centre_shift"]) <= 1e-12
            assert eb["changes_physics"] == ea["changes_physics"] is False


def test_a_pair_facing_nothing_or_listed_twice_is_refused():
    """A pair whose slave nodes all lie beside the master surface could never touch (it ran to
    the end and then failed to write its history); a slave node in two pairs makes two equal
    rows (a singular Delassus matrix, found as a numerical failure mid-run)."""
    a, b = rectangle(10, 2, 1.0, 0.2), rectangle(3, 3, 0.3, 0.3)
    b.points = b.points + [5.0, 0.25]  # beside the plate
    m = join({"plate": a, "block": b})
    with pytest.raises(InputError, match="none of its 4 slave node.*faces the master surface"):
        simulate(Problem(m, IsotropicElastic.from_young(10.0, 0.3, 1.0), None, None,
                         pairs=[ContactPair("block_ymin", "plate_ymax")]), "cn", 0.01, 0.02)  # fmt: skip
    b.points = b.points - [4.5, 0.0]
    m = join({"plate": a, "block": b})
    with pytest.raises(InputError, match="contact pairs 0 .* and 1 .* share slave node"):
        simulate(Problem(m, IsotropicElastic.from_young(10.0, 0.3, 1.0), None, None,
                         pairs=[ContactPair("block_ymin", "plate_ymax")] * 2), "cn", 0.01, 0.02)  # fmt: skip
