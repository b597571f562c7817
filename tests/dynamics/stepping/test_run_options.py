"""The run's options in one declared object (issue 39): ``Stepper(problem, scheme, (dt, T), options)``
with ``options`` a RunOptions or a mapping of its names; every wrong input a one-line InputError."""

import numpy as np
import pytest

from signorini import CheckpointPolicy, RunOptions, Stepper, simulate
from signorini.errors import InputError
from signorini.studies.benchmarks import get_benchmark


@pytest.fixture(scope="module")
def bar():
    b = get_benchmark("bar2d")
    dt, T = b.run_times(2, {})
    return b.problem(2, {}), dt, T


def _run(stepper: Stepper):
    while stepper.step() == "running":
        pass
    return stepper.finish()


@pytest.mark.parametrize(
    "grid, options, message",
    [
        (0.025, None, "grid must be a pair"),
        ((0.025, 1.0, 2.0), None, "grid must be a pair"),
        ((0.025, 1.0), {"mas": "seed"}, "unknown run option.*'mas'.*allowed: mass"),
        ((0.025, 1.0), 3, "must be a RunOptions or a mapping"),
        ((0.025, 1.0), {"checkpoint": 5}, "'checkpoint' must be a CheckpointPolicy or a path"),
        ((0.025, 1.0), {"mass": "nope"}, "unknown mass 'nope'"),
        ((-1.0, 1.0), None, "dt must be > 0"),
    ],
)
def test_a_wrong_grid_or_option_is_refused_in_one_line(bar, grid, options, message):
    with pytest.raises(InputError, match=message):
        Stepper(bar[0], "cn", grid, options)


def test_a_negative_checkpoint_interval_is_refused():
    with pytest.raises(InputError, match="checkpoint_every must be a non-negative integer"):
        CheckpointPolicy("c.h5", -1)
    with pytest.raises(InputError, match="checkpoint_every needs a checkpoint path"):
        CheckpointPolicy.of(None, 3)


def test_a_mapping_a_runoptions_and_simulates_keywords_run_the_same(bar):
    p, dt, T = bar
    a = _run(Stepper(p, "cn", (dt, T / 4), {"mass": "seed", "energy": True}))
    b = _run(Stepper(p, "cn", [dt, T / 4], RunOptions(mass="seed")))
    c = simulate(p, "cn", dt, T / 4, mass="seed")
    for other in (b, c):
        assert np.array_equal(a.lam, other.lam) and np.array_equal(a.energy, other.energy)


def test_a_checkpoint_path_is_a_policy_and_resume_is_a_constructor(bar, tmp_path):
    """{"checkpoint": PATH} writes the last level; Stepper.resume continues it to a later T and
    computes what the uninterrupted run computes."""
    p, dt, T = bar
    assert RunOptions(checkpoint=tmp_path / "c.h5").checkpoint == CheckpointPolicy(tmp_path / "c.h5")
    _run(Stepper(p, "cn", (dt, T / 4), {"checkpoint": str(tmp_path / "c.h5")}))
    resumed = _run(Stepper.resume(tmp_path / "c.h5", p, "cn", (dt, T / 2)))
    whole = _run(Stepper(p, "cn", (dt, T / 2)))
    assert resumed.meta["resumed_from"]["level"] == round(T / 4 / dt)
    assert np.array_equal(resumed.lam, whole.lam) and np.array_equal(resumed.energy, whole.energy)


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: CheckpointPolicy(None, 2), "checkpoint's path must be a path"),
        (lambda: CheckpointPolicy(5), "checkpoint's path must be a path"),
        (lambda: CheckpointPolicy("c.h5", on_checkpoint=5), "on_checkpoint must be a function"),
        (lambda: CheckpointPolicy("c.h5", meta=[1]), "checkpoint_meta must be a mapping"),
        (lambda: RunOptions.of({1: 2, "x": 3}), "unknown run option"),
    ],
)
def test_a_wrong_checkpoint_policy_is_refused_when_it_is_made(make, message):
    """(An adversarial review's cases: each raised a TypeError out of finish(), or ran without writing.)"""
    with pytest.raises(InputError, match=message):
        make()


def test_the_case_file_is_part_of_the_identity_without_a_checkpoint_path(bar, tmp_path):
    """A resume that writes no checkpoint of its own still compares the case file's hash."""
    p, dt, _ = bar
    simulate(p, "cn", dt, 4 * dt, checkpoint=tmp_path / "c.h5", case_hash="AAAA")
    with pytest.raises(InputError, match="the case file .* differs"):
        simulate(p, "cn", dt, 8 * dt, resume=tmp_path / "c.h5", case_hash="BBBB")
    with pytest.raises(InputError, match="needs the path of a checkpoint"):
        Stepper.resume(None, p, "cn", (dt, 8 * dt))


def test_the_problem_and_the_step_are_checked_first(bar):
    p, dt, T = bar
    with pytest.raises(InputError, match="problem must be a signorini Problem"):
        simulate("x", "cn", dt, T, checkpoint_every=-3)
    with pytest.raises(InputError, match="dt must be > 0"):
        simulate(p, "cn", -1.0, T, checkpoint_every=3)
