"""Contact pairs in the current configuration (finite strain) on quadratic cells (issue 54, item 3): two free
Neo-Hookean quad9 blocks collide obliquely; the pair's forces balance (the total momentum kept to round-off), the
energy identity closes, the slave rows take every node of the slave side, and the impact ends."""

import numpy as np

from signorini.contact.pairs import ContactPair
from signorini.dynamics.model.problem import Problem, RegionInitial
from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.material import NeoHookean
from signorini.fem.mesh import join, rectangle


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
