"""rings2d (issue 41): two Neo-Hookean rings colliding obliquely, a contact pair in the current configuration."""

from __future__ import annotations

import pytest

from signorini.dynamics.stepping.simulate import simulate
from signorini.studies.benchmarks import get_benchmark


def _run(scheme: str, mass: str, T: float = 0.3, check: str = "fail"):
    b = get_benchmark("rings2d")
    p = b.params({})
    dt, _ = b.run_times(1, {})
    m = b.measure(p)
    H = simulate(b.problem(1, {}), scheme, dt, T, mass=mass, solver_options={"energy_check": check})
    assert H.status == "finished", H.message
    return H, m.summary(H)["rings"]


def test_energy_momentum_through_the_rings_impact_against_crank_nicolson_with_the_standard_mass():
    """Energy-momentum with the default mass (the outer circles massless), the whole run (T = 1: the rings
    touch from t = 0.025 to 0.97): the identity closed at every level, the energy within 1e-3 of E0 (issue 41;
    measured 8.6e-4), the linear and the angular momentum within 1e-9 of their initial values (measured
    3e-12 and 4.5e-12 against each ring's 1.1: the momentum projection; 5e-4 and 1.4e-4 without it), no node
    through the other ring, every slave node a row (none facing nothing).  Crank-Nicolson with the standard
    mass on the same steps to t = 0.3: the energy error and the contact force's peak both larger (shown
    beside it)."""
    H, s = _run("energy-momentum", "moment-preserving", T=1.0)
    assert s["contact_start"] is not None and s["contact_end"] > 0.5 and s["energy_max_relative_drift"] <= 1e-3, s
    assert s["momentum_max_drift"] <= 1e-9 and s["angular_momentum_max_drift"] <= 1e-9, s
    assert H.gap.min() >= -1e-10 and H.meta["pairs"][0]["rows"] == 32
    Hc, c = _run("crank-nicolson", "standard", check="warn")  # it creates energy: the check would stop it
    assert Hc.summary()["energy_identity_residual"] < 1e-10
    early = H.t <= Hc.t[-1] * (1 + 1e-12)  # the same levels
    drift = float(abs(H.energy[early] - H.energy[0]).max() / abs(H.energy[0]))
    assert c["energy_max_relative_drift"] > 3 * drift, (c, drift)
    assert c["peak_contact_force"] > -H.lambda_sum[early].min(), (c, s)


@pytest.mark.slow
def test_quadratic_rings_collide_as_the_linear_ones():
    """rings2d --set order=2 (curved quad9 rings, 1,280 dofs; pairs in the current configuration on curved
    facets), its default scheme and mass to its default T: measured energy drift 7.4e-4 (linear: 7.7e-4), momentum
    2.2e-13 (5.7e-13), angular momentum 1.8e-4 (9.7e-5), peak force 5.06 (5.74: the linear rings are stiffer)."""
    b = get_benchmark("rings2d")
    p = b.params({"order": 2})
    dt, T = b.run_times(1, p)
    H = simulate(b.problem(1, p), "crank-nicolson", dt, T)
    assert H.status == "finished", H.message
    s = b.measure(p).summary(H)["rings"]
    assert s["energy_max_relative_drift"] <= 2e-3 and s["momentum_max_drift"] <= 1e-11, s
    assert H.meta["pairs"][0]["rows"] == 64  # every node of the slave ring's outer circle: 32 vertices, 32 mid-sides
