"""Contact pairs in the current configuration (finite strain) on quadratic cells (issue 54, item 3): two free
Neo-Hookean quad9 blocks collide obliquely; the pair's forces balance (the total momentum kept to round-off), the
energy identity closes, the slave rows take every node of the slave side, and the impact ends."""

import numpy as np

from backends import needs_gmsh
from signorini.contact.pairs import ContactPair, pair_rows
from signorini.dynamics.model.problem import Problem, RegionInitial
from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.material import NeoHookean
from signorini.fem.mesh import box, join, rectangle
from test_quadratic import serendipity


def test_free_neo_hookean_quadratic_blocks_collide_keeping_momentum():
    """Measured: momentum drift 1.7e-14 of |P| (the linear blocks of the same nodes: 1.9e-14), the energy identity
    4.6e-12 (linear: 3.0e-11), 5 slave rows (3 vertices and 2 mid-side nodes)."""
    lower = rectangle(2, 1, 0.2, 0.1, order=2)
    upper = rectangle(2, 1, 0.2, 0.1, order=2)
    upper.points = upper.points + [0.05, 0.11]
    mesh = join({"lower": lower, "upper": upper})
    material = NeoHookean.from_young(100.0, 0.3, 1.0)
    problem = Problem(mesh, material, None, None, pairs=[ContactPair("upper_ymin", "lower_ymax")],
                      initial_regions=[RegionInitial("upper", velocity=[0.2, -1.0])])  # fmt: skip
    H = simulate(problem, "crank-nicolson", 0.002, 0.06)
    assert H.status == "finished", H.message
    assert H.nodes.size == 5
    assert H.lambda_sum.min() < 0 and H.lambda_sum[-1] == 0  # an impact, over by T
    P = np.asarray(H.momentum)
    assert np.abs(P - P[0]).max() <= 1e-12 * np.abs(P[0]).max()
    assert H.summary()["energy_identity_residual"] < 1e-10


def test_pairs_between_serendipity_blocks():
    """hexahedron20 blocks (quad8 facets: curved-capable, 8 nodes): every node of the slave side a row (a 3 x 3
    side: 16 vertices and 24 mid-side nodes), its gap the blocks' distance, its row 8 master shape functions
    summing to 1 (a rigid translation leaves every gap unchanged)."""
    lower, upper = serendipity(box(2, 2, 1, order=2)), serendipity(box(3, 3, 1, order=2))
    upper.points = upper.points + [0.0, 0.0, 1.02]
    mesh = join({"lower": lower, "upper": upper})
    r = pair_rows(mesh, ContactPair("upper_zmin", "lower_zmax"), 3 * mesh.n_nodes)
    assert r.nodes.size == 40 and r.xi.shape == (40, 8)
    assert np.allclose(r.gaps, 0.02, rtol=0, atol=1e-15) and np.allclose(r.xi.sum(axis=1), 1.0, rtol=0, atol=1e-14)
    assert np.abs(r.B @ np.tile([0.3, -0.2, 0.7], mesh.n_nodes)).max() < 1e-14


@needs_gmsh
def test_a_curved_tetra10_ball_on_a_hexahedron27_plate():
    """Issue 54's curved pair: a steel ball of tetra10 cells (gmsh puts its mid-side nodes on the sphere: curved
    slave facets; R = 5 cm) hits a free hexahedron27 plate at 1 m/s; both free, CN, the default mass, 100 steps
    through the impact.  Measured: the momentum kept to 4.6e-11 of |P| (2.5e-12 in flight, the impact's contact
    solves the rest; at dt / 2.5 1.7e-10: round-off per step of the total displacement), penetration 2.7e-20 m,
    the identity 3.5e-12."""
    import math

    from signorini.fem.material import IsotropicElastic
    from signorini.fem.meshing import pole_refined_ball

    ball = pole_refined_ball(3, 0.05, math.radians(60.0), 0.006, 0.02, 0.02, order=2)
    plate = box(4, 4, 1, 0.2, 0.2, 0.02, order=2)
    plate.points = plate.points + [-0.1, -0.1, -0.0201]  # its top 0.1 mm below the ball's pole
    mesh = join({"plate": plate, "ball": ball})
    assert [b.cell_type for b in mesh.blocks] == ["hexahedron27", "tetra10"]
    problem = Problem(mesh, IsotropicElastic.from_young(2e11, 0.3, 7800.0), None, None,
                      pairs=[ContactPair("ball_cap", "plate_zmax")],
                      initial_regions=[RegionInitial("ball", velocity=[0.0, 0.0, -1.0])])  # fmt: skip
    H = simulate(problem, "crank-nicolson", 5e-6, 5e-4)
    assert H.status == "finished" and H.impacts == 1
    assert H.lambda_sum.min() < 0 and H.lambda_sum[-1] == 0  # the impact is over by T
    P = np.asarray(H.momentum)
    assert np.abs(P - P[0]).max() <= 1e-10 * np.abs(P[0]).max()
    s = H.summary()
    assert s["penetration_max"] <= 1e-10 * 0.1 and s["energy_identity_residual"] < 1e-10
