"""Rollback (issue 39, item 2's verification): a step taken, its solvers' warm starts put back
(what the energy control does on a rejected step), and taken again gives the same bits, for every
scheme, with Coulomb friction and with contact pairs re-pairing as they slide."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from signorini.dynamics.model.problem import RegionInitial, with_friction
from signorini.dynamics.schemes import SCHEMES, friction_schemes
from signorini.dynamics.stepping.simulate import Stepper
from signorini.errors import InputError
from signorini.io.config import load_case
from signorini.studies.benchmarks import get_benchmark


def _same_step_twice(stepper: Stepper, before: int) -> None:
    """Step ``before`` levels (a contact building up), then take the next step, roll it back and
    take it again: U, V, A, lambda, lambda_t and the iteration count equal bit for bit."""
    for _ in range(before):
        assert stepper.step() == "running"
    n = stepper.n + 1
    saved = stepper.solvers.point()
    first, why = stepper.trial(n)
    assert first is not None, why
    stepper.solvers.put_back(saved)
    again, why = stepper.trial(n)
    assert again is not None, why
    for name in ("U", "V", "A", "lam"):
        assert np.array_equal(getattr(first, name), getattr(again, name)), name
    if first.lam_t is not None:
        assert np.array_equal(first.lam_t, again.lam_t)
    assert first.info.iterations == again.info.iterations
    stepper.finish()


def _stepper(problem, scheme: str, dt: float, T: float, mass: str) -> Stepper | None:
    try:
        return Stepper(problem, scheme, (dt, T), {"mass": mass})
    except InputError:  # the scheme refuses the mass (tests/dynamics/test_schemes.py says why)
        return None


@pytest.mark.parametrize("mass", ["standard", "moment-preserving"])
@pytest.mark.parametrize("scheme", SCHEMES.names(aliases=False))
def test_a_rolled_back_step_is_the_same_step(scheme, mass):
    """bar2d at the level after its first contact (the steps before make the warm starts)."""
    b = get_benchmark("bar2d")
    p = b.problem(4, {})
    dt, T = b.run_times(4, {})
    s = _stepper(p, scheme, dt, T, mass)
    if s is not None:
        _same_step_twice(s, round(0.3 * T / dt))


@pytest.mark.parametrize("scheme", friction_schemes())
def test_a_rolled_back_step_is_the_same_step_with_friction(scheme):
    b = get_benchmark("bar2d")
    p = with_friction(b.problem(4, {}), "coulomb:0.3")
    dt, T = b.run_times(4, {})
    s = _stepper(p, scheme, dt, T, "standard")
    if s is not None:
        _same_step_twice(s, round(0.3 * T / dt))


@pytest.mark.parametrize("scheme", ["crank-nicolson", "backward-euler", "generalized-alpha"])
def test_a_rolled_back_step_is_the_same_step_with_sliding_pairs(scheme):
    """examples/block_on_block.toml with the upper block launched at 1 m/s along the lower one
    (Coulomb 0.3): rows re-paired before the step rolled back."""
    c = load_case(Path(__file__).parents[3] / "examples" / "block_on_block.toml")
    p = dataclasses.replace(c.problem, initial_regions=[RegionInitial("upper", velocity=[1.0, 0.0])])
    s = Stepper(p, scheme, (1e-3, 0.03), {"mass": c.mass})
    _same_step_twice(s, 12)
    assert s.run.ctx.rows.repaired > 0
