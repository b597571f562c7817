"""The factor cache's owner (issue 39, item 1): one system per operator up to a positive factor,
released or kept on a ladder when the step changes, counters kept, warm starts passed on."""

from __future__ import annotations

import numpy as np
import pytest

from signorini.dynamics.model.operator import Operator
from signorini.dynamics.solve.factorizations import Factorizations
from signorini.errors import InputError


class _Solver:
    warm_state = ("active",)

    def __init__(self, nbytes: int):
        self.counters = {"factorizations": 1, "linear_solves": 0}
        self.factor_bytes = nbytes
        self.active = np.zeros(3, dtype=bool)


class _System:
    def __init__(self, op: Operator, nbytes: int = 100):
        self.op, self.solver = op, _Solver(nbytes)


def test_a_multiple_of_an_operator_shares_its_system():
    f = Factorizations(_System, 0.1)
    a, s = f.system(Operator(400.0, 1.0))
    b, s2 = f.system(Operator(100.0, 0.25))  # Paoli-Schatzman's M/dt^2 + S/4 against CN's 4 M/dt^2 + S
    assert a is b and s == 1.0 and s2 == pytest.approx(0.25, rel=1e-14, abs=0.0) and len(f.current) == 1
    c, _ = f.system(Operator(1.0, 1.0))
    assert c is not a and f.counters()["factorizations"] == 2
    with pytest.raises(InputError, match="non-negative coefficients"):
        f.system(Operator(-1.0, 1.0))


def test_replace_releases_the_systems_and_keeps_their_counters():
    f = Factorizations(_System, 0.1)
    sys, _ = f.system(Operator(1.0, 1.0))
    sys.solver.counters["linear_solves"] = 7
    f.replace(0.05, [Operator(4.0, 1.0)])
    assert f.dt == 0.05 and len(f.current) == 1 and f.current[0].op == Operator(4.0, 1.0)
    assert f.counters() == {"factorizations": 2, "linear_solves": 7}


def test_the_ladder_keeps_steps_passes_warm_starts_and_drops_the_least_recently_used():
    f = Factorizations(_System, 1.0)
    first = f.system(Operator(1.0, 1.0))[0]
    first.solver.active[:] = [True, False, True]
    f.use(0.5, [Operator(4.0, 1.0)], keep_bytes=1e9)
    half = f.current[0]
    assert np.array_equal(half.solver.active, [True, False, True])  # passed on, a copy
    assert half.solver.active is not first.solver.active
    assert [dt for dt, _ in f.by_step()] == [1.0, 0.5] and len(f.every()) == 2
    f.use(1.0, [], keep_bytes=1e9)  # taken back, not factorized again
    assert f.current[0] is first and f.counters()["factorizations"] == 2
    f.use(0.25, [Operator(16.0, 1.0)], keep_bytes=150)  # two kept steps of 100 bytes: the older goes
    assert [dt for dt, _ in f.by_step()] == [1.0, 0.25]
    assert f.counters()["factorizations"] == 3  # the dropped step's counters are kept
