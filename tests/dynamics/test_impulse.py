"""The ``impulse`` column: the contact impulse of each step, that of the scheme's momentum balance.

On a free bar (no Dirichlet condition, no load) the stiffness has the translations in its
kernel, so the momentum p = sum(M V) changes only by the contact: p^{n+1} - p^n = -P^{n+1}
(the obstacle's normal points into the bar; P <= 0).  That is exact for every scheme whose
balance is M (V^{n+1} - V^n) = ... + B^T P, and holds over the run for generalized-alpha.
"""

import json

import numpy as np
import pytest

from distinct_schemes import DISTINCT_SCHEMES
from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.model.problem import Problem, discretize
from signorini.dynamics.observe.diagnostics import impact_impulses
from signorini.dynamics.observe.history import HISTORY_COLUMNS, history_columns
from signorini.dynamics.schemes import SCHEMES
from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import interval
from signorini.io.cli import main

N, L, V0 = 20, 1.0, 0.5


def free_bar() -> Problem:
    """A free elastic bar (rho = E = 1) moving at V0 towards the plane x = 0, 0.1 away."""
    return Problem(
        mesh=interval(N, L),
        material=IsotropicElastic.from_young(1.0, 0.0, 1.0),
        contact_tag="xmin",
        obstacle=PlaneObstacle([0.0], [1.0]),
        u0=0.1,
        v0=-V0,
        name="free-bar",
    )


def _momentum_run(scheme: str, mass: str):
    p = free_bar()
    H = simulate(p, scheme, L / N / 2, 3.0, mass=mass, snapshot_every=1)
    M = discretize(p, mass).M
    momentum = np.array([(M @ v).sum() for v in H.snapshots["v"]])
    return H, momentum


@pytest.mark.parametrize("scheme", DISTINCT_SCHEMES)
def test_impulse_is_the_momentum_change_of_a_free_body(scheme):
    mass = "seed" if SCHEMES.get(scheme).obj.massless_dofs_allowed else "standard"
    H, p = _momentum_run(scheme, mass)
    assert H.status == "finished"
    imp = H.columns()["impulse"]
    assert np.isnan(imp[0]) and np.all(imp[1:] <= 1e-15)
    tol = 1e-13 * abs(p[0])
    if scheme in ("generalized-alpha", "hht"):  # weighted balance: over the run, not per step
        assert abs(p[-1] - p[0] + np.nansum(imp)) <= tol
    else:
        assert np.max(np.abs(np.diff(p) + imp[1:])) <= tol
    s = H.summary()
    assert s["impulse"] == pytest.approx(np.nansum(imp), rel=1e-14, abs=0)  # measured 0
    # one impact, a rebound: about -2 p0 (the exact elastic bar reverses its momentum); measured 1.2e-16
    assert len(s["impact_impulses"]) == 1 and s["impact_impulses"][0] == pytest.approx(
        s["impulse"], rel=1e-14, abs=0
    )  # measured 1.3e-16
    assert -2.05 * abs(p[0]) < s["impulse"] < -1.8 * abs(p[0])


def test_impulse_of_velocity_and_position_level_schemes():
    p = free_bar()
    dt = L / N / 2
    mj = simulate(p, "moreau-jean", dt, 2.0, mass="standard", scheme_options={"theta": 1.0})
    assert np.allclose(mj.columns()["impulse"][1:], dt * mj.lambda_sum[1:], rtol=1e-14, atol=0)  # force = P/dt
    cn = simulate(p, "crank-nicolson", dt, 2.0, mass="seed")
    trapezoid = 0.5 * dt * (cn.lambda_sum[1:] + cn.lambda_sum[:-1])
    assert np.allclose(cn.columns()["impulse"][1:], trapezoid, rtol=1e-14, atol=0)
    be = simulate(p, "backward-euler", dt, 2.0, mass="seed")
    assert np.allclose(be.columns()["impulse"][1:], dt * be.lambda_sum[1:], rtol=1e-14, atol=0)


def test_impact_impulses_windows():
    force = np.zeros(100)
    force[10:20] = -1.0
    force[60:65] = -2.0
    imp = np.concatenate([[np.nan], np.full(99, 0.0)])
    imp[10:21] = -0.5  # a trapezoidal step after the last force still carries some
    imp[60:65] = -1.0
    assert impact_impulses(force, imp) == pytest.approx([-5.5, -5.0], rel=1e-15, abs=0)  # sums of halves: exact
    assert impact_impulses(force, np.full(100, np.nan)) == []
    assert impact_impulses(np.zeros(100), imp) == []


def test_history_csv_and_summary_have_the_impulse(tmp_path):
    out = tmp_path / "r"
    assert main(["run", "bar1d-impact", "--scheme", "moreau-jean", "--mass", "standard", "--n", "20", "--T", "1",
                 "--out", str(out), "--quiet"]) == 0  # fmt: skip
    header = (out / "history.csv").read_text().splitlines()[0].split(",")
    # the fixed columns, then one reaction column per Dirichlet tag and component (the clamp)
    assert tuple(header) == history_columns(1) + ("reaction_xmax_x",) and header[16] == "impulse"
    assert tuple(header[: len(HISTORY_COLUMNS)]) == HISTORY_COLUMNS  # new columns only added after
    before = "t energy kinetic_energy elastic_energy energy_increment predicted_increment lambda_sum gap_mean gap_min "
    before += "active_contacts newton_iterations complementarity_residual external_work contact_work "
    before += "numerical_dissipation penetration"
    assert header[:16] == before.split()  # the columns written before, unchanged and in order (added after)
    rows = np.genfromtxt(out / "history.csv", delimiter=",", skip_header=1)
    s = json.loads((out / "summary.json").read_text())
    assert s["impulse"] == pytest.approx(np.nansum(rows[:, 16]), rel=1e-14, abs=0) and s["impulse"] < 0  # measured 0
    assert len(s["impact_impulses"]) == s["impacts"] >= 1
