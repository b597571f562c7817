"""The momentum projection of energy-momentum with finite strain (signorini.dynamics.momentum_projection):
the correction is a rigid motion of the nodes with mass, gives the momenta exactly what it is asked, is the
closest such field in M's norm, and runs only where the summary says it does."""

import numpy as np
import pytest

from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.momentum_projection import momenta, rigid_fields, velocity_correction
from signorini.dynamics.problem import Problem, discretize
from signorini.dynamics.simulate import simulate
from signorini.fem.material import NeoHookean
from signorini.fem.mesh import box, rectangle


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("mass", ["standard", "moment-preserving"])
def test_the_correction_gives_the_momenta_asked_and_is_the_closest_rigid_field(dim, mass):
    mesh = rectangle(4, 3, 1.0, 0.6) if dim == 2 else box(3, 2, 2, 1.0, 0.6, 0.5)
    tag = "ymin" if dim == 2 else "zmin"
    floor = PlaneObstacle([0.0] * (dim - 1) + [-1.0], [0.0] * (dim - 1) + [1.0])
    disc = discretize(Problem(mesh, NeoHookean.from_young(100.0, 0.3, 1.0), tag, floor), mass)
    M = disc.M.tocsr()
    n = M.shape[0]
    rng = np.random.default_rng(3)
    X = mesh.points
    U0, U1, h = 0.1 * rng.standard_normal(n), 0.1 * rng.standard_normal(n), rng.standard_normal(n)
    massive = np.asarray(abs(M).sum(axis=1)).ravel() > 0
    assert massive.all() == (mass == "standard")
    dt = 0.01
    dV = velocity_correction(M, X, U0, U1, h, dt, massive)
    x1, x_mid = X + U1.reshape(-1, dim), X + 0.5 * (U0 + U1).reshape(-1, dim)
    want = dt * momenta(x_mid, h)
    assert np.allclose(momenta(x1, M @ dV), want, rtol=1e-12, atol=1e-14 * np.abs(want).max())
    assert not dV[~massive].any()
    G = rigid_fields(x1, massive)
    a = np.linalg.lstsq(G, dV, rcond=None)[0]
    assert np.abs(G @ a - dV).max() <= 1e-12 * np.abs(dV).max()  # a rigid motion
    # any other field with the same momenta is farther from 0 in M's norm: add one whose momenta vanish
    w = rng.standard_normal(n) * massive
    C = np.column_stack([momenta(x1, M @ G[:, j]) for j in range(G.shape[1])])
    w -= G @ np.linalg.solve(C, momenta(x1, M @ w))
    assert np.abs(momenta(x1, M @ w)).max() <= 1e-10 * np.abs(M @ w).max()
    assert (dV + w) @ (M @ (dV + w)) > dV @ (M @ dV)


def test_the_summary_says_where_it_runs():
    """On with energy-momentum and finite strain; off with the option, with a linear body, with another scheme,
    and for a body with a prescribed motion (its reactions change the momenta)."""
    mesh = rectangle(4, 2, 1.0, 0.5)
    floor = PlaneObstacle([0.0, -1.0], [0.0, 1.0])
    neo = NeoHookean.from_young(100.0, 0.3, 1.0)
    free = Problem(mesh, neo, "ymin", floor, v0=lambda x: np.column_stack([-(x[:, 1] - 0.25), x[:, 0] - 0.5]))
    on = lambda p, scheme="energy-momentum", **o: simulate(p, scheme, 0.02, 0.06, solver_options=o).meta[  # noqa: E731
        "momentum_projection"
    ]
    assert on(free) is True
    assert on(free, momentum_projection=False) is False
    assert on(free, "crank-nicolson") is False
    from signorini.fem.material import IsotropicElastic

    assert on(Problem(mesh, IsotropicElastic.from_young(100.0, 0.3, 1.0), "ymin", floor)) is False
    from signorini.fem.space import Dirichlet

    clamped = Problem(mesh, neo, "ymax", PlaneObstacle([0.0, 2.0], [0.0, -1.0]), dirichlet=[Dirichlet("ymin", 0.0)])
    assert on(clamped) is False
