"""Penalty contact with CN: penetration O(1/stiffness), CN identity, one factorization."""

import numpy as np
import pytest

from signorini.dynamics.stepping.simulate import simulate
from signorini.studies.benchmarks import get_benchmark


def _run(n, stiffness, mass="standard"):
    b = get_benchmark("bar1d-impact")
    dt = b.h(n) / 2
    return simulate(b.problem(n), "penalty", dt, dt * round(1.5 / dt), mass=mass,
                    scheme_options={"stiffness": stiffness})  # fmt: skip


@pytest.mark.parametrize("mass", ["standard", "seed"])
def test_penetration_decreases_like_one_over_stiffness(mass):
    pens = [_run(80, k, mass).summary()["penetration_max"] for k in (10.0, 100.0, 1000.0)]
    ratios = np.array(pens[:-1]) / np.array(pens[1:])
    assert np.all((3.0 < ratios) & (ratios < 15.0)), ratios  # about 10 per decade of stiffness
    assert pens[-1] < 1e-4


def test_cn_energy_identity_and_single_factorization():
    H = _run(40, 100.0)
    ok = np.isfinite(H.predicted_increment)
    assert ok[1:].all()
    assert np.abs(H.energy_increment - H.predicted_increment)[ok].max() <= 5e-13 * H.energy[0]  # measured 9.7e-15
    assert H.counters["factorizations"] == 1 and H.lam.max() <= 0 and H.lam.min() < 0


def test_penalty_force_law():
    """lambda_i = -k_i max(0, -gap_i) at every level (k_i = stiffness E / h in 1D)."""
    b = get_benchmark("bar1d-impact")
    H = _run(40, 50.0)
    k = 50.0 * b.params()["E"] / b.h(40)
    assert np.allclose(H.lam, -k * np.maximum(0.0, -H.gap), rtol=1e-13, atol=1e-15)  # |lam| <= 2.3: measured 4e-15
