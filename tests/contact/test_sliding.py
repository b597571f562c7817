"""Small sliding of contact pairs (contact/pairs.py slid_rows, ContactSet.slide, Context.slide,
the Delassus columns' replace_rows): a slave node whose projection leaves its master facet is
re-paired to the facet it faces, its row of B and its Delassus column recomputed.

Case: a Q1 block (4 cells, 5 slave nodes, h = 0.1) sliding without friction at 1 m/s under
gravity over a clamped plate (16 facets of 0.125): in 1 s every slave node crosses 8 facet
edges: 40 re-pairings.  Measured: energy identity 1.0e-11 (CN), 1.4e-11 (BE), 1.3e-11 (HHT)
of E0 with re-pairing (it was 2.7e-3 before the levels' own rows entered the identity); cg
equals the direct solve to 1.5e-12 of the energy.
"""

import numpy as np
import pytest
import scipy.sparse as sp

from signorini.contact.delassus import DelassusColumns
from signorini.contact.pairs import ContactPair
from signorini.dynamics.model.problem import Problem, RegionInitial
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import join, rectangle
from signorini.fem.space import Dirichlet
from signorini.linalg import factorize


def sliding_block(friction=None, x0: float = 0.2) -> Problem:
    a, b = rectangle(16, 2, 2.0, 0.25), rectangle(4, 2, 0.4, 0.2)
    b.points = b.points + [x0, 0.25]
    m = join({"plate": a, "block": b})
    return Problem(m, IsotropicElastic.from_young(1000, 0.3, 1), None, None, dirichlet=[Dirichlet("plate_ymin")],
                   initial_regions=[RegionInitial("block", velocity=[1.0, 0.0])], gravity=[0, -10.0],
                   pairs=[ContactPair("block_ymin", "plate_ymax", friction=friction)])  # fmt: skip


@pytest.mark.parametrize("scheme", ["cn", "be", "hht"])
def test_a_sliding_block_is_re_paired_and_keeps_the_energy_identity(scheme):
    H = simulate(sliding_block(), scheme, 0.005, 1.0)
    assert H.status == "finished", H.message
    # 40 facet crossings, and the node at x = 0.5 that starts on a shared vertex: the tie goes to the
    # facet whose centre is first in x (a rule of the geometry), which it leaves at once
    assert H.counters["pair_rows_repaired"] == 41 and H.meta["pairs"][0]["repaired_rows"] == 41
    E0 = H.energy[0]
    assert H.summary()["energy_identity_residual"] <= 1e-9 * E0 / 0.04  # measured 1.0e-11 .. 1.4e-11 (E0 = 0.04)
    assert H.gap.min() >= -1e-15


def test_before_the_first_re_pairing_the_run_is_the_frozen_one_and_after_it_is_not():
    H = simulate(sliding_block(x0=0.21), "cn", 0.005, 1.0)
    F = simulate(sliding_block(x0=0.21), "cn", 0.005, 1.0, solver_options={"pairing": "frozen"})
    assert F.counters["pair_rows_repaired"] == 0
    # slave nodes at x = 0.21 .. 0.61, facet edges every 0.125: the first crossing is at x = 0.625
    # after 0.015 m (t = 0.015, level 3 at 1 m/s): the levels before it are the same arrays
    first = 3
    assert np.array_equal(H.lam[:first], F.lam[:first]) and np.array_equal(H.energy[:first], F.energy[:first])
    assert np.abs(H.lam[-1] - F.lam[-1]).max() > 1e-6 * np.abs(F.lam[-1]).max()


def test_the_slave_nodes_face_the_facets_under_them_at_the_end():
    from signorini.dynamics.model.problem import discretize
    from signorini.dynamics.solve.context import Context

    p = sliding_block()
    disc = discretize(p)
    ctx = Context(disc, 0.005)
    U = np.zeros(disc.space.n_dofs)
    U.reshape(-1, 2)[p.mesh.region_nodes("block"), 0] = 0.93  # the block moved by 0.93 along x
    assert ctx.slide(U, 0.0) == 5
    c = disc.contact
    top = p.mesh.facets_of("plate_ymax")
    x = p.mesh.points[c.nodes, 0] + 0.93
    lo, hi = p.mesh.points[top[c.master_facet], 0].min(axis=1), p.mesh.points[top[c.master_facet], 0].max(axis=1)
    assert np.all((lo <= x + 1e-12) & (x <= hi + 1e-12))
    # the new rows measure the current normal gap: 0 for a block resting on the plate
    assert np.abs(c.gaps - c.B @ U).max() <= 1e-15
    # and B's new rows are the slave node against the facet's nodes at the shape functions of x
    N = c.master_shape
    assert np.allclose(N.sum(axis=1), 1.0, rtol=0, atol=1e-15)


def test_cg_follows_the_sliding_as_the_direct_solve():
    H = simulate(sliding_block(), "cn", 0.005, 0.5)
    G = simulate(sliding_block(), "cn", 0.005, 0.5, solver_options={"backend": "cg", "rtol": 1e-13})
    assert G.counters["pair_rows_repaired"] == H.counters["pair_rows_repaired"] > 0
    assert np.abs(G.energy - H.energy).max() <= 1e-9 * H.energy[0]  # measured 1.5e-12
    assert np.abs(G.lambda_sum - H.lambda_sum).max() <= 1e-7 * np.abs(H.lambda_sum).max()


def test_friction_follows_the_re_paired_rows():
    H = simulate(sliding_block("coulomb:0.2"), "be", 0.005, 1.0)
    assert H.status == "finished" and H.counters["pair_rows_repaired"] > 0
    assert H.summary()["energy_identity_residual"] <= 1e-10 * H.energy[0]  # measured 8.4e-13
    # Coulomb's cone on every row at every level
    assert np.all(np.abs(H.lam_t[..., 0]) <= 0.2 * np.abs(H.lam) * (1 + 1e-12) + 1e-15)


def test_schur_cannot_follow_the_sliding():
    with pytest.raises(InputError, match="condensation='schur' cannot follow contact pairs"):
        simulate(sliding_block(), "cn", 0.005, 0.01, solver_options={"backend": "superlu", "condensation": "schur"})


def test_delassus_columns_after_replaced_rows_are_the_recomputed_ones():
    """W after replace_rows (stored and new columns, with and without Z kept) = B' K^-1 B'^T of
    the new B' computed afresh; measured 3e-16 of max|W|."""
    rng = np.random.default_rng(3)
    n, nc = 40, 9
    A = sp.random(n, n, density=0.2, random_state=rng)
    K = (A @ A.T + 5 * sp.eye(n)).tocsc()
    B = sp.random(nc, n, density=0.2, random_state=rng, format="csr")
    for budget in (1e9, 0.0):
        D = DelassusColumns(factorize(K, "superlu"), B, budget)
        D.ensure(np.array([0, 2, 3, 5]))
        B2 = B.tolil()
        B2[[2, 7]] = sp.random(2, n, density=0.3, random_state=rng).toarray()
        B2 = B2.tocsr()
        D.replace_rows(np.array([2, 7]), B2)
        D.ensure(np.arange(nc))
        W = (B2 @ sp.linalg.spsolve(K, B2.T.toarray())).astype(float)
        assert np.abs(D.W(np.arange(nc), np.arange(nc)) - W).max() <= 1e-13 * np.abs(W).max()


def test_replaced_rows_update_their_columns_from_cached_dof_columns():
    """With Z kept, a re-paired row's column is updated from K^-1 e_k of the dofs where its row
    changed (solved once, in blocks): twenty re-pairings back and forth between two sets of dofs
    solve each dof's column once, and W stays B' K^-1 B'^T of the current B' (measured 1e-15
    of max|W| after the twenty updates; drift of the updates included)."""
    rng = np.random.default_rng(4)
    n, nc = 60, 8
    A = sp.random(n, n, density=0.2, random_state=rng)
    K = (A @ A.T + 5 * sp.eye(n)).tocsc()
    base = sp.random(nc, n, density=0.1, random_state=rng).toarray()
    facets = [rng.random((2, 4)) for _ in range(2)]  # two "master facets": rows 3 and 5 move between them
    dofs = [np.array([10, 11, 12, 13]), np.array([20, 21, 22, 23])]

    def B_on(k: int) -> sp.csr_matrix:
        B = base.copy()
        for r, w in zip((3, 5), facets[k], strict=True):
            B[r, dofs[k]] = w
        return sp.csr_matrix(B)

    D = DelassusColumns(factorize(K, "superlu"), B_on(0), 1e9)
    D.ensure(np.arange(nc))
    solved = D.solved
    for i in range(1, 21):
        D.replace_rows(np.array([3, 5]), B_on(i % 2))
    assert D.dof_columns == 8 and D.solved == solved + 8  # the 8 dofs of both facets, once each
    B = B_on(0)
    W = B @ sp.linalg.spsolve(K, B.T.toarray())
    assert np.abs(D.W(np.arange(nc), np.arange(nc)) - W).max() <= 1e-13 * np.abs(W).max()
    Z = sp.linalg.spsolve(K, B.T.toarray())
    lam = rng.random(nc)
    assert np.abs(D.Z_times(np.arange(nc), lam) - Z @ lam).max() <= 1e-13 * np.abs(Z @ lam).max()


@pytest.mark.parametrize("friction", [None, "coulomb:0.3"])
def test_sliding_does_not_depend_on_the_node_numbering(friction):
    """Matching faces (every slave node on a master vertex, facets tied): a tie goes to the
    nearest facet centre, then the first centre in (x, y, z), rules of the geometry.  The same
    two free bodies with their nodes randomly renumbered give the same run; measured 8e-13 of
    the energy, 4e-14 of the force (it was 1e-2 with ties broken by the candidates' order)."""
    from signorini.fem.node_order import renumber

    a, b = rectangle(12, 2, 1.2, 0.2), rectangle(4, 2, 0.4, 0.2)
    b.points = b.points + [0.3, 0.2]  # touching, the block's nodes on the plate's vertices
    m = join({"plate": a, "block": b})
    perm = np.random.default_rng(5).permutation(m.n_nodes)
    runs = []
    for mesh in (m, renumber(m, perm)):
        p = Problem(mesh, IsotropicElastic.from_young(100, 0.3, 1), None, None,
                    initial_regions=[RegionInitial("block", velocity=[1.0, -0.3])],
                    pairs=[ContactPair("block_ymin", "plate_ymax", friction=friction)])  # fmt: skip
        runs.append(simulate(p, "cn", 0.002, 0.3))
    H, G = runs
    assert H.counters["pair_rows_repaired"] == G.counters["pair_rows_repaired"] > 0
    assert np.abs(H.energy - G.energy).max() <= 1e-10 * np.abs(H.energy).max()
    assert np.abs(H.lambda_sum - G.lambda_sum).max() <= 1e-10 * np.abs(H.lambda_sum).max()
