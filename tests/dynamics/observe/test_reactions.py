"""Reaction forces per Dirichlet tag (``reaction_<tag>_<axis>`` in history.csv): with the loads
and the contact forces they balance the momentum, step by step (issue 38)."""

import dataclasses

import numpy as np
import pytest

from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.space import Dirichlet
from signorini.studies.benchmarks import get_benchmark


def _total_load(H, problem, mass):
    """(N+1, d) the total load 1_k^T F(t) per level (body forces, tractions, gravity as M g)."""
    from signorini.dynamics.model.problem import discretize

    disc = discretize(problem, mass)
    d = problem.mesh.dim
    return np.array([disc.load(t).reshape(-1, d).sum(axis=0) for t in H.t])


@pytest.mark.parametrize("mass", ["standard", "moment-preserving"])
@pytest.mark.parametrize("gravity", [None, [0.3, -9.81]])
def test_reactions_loads_and_contact_balance_the_momentum(mass, gravity):
    """Crank-Nicolson on the paper's bar, clamped at its top, falling onto the obstacle (with and
    without gravity): p^{n+1} - p^n = dt/2 sum_{n, n+1} (F + contact force + reactions), per
    component, to round-off of the largest term (measured 5e-14 to 3.6e-13 of dt max|force|; asserted
    1e-10; 1^T S U = 0: a translation is stress-free)."""
    b = get_benchmark("bar2d")
    p = b.problem(4, {})
    if gravity is not None:
        p = dataclasses.replace(p, gravity=gravity)
    dt, T = b.run_times(4, {})
    H = simulate(p, "cn", dt, T, mass=mass)
    assert H.reaction_columns == ("reaction_ymax_x", "reaction_ymax_y")
    assert H.lam.min() < 0  # contact
    R = H.reaction[:, 0, :]
    F = _total_load(H, p, mass)
    force = F + H.contact_force + R
    lhs = np.diff(H.momentum, axis=0)
    rhs = 0.5 * dt * (force[1:] + force[:-1])
    scale = dt * np.abs(force).max()
    assert np.abs(lhs - rhs).max() <= 1e-10 * scale
    assert np.abs(R).max() > 10 * np.abs(lhs - rhs).max()  # the reactions are not negligible


def test_a_dof_fixed_by_two_tags_counts_once_and_columns_follow_the_tags(tmp_path):
    """Two clamped sides sharing a corner: one column per tag and component, the corner in the
    first tag only (the sum over tags is the total reaction); history.csv has the columns last."""
    from signorini.io.cli import main

    b = get_benchmark("bar2d")
    p = b.problem(2, {})
    p2 = dataclasses.replace(p, dirichlet=[Dirichlet("ymax", [0.0, 0.2]), Dirichlet("xmax", 0.0, (0,))])
    H = simulate(p2, "cn", 0.025, 0.2)
    assert H.reaction_columns == ("reaction_ymax_x", "reaction_ymax_y", "reaction_xmax_x", "reaction_xmax_y")
    assert np.all(H.reaction[:, 1, 1] == 0.0)  # xmax fixes x only
    assert main(["run", "bar2d", "--n", "1", "--T", "0.1", "--quiet", "--out", str(tmp_path / "o")]) == 0
    header = (tmp_path / "o" / "history.csv").read_text().splitlines()[0].split(",")
    assert header[-2:] == ["reaction_ymax_x", "reaction_ymax_y"]
    assert header[-10:-2] == [
        "momentum_x",
        "momentum_y",
        "dt",
        "damping_dissipation",
        "angular_momentum_z",
        "nonlinear_iterations",
        "solver_work",
        "master_penetration",
    ]
