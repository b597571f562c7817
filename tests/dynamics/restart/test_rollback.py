"""Rollback (issue 39, item 2's verification; issue 53, item 2): a step taken, the parts it changed put back
(what the energy control does on a rejected step: ``Stepper.step_parts``), and taken again gives the same bits,
for every scheme, with Coulomb friction, with contact pairs re-pairing as they slide, and with finite strain
whose rows move with every Newton iterate (pairs in the current configuration, with friction)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from signorini.contact.obstacles import SphereObstacle
from signorini.dynamics.model.problem import Problem, RegionInitial, with_friction
from signorini.dynamics.schemes import SCHEMES, friction_schemes
from signorini.dynamics.stepping.simulate import Stepper
from signorini.errors import InputError
from signorini.fem.material import NeoHookean
from signorini.fem.mesh import rectangle
from signorini.io.config import load_case
from signorini.studies.benchmarks import get_benchmark


def _same_step_twice(stepper: Stepper, before: int) -> None:
    """Step ``before`` levels (a contact building up), then take the next step, roll it back and
    take it again: U, V, A, lambda, lambda_t and the iteration count equal bit for bit."""
    for _ in range(before):
        assert stepper.step() == "running"
    n = stepper.n + 1
    marked = stepper.step_parts.mark()
    first, why = stepper.trial(n)
    assert first is not None, why
    stepper.step_parts.rollback(marked)
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


def _columns_differ(a, b) -> list[str]:
    ca, cb = a.columns(), b.columns()
    return [k for k in ca if not np.array_equal(ca[k], cb[k], equal_nan=True)]


@pytest.mark.parametrize("scheme", ["crank-nicolson", "energy-momentum"])
def test_a_rejected_finite_strain_step_with_pairs_and_friction_leaves_nothing_behind(scheme):
    """rings2d (two Neo-Hookean rings, a pair in the current configuration) with Coulomb 0.3 on the pair, under
    the energy control, every step rejected once (the control's test hook) and tried again: every column of the
    history equals the run without the extra rejections bit for bit.  Before the Delassus columns were part of
    the rollback, the moved rows' columns kept the rejected trial's round-off (1e-13 of the contact force from the
    first contact on).  The run itself: the rings touch, friction dissipates, the control rejects steps of its
    own (2 measured)."""
    b = get_benchmark("rings2d")
    p = b.problem(1, {})
    p.pairs = [dataclasses.replace(p.pairs[0], friction="coulomb:0.3")]
    p.__post_init__()
    dt, _ = b.run_times(1, {})

    def run(force: bool):
        s = Stepper(p, scheme, (dt, 0.06), {"control": "energy"})
        s.adaptive.control.force_reject_once = force
        while s.status == "running":
            s.step()
        return s.finish()

    a, again = run(False), run(True)
    assert a.status == "finished", a.message
    assert a.lambda_sum.min() < 0 and -a.friction_work[-1] > 0 and a.meta["time_control"]["steps_rejected"] > 0
    assert again.meta["time_control"]["steps_rejected"] == a.meta["time_control"]["steps_rejected"]
    assert a.t.size == again.t.size and _columns_differ(a, again) == []


def test_a_finite_strain_step_against_a_ball_rolled_back_is_the_same_step():
    """A Neo-Hookean block thrown spinning onto a rigid ball (the rows the ball's normals at the current
    positions, moved by every Newton iterate), a step in contact taken, rolled back and taken again: the
    same bits."""
    mesh, c = rectangle(8, 4, 0.04, 0.02), np.array([0.02, 0.01])
    p = Problem(mesh, NeoHookean.from_young(5e6, 0.45, 1100.0), ["xmin", "xmax", "ymin", "ymax"],
                SphereObstacle([0.025, -0.1], 0.096),
                v0=lambda x: np.column_stack([-60.0 * (x[:, 1] - c[1]), 60.0 * (x[:, 0] - c[0]) - 1.0]))  # fmt: skip
    s = Stepper(p, "crank-nicolson", (1e-4, 0.01), {"control": "energy"})
    for _ in range(100):  # to the first level with a contact force
        assert s.step() == "running"
        if np.any(s.state.lam):
            break
    assert np.any(s.state.lam)
    _same_step_twice(s, 0)
