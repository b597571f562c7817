"""Diagnostics of a history: penetration, oscillation index per impact, identity residual."""

import numpy as np
import pytest

from signorini.dynamics.observe.diagnostics import impact_windows, oscillation_index, oscillation_indices, penetration
from signorini.dynamics.stepping.simulate import simulate
from signorini.studies.benchmarks import get_benchmark


def test_penetration_is_the_largest_violation_per_level():
    gap = np.array([[0.1, 0.2], [-0.01, 0.3], [0.0, -0.5]])
    assert np.array_equal(penetration(gap), [0.0, 0.01, 0.5])
    assert penetration(np.zeros((3, 0))).tolist() == [0.0, 0.0, 0.0]


def test_oscillation_index_values():
    pulse = np.concatenate([np.zeros(5), np.sin(np.linspace(0, np.pi, 30)[1:-1]), np.zeros(40)])
    assert oscillation_index(None, -pulse) == pytest.approx(1.0, rel=1e-14, abs=0)  # measured 1.1e-16
    dip = -pulse.copy()
    dip[15] *= 0.5  # a dip of depth ~0.5 peak
    assert 1.3 < oscillation_index(None, dip) < 1.6
    two = np.concatenate([-pulse, -0.5 * pulse])
    assert len(impact_windows(two)) == 2
    assert oscillation_indices(two) == pytest.approx([1.0, 1.0], rel=1e-14, abs=0)  # measured 1.1e-16
    assert oscillation_index(None, np.zeros(10)) == 0.0


@pytest.mark.parametrize("scheme, mass", [("cn", "seed"), ("cn", "standard"), ("generalized-alpha", "seed")])
def test_summary_diagnostics_of_exact_contact_schemes(scheme, mass):
    b = get_benchmark("bar1d-impact")
    H = simulate(b.problem(40), scheme, b.h(40) / 2, 3.0, mass=mass)
    d = H.summary()
    # measured 1.7e-18 and 4.3e-20 (gap 0.1-1): bounds 1e-14, the round-off floor
    assert d["penetration_max"] <= 1e-14 and d["penetration_time_integral"] <= 1e-14
    assert d["energy_identity_residual"] <= 1e-12  # relative to max |E|; measured 1.7e-14
    assert len(d["impact_oscillation_indices"]) >= 1 and d["oscillation_index"] >= 1.0 - 1e-12
    assert "penetration" in H.columns()
    if mass == "standard":  # spec 3.3: the standard mass makes the force oscillate
        assert d["oscillation_index"] > 2.0
    else:
        assert d["oscillation_index"] < 1.5
