"""Every registered scheme on the 1D exact benchmark (non-default parameters L = 2, E = 4,
gap = 0.3; dt = h/2; T = 3), n = 40, 80, 160 against the exact solution.

Observed rates are data (two-sided bands around the measured values, recorded in
docs/schemes.md); the known qualitative facts are asserted: CN with the standard mass
does not converge in H1/stress, with a redistributed mass it does; backward Euler is
first order in L2 at best; the energy-conserving (persistency) scheme does not converge
in stress (e = 1 at every step chatters).  About 8 s.
"""

import numpy as np
import pytest

from distinct_schemes import REPEATS
from exact_bar import exact_bar_runs
from signorini.dynamics.schemes import SCHEMES
from signorini.studies.study import observed_rates

LEVELS = (40, 80, 160)
NOT_CONVERGING_STANDARD = {"crank-nicolson", "generalized-alpha", "penalty"}  # default options


def _errors(scheme: str, mass: str) -> tuple[np.ndarray, list[float]]:
    runs = exact_bar_runs(scheme, mass, LEVELS)
    return np.array([[e["u_L2"], e["u_H1"], e["stress"]] for *_, e in runs]), [h for _, h, _, _ in runs]


CASES = [
    (e.name, m)
    for e in SCHEMES
    if e.name not in REPEATS  # newmark and theta at their defaults: crank-nicolson and backward-euler again
    for m in ("standard", "seed")
    if m == "standard" or e.obj.massless_dofs_allowed
]


@pytest.mark.parametrize("scheme, mass", CASES)
def test_every_scheme_on_the_exact_1d_bar(scheme, mass):
    err, hs = _errors(scheme, mass)
    r_l2 = np.asarray(observed_rates(err[:, 0], hs))
    r_h1 = np.asarray(observed_rates(err[:, 1], hs))
    if mass == "standard" and scheme in NOT_CONVERGING_STANDARD:
        # spec 3.3: CN-type schemes with the standard mass do not converge in H1 (measured 1.00 -> 1.44)
        assert err[-1, 1] > err[0, 1] and err[-1, 2] > 1.0
        return
    assert np.all((0.4 < r_l2) & (r_l2 < 1.2)), r_l2  # measured 0.5 - 1.1
    assert np.all((0.2 < r_h1) & (r_h1 < 0.5)), r_h1  # measured 0.25 - 0.44
    assert err[-1, 1] < 0.26  # finest H1 error, measured 0.13 - 0.25
    if scheme == "energy-conserving":
        assert err[-1, 2] > 0.9  # the stress does not converge (measured 0.99)
    elif scheme == "energy-momentum" and mass == "standard":
        # the midpoint rule with the contact nodes' inertia: the displacement converges (H1 0.25 -> 0.16),
        # the stress chatters (measured 0.65, 0.54, 0.61); with a massless contact it is Crank-Nicolson's
        assert err[-1, 2] > 0.5
    else:
        assert err[-1, 2] < 0.3 and err[-1, 2] < err[0, 2]  # measured 0.088 - 0.29
