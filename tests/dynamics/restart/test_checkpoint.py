"""Checkpoints and resume (issue 33): a run to T/2 resumed to T equals the run to T, bit for bit
on the same machine and backend (every scheme x standard, seed, moment-preserving; with
Coulomb friction; contact pairs), a hand-driven Stepper, and hostile checkpoints refused."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from signorini.dynamics.model.problem import with_friction
from signorini.dynamics.schemes import SCHEMES, friction_schemes
from signorini.dynamics.stepping.run_options import CheckpointPolicy
from signorini.dynamics.stepping.simulate import Stepper, simulate
from signorini.errors import InputError
from signorini.studies.benchmarks import get_benchmark

SERIES = ("t", "gap", "lam", "kinetic_energy", "elastic_energy", "load_potential", "predicted_increment",
          "external_work", "contact_work", "numerical_dissipation", "impulse", "momentum", "active", "iterations",
          "untagged_penetration")  # fmt: skip


def _bar2d(friction: str | None = None):
    b = get_benchmark("bar2d")
    p = b.problem(4, {})
    dt, T = b.run_times(4, {})
    return (with_friction(p, friction) if friction else p), dt, T


def assert_same_run(a, b) -> None:
    """Every series and counter of two histories equal, bit for bit."""
    for k in SERIES:
        x, y = getattr(a, k), getattr(b, k)
        assert np.array_equal(x, y, equal_nan=True), k
    if a.lam_t is not None:
        assert np.array_equal(a.lam_t, b.lam_t) and np.array_equal(a.slip, b.slip)
    assert a.counters == b.counters
    assert a.status == b.status == "finished"


def _resumed(tmp_path: Path, problem, scheme: str, dt: float, T: float, mass: str, **kw):
    ck = tmp_path / f"{scheme}-{mass}.h5"
    half = (round(T / dt) // 2) * dt
    first = simulate(problem, scheme, dt, half, mass=mass, checkpoint=ck, **kw)
    assert first.meta["checkpoints"]["level"] == round(half / dt)
    return simulate(problem, scheme, dt, T, mass=mass, resume=ck, **kw)


def _full_and_resumed(tmp_path: Path, problem, scheme: str, dt: float, T: float, mass: str):
    """(the run to T, the run to T/2 resumed to T), or None when the scheme refuses the mass
    (then the checkpointed run refuses it too)."""
    try:
        full = simulate(problem, scheme, dt, T, mass=mass)
    except InputError:
        with pytest.raises(InputError):
            _resumed(tmp_path, problem, scheme, dt, T, mass)
        return None
    return full, _resumed(tmp_path, problem, scheme, dt, T, mass)


@pytest.mark.parametrize("mass", ["standard", "seed", "moment-preserving"])
@pytest.mark.parametrize("scheme", SCHEMES.names(aliases=False))
def test_resume_equals_uninterrupted_run(tmp_path, scheme, mass):
    """bar2d: T/2 + resume to T = T, every series and counter bit for bit (or the scheme refuses
    the mass in both)."""
    p, dt, T = _bar2d()
    runs = _full_and_resumed(tmp_path, p, scheme, dt, T, mass)
    if runs is None:
        return
    full, r = runs
    assert_same_run(full, r)
    assert r.meta["resumed_from"]["level"] == round(T / dt) // 2


@pytest.mark.parametrize("scheme", ["crank-nicolson", "backward-euler", "generalized-alpha", "moreau-jean"])
def test_resume_with_coulomb_friction(tmp_path, scheme):
    assert scheme in friction_schemes()
    p, dt, T = _bar2d("coulomb:0.3")
    mass = "standard" if scheme == "moreau-jean" else "moment-preserving"
    full = simulate(p, scheme, dt, T, mass=mass)
    assert_same_run(full, _resumed(tmp_path, p, scheme, dt, T, mass))


def test_resume_contact_pairs_with_small_sliding(tmp_path):
    """Two blocks with Coulomb friction on a pair, re-paired by small sliding before and after
    the checkpoint: the resumed run equals the uninterrupted one."""
    from signorini.io.config import load_case

    c = load_case(Path(__file__).parents[3] / "examples" / "block_on_block.toml")
    T = 60 * c.dt
    full = simulate(c.problem, c.scheme, c.dt, T, mass=c.mass)
    r = _resumed(tmp_path, c.problem, c.scheme, c.dt, T, c.mass)
    assert full.counters["pair_rows_repaired"] > 0
    for k in SERIES:
        assert np.array_equal(getattr(full, k), getattr(r, k), equal_nan=True), k
    assert r.counters["pair_rows_repaired"] == full.counters["pair_rows_repaired"]


def _block_on_block(velocity: list[float], frictional: bool):
    """examples/block_on_block.toml with the upper block launched at ``velocity`` (1 m/s along
    the lower block: the pair re-pairs every few steps; or down onto it: an impact), its
    Coulomb friction kept or removed (a scheme without friction)."""
    import dataclasses

    from signorini.dynamics.model.problem import RegionInitial
    from signorini.io.config import load_case

    c = load_case(Path(__file__).parents[3] / "examples" / "block_on_block.toml")
    p = dataclasses.replace(c.problem, initial_regions=[RegionInitial("upper", velocity=velocity)])
    if not frictional:
        p = dataclasses.replace(p, pairs=[dataclasses.replace(q, friction=None) for q in p.pairs])
    return p


#: (the upper block's velocity, dt, the checkpoint's level, the last level): sliding across
#: the lower block's facets at 1 m/s, and an impact checkpointed while the blocks touch
PAIR_MOTIONS = {"sliding": ([1.0, 0.0], 1e-3, 12, 24), "impact": ([0.0, -0.5], 2e-4, 10, 24)}


@pytest.mark.parametrize("motion", sorted(PAIR_MOTIONS))
@pytest.mark.parametrize("mass", ["standard", "moment-preserving"])
@pytest.mark.parametrize("scheme", SCHEMES.names(aliases=False))
def test_resume_with_sliding_pairs_and_inside_an_impact_is_bit_for_bit(tmp_path, scheme, mass, motion):
    """Issue 38: re-pairings and Delassus columns added while the pair slides or the blocks
    touch are replayed on resume in the order the uninterrupted run made them (the resumed run
    used to differ by 1e-11..1e-9 from the first step after the checkpoint and to count 504
    columns against 462): every series, lam_t and counter equal, for every scheme and mass
    (with Coulomb friction where the scheme carries it), or a refusal in both."""
    velocity, dt, n1, n2 = PAIR_MOTIONS[motion]
    p = _block_on_block(velocity, scheme in friction_schemes())
    try:
        full = simulate(p, scheme, dt, n2 * dt, mass=mass)
    except InputError:
        with pytest.raises(InputError):
            simulate(p, scheme, dt, n1 * dt, mass=mass, checkpoint=tmp_path / "c.h5")
        return
    first = simulate(p, scheme, dt, n1 * dt, mass=mass, checkpoint=tmp_path / "c.h5")
    assert first.meta["checkpoints"]["level"] == n1
    r = simulate(p, scheme, dt, n2 * dt, mass=mass, resume=tmp_path / "c.h5")
    assert_same_run(full, r)
    if motion == "sliding":
        assert first.counters["pair_rows_repaired"] > 0 < full.counters["pair_rows_repaired"] - first.counters[
            "pair_rows_repaired"]  # fmt: skip
    else:
        assert (full.lam[1 : n1 + 1] < 0).any() and (full.lam[n1 + 1 :] < 0).any()  # the checkpoint: inside it


def test_interrupted_run_resumes_from_its_last_level(tmp_path):
    """A KeyboardInterrupt at level 17 (Ctrl-C inside a step): the run checkpoints level 16
    and the resume equals the uninterrupted run."""
    from signorini.dynamics.observe.observers import Observer

    class CtrlC(Observer):
        def record(self, run, n, state):
            if n == 17:
                raise KeyboardInterrupt

    p, dt, T = _bar2d()
    ck = tmp_path / "c.h5"
    cut = simulate(p, "cn", dt, T, checkpoint=ck, observers=[CtrlC()])
    assert cut.status == "interrupted" and cut.meta["checkpoints"]["level"] == 16
    assert_same_run(simulate(p, "cn", dt, T), simulate(p, "cn", dt, T, resume=ck))


def test_stepper_by_hand(tmp_path):
    """The public loop: status, t and n follow the steps; a stepper stopped early finishes as
    interrupted; step() after the end is an error; finish() is idempotent."""
    p, dt, T = _bar2d()
    s = Stepper(p, "cn", (dt, T))
    assert (s.status, s.n, s.t, s.dt) == ("running", 0, 0.0, dt)
    while s.status == "running" and s.n < 5:
        s.step()
    assert s.n == 5 and s.t == 5 * dt and s.counters["steps"] == 5
    H = s.finish()
    assert H.status == "interrupted" and "after step 5" in H.message and len(H.t) == 6
    assert s.finish() is H
    with pytest.raises(RuntimeError):
        s.step()
    s2 = Stepper(p, "cn", (dt, T))
    while s2.step() == "running":
        pass
    assert_same_run(s2.finish(), simulate(p, "cn", dt, T))


def test_checkpoint_of_another_problem_is_refused(tmp_path):
    p, dt, T = _bar2d()
    ck = tmp_path / "c.h5"
    simulate(p, "cn", dt, T / 2, checkpoint=ck)
    with pytest.raises(InputError, match="scheme differs"):
        simulate(p, "be", dt, T, resume=ck)
    b = get_benchmark("bar2d")
    with pytest.raises(InputError, match="mesh|number of dofs"):
        simulate(b.problem(2, {}), "cn", dt, T, resume=ck)
    with pytest.raises(InputError, match="mass differs"):
        simulate(p, "cn", dt, T, mass="standard", resume=ck)


def _cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "signorini", *args], cwd=cwd, capture_output=True, text=True)


def test_cli_resume_equals_the_uninterrupted_run(tmp_path):
    """`signorini resume` of a run to T = 0.5 gives the files of the run to T = 1: history.csv,
    contact.npz and every XDMF snapshot."""
    import meshio

    assert (
        _cli("run", "bar2d", "--T", "0.5", "--snapshot-every", "10", "--quiet", "--out", "a", cwd=tmp_path).returncode
        == 0
    )
    r = _cli("resume", "a", "--T", "1", "--quiet", "--out", "b", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (
        _cli("run", "bar2d", "--T", "1", "--snapshot-every", "10", "--quiet", "--out", "c", cwd=tmp_path).returncode
        == 0
    )
    assert (tmp_path / "b/history.csv").read_text() == (tmp_path / "c/history.csv").read_text()
    x, y = np.load(tmp_path / "b/contact.npz"), np.load(tmp_path / "c/contact.npz")
    assert all(np.array_equal(x[k], y[k], equal_nan=True) for k in y.files)
    summary = json.loads((tmp_path / "b/summary.json").read_text())
    assert summary["resumed_from"]["level"] == 40 and summary["status"] == "finished"

    def fields(d):
        with meshio.xdmf.TimeSeriesReader(str(tmp_path / d / "fields.xdmf")) as reader:
            reader.read_points_cells()
            return [reader.read_data(k) for k in range(reader.num_steps)]

    fb, fc = fields("b"), fields("c")
    assert [f[0] for f in fb] == [f[0] for f in fc] and len(fc) == 9
    assert all(np.array_equal(a[1][k], b[1][k]) for a, b in zip(fb, fc, strict=True) for k in b[1])


def _hostile(path: Path, how: str) -> None:
    if how == "truncated":
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 3])
    elif how == "nan":
        with h5py.File(path, "a") as f:
            a = f["state/U"][()]
            a[3] = np.nan
            f["state/U"][...] = a
    elif how == "shape":
        with h5py.File(path, "a") as f:
            a = f["state/V"][()]
            del f["state/V"]
            f["state/V"] = a[:-1]
    elif how == "newer":
        with h5py.File(path, "a") as f:
            f.attrs["version"] = json.dumps(99)
    elif how == "not-hdf5":
        path.write_text("[mesh]\n")


@pytest.mark.parametrize("how", ["truncated", "nan", "shape", "newer", "not-hdf5"])
def test_hostile_checkpoints_are_refused(tmp_path, how):
    assert _cli("run", "bar2d", "--T", "0.5", "--quiet", "--out", "a", cwd=tmp_path).returncode == 0
    _hostile(tmp_path / "a/checkpoint.h5", how)
    r = _cli("resume", "a", "--T", "1", "--out", "b", cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "checkpoint" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "b").exists() and not list(tmp_path.glob(".signorini-new.*"))


def test_changed_case_file_is_refused(tmp_path):
    case = tmp_path / "case.toml"
    case.write_text((Path(__file__).parents[3] / "examples" / "bar2d.toml").read_text().replace("T = 1.0", "T = 0.1"))
    assert _cli("run", str(case), "--quiet", "--out", "a", cwd=tmp_path).returncode == 0
    case.write_text(case.read_text().replace("mu = 0.5", "mu = 0.4"))
    r = _cli("resume", "a", "--T", "0.2", "--out", "b", cwd=tmp_path)
    assert r.returncode == 2 and "changed since the checkpoint" in r.stderr
    assert not (tmp_path / "b").exists()


def _resume_equals_a_run_to(tmp_path, result: str, args: list[str], level: int, dt: float) -> None:
    """``signorini resume result`` to 80 levels after ``level`` equals a run of ``args`` to there
    (history.csv byte for byte); nothing temporary left."""
    T = repr((level + 80) * dt)
    assert _cli("resume", result, "--T", T, "--quiet", "--out", "r", cwd=tmp_path).returncode == 0
    assert _cli(*args, "--T", T, "--out", "u", cwd=tmp_path).returncode == 0
    assert (tmp_path / "r/history.csv").read_text() == (tmp_path / "u/history.csv").read_text()
    assert not list(tmp_path.glob(".signorini-*"))


def test_killed_run_is_resumable(tmp_path):
    """SIGKILL at a random moment after the first periodic checkpoint of a long run: --out holds
    that checkpoint (status killed, resumable) and its resume equals the uninterrupted run."""
    import os
    import random
    import signal
    import time

    args = ["run", "bar2d", "--n", "8", "--quiet"]
    p = subprocess.Popen([sys.executable, "-m", "signorini", *args, "--T", "600", "--checkpoint-every", "40", "--out",
                          "k"], cwd=tmp_path, stderr=subprocess.PIPE)  # fmt: skip
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob(".signorini-new.*/checkpoint.h5")) and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(random.Random(7).uniform(0.0, 0.5))  # 96,000 steps: far from the end whatever the machine
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    deadline = time.monotonic() + 20
    while not (tmp_path / "k/summary.json").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    summary = json.loads((tmp_path / "k/summary.json").read_text())
    level = summary["checkpoint"]["level"]
    assert summary["status"] == "killed" and summary["resumable"] and level % 40 == 0 and level > 0
    assert sorted(x.name for x in (tmp_path / "k").iterdir()) == [".signorini", "checkpoint.h5", "checkpoint.series",
                                                                   "summary.json"]  # fmt: skip
    _resume_equals_a_run_to(tmp_path, "k", args, level, 0.1 / 8 / 2)


# ----------------------------------------------------------------------------- a time step that changes
HALVED = [{"until": 0.3, "dt": 0.0125}, {"until": 0.6, "dt": 0.00625}, {"until": 1.0, "dt": 0.0125}]


def _identity_error(H) -> float:
    """max_n |E_n - E_{n-1} - predicted_n| / E_0 over every level."""
    E = H.kinetic_energy + H.elastic_energy + H.load_potential
    return float(np.nanmax(np.abs(np.diff(E) - H.predicted_increment[1:])) / abs(E[0]))


@pytest.mark.parametrize("scheme", [s for s in SCHEMES.names(aliases=False) if s != "paoli-schatzman"])
def test_schedule_keeps_the_energy_identity_where_the_step_changes(scheme):
    """bar2d, the step halved over the impact (0.3 .. 0.6) and back: the levels are those of
    the schedule, one factorization per step size, and the scheme's energy identity holds to
    round-off at every level, the two where the step changes included."""
    p, _, T = _bar2d()
    H = simulate(p, scheme, HALVED, T, mass="standard")
    assert H.status == "finished" and len(H.t) == 24 + 48 + 32 + 1
    steps = np.diff(H.t)
    assert np.allclose(steps[:24], 0.0125, rtol=1e-12, atol=0) and np.allclose(
        steps[24:72], 0.00625, rtol=1e-12, atol=0
    )
    assert H.t[-1] == pytest.approx(1.0, rel=1e-15, abs=0) and H.meta["dt_schedule"][1] == pytest.approx(
        {"until": 0.6, "dt": 0.00625}, rel=1e-12, abs=0
    )
    if not np.all(np.isnan(H.predicted_increment[1:])):
        assert _identity_error(H) < 1e-11
    assert H.counters["factorizations"] >= 3


def test_schedule_is_refused_by_a_two_step_scheme():
    p, _, T = _bar2d()
    with pytest.raises(InputError, match="paoli-schatzman cannot change its time step"):
        simulate(p, "ps", HALVED, T, mass="standard")


def test_resume_with_another_step(tmp_path):
    """A run to 0.5 resumed with half the step: the first levels are the checkpoint's, the
    others on the new step, and the energy identity holds across the change."""
    p, dt, T = _bar2d()
    ck = tmp_path / "c.h5"
    first = simulate(p, "cn", dt, 0.5, checkpoint=ck)
    r = simulate(p, "cn", dt / 2, T, resume=ck)
    assert np.array_equal(r.t[:41], first.t) and np.allclose(np.diff(r.t[40:]), dt / 2, rtol=1e-12, atol=0)
    assert np.array_equal(r.lam[:41], first.lam) and _identity_error(r) < 1e-12
    with pytest.raises(InputError, match="not an integer multiple"):
        simulate(p, "cn", 0.03, T, resume=ck)


@pytest.mark.parametrize(
    "schedule, match",
    [
        ([{"until": 0.6, "dt": 0.0125}, {"until": 0.3, "dt": 0.01}], "must increase"),
        ([{"until": 0.31, "dt": 0.0125}], "not an integer multiple"),
        ([{"until": 1.0}], "exactly the keys until and dt"),
        ([], "empty schedule"),
        # issue 52: a piece's dt beyond doubles' range was an internal OverflowError (dt^2) or a huge step count
        ([{"until": 0.2, "dt": 0.025}, {"until": 1e200, "dt": 1e199}], r"dt\[1\]\.dt' must be between"),
        ([{"until": 0.2, "dt": 0.025}, {"until": 0.4, "dt": 1e-300}], r"dt\[1\]\.dt' must be between"),
    ],
)
def test_bad_schedules_are_refused(schedule, match):
    p, _, T = _bar2d()
    with pytest.raises(InputError, match=match):
        simulate(p, "cn", schedule, None)


def test_case_file_schedule(tmp_path):
    """[time] dt as a schedule in a case file: T defaults to the last until; the CLI runs it."""
    case = tmp_path / "case.toml"
    text = (Path(__file__).parents[3] / "examples" / "bar2d.toml").read_text()
    case.write_text(
        text.replace("dt = 0.0125\nT = 1.0", "dt = [{ until = 0.3, dt = 0.0125 }, { until = 0.5, dt = 0.00625 }]")
    )
    r = _cli("run", str(case), "--quiet", "--out", "a", "--dt-control", "fixed", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    s = json.loads((tmp_path / "a/summary.json").read_text())
    assert s["T"] == 0.5 and s["steps"] == 24 + 32 and len(s["dt_schedule"]) == 2
    case.write_text(text.replace("dt = 0.0125\nT = 1.0", "dt = [{ until = 0.3, dt = 0.007 }]"))
    r = _cli("run", str(case), "--quiet", "--out", "b", cwd=tmp_path)
    assert r.returncode == 2 and "not an integer multiple" in r.stderr and not (tmp_path / "b").exists()


def test_a_checkpoint_that_cannot_be_written_does_not_end_the_run(tmp_path, monkeypatch):
    """A full disk at the second periodic checkpoint: the run goes on to T (finished), the
    summary counts the failure and warns, the first checkpoint is intact and resumes."""
    import errno

    import signorini.dynamics.restart.checkpoint as ckpt

    real, calls = ckpt.write, []

    def write(path, contents):
        calls.append(contents["attrs"]["level"])
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(path, contents)

    monkeypatch.setattr(ckpt, "write", write)
    p, dt, T = _bar2d()
    H = simulate(p, "cn", dt, T, checkpoint=tmp_path / "c.h5", checkpoint_every=20)
    assert H.status == "finished" and len(H.t) == 81
    assert H.meta["checkpoints"]["failed"] == 1 and "No space left" in H.meta["checkpoints"]["error"]
    assert any("could not be written" in w for w in H.meta["warnings"])
    assert calls == [20, 40, 60, 80]
    monkeypatch.setattr(ckpt, "write", real)  # the last one (level 80) was written: on to 1.5
    assert_same_run(simulate(p, "cn", dt, 1.5), simulate(p, "cn", dt, 1.5, resume=tmp_path / "c.h5"))


def test_terminal_event_then_resume_with_sliding_pairs(tmp_path):
    """A terminal event at a level after which small sliding re-pairs (block_on_block, level 1):
    the checkpoint holds the pairing of after that level and the resume equals the run."""
    from signorini.dynamics.observe.events import Event
    from signorini.io.config import load_case

    c = load_case(Path(__file__).parents[3] / "examples" / "block_on_block.toml")
    T = 40 * c.dt
    full = simulate(c.problem, c.scheme, c.dt, T, mass=c.mass)
    stop = Event("stop", lambda t, s: 1.0 if t < 0.5 * c.dt else -1.0, terminal=True, direction=-1)
    first = simulate(c.problem, c.scheme, c.dt, T, mass=c.mass, events=[stop], checkpoint=tmp_path / "c.h5")
    assert first.status == "finished" and len(first.t) == 2 and first.counters["pair_rows_repaired"] > 0
    r = simulate(c.problem, c.scheme, c.dt, T, mass=c.mass, resume=tmp_path / "c.h5")
    for k in SERIES:
        assert np.array_equal(getattr(full, k), getattr(r, k), equal_nan=True), k


def test_resume_in_a_later_segment_of_a_schedule(tmp_path):
    """Checkpointed in the second segment of a schedule (other step than the first), with
    Coulomb friction: the resume solves with that segment's factorization and warm starts, bit
    for bit, counters included."""
    p, _, _ = _bar2d("coulomb:0.3")
    schedule = [{"until": 0.4, "dt": 0.0125}, {"until": 0.7, "dt": 0.00625}, {"until": 1.2, "dt": 0.025}]
    full = simulate(p, "cn", schedule, None)
    simulate(p, "cn", schedule, 0.5, checkpoint=tmp_path / "c.h5")
    assert_same_run(full, simulate(p, "cn", schedule, None, resume=tmp_path / "c.h5"))


def test_friction_is_part_of_the_identity(tmp_path):
    p, dt, T = _bar2d("coulomb:0.3")
    simulate(p, "cn", dt, T / 2, checkpoint=tmp_path / "c.h5")
    for other in (_bar2d("coulomb:0.5")[0], _bar2d()[0]):
        with pytest.raises(InputError, match="the friction law or its coefficients differs"):
            simulate(other, "cn", dt, T, resume=tmp_path / "c.h5")


@pytest.mark.parametrize(
    "attr, value",
    [
        ("level", "x"),
        ("t", float("nan")),
        ("counters", []),
        ("solvers/count", "2"),
        ("state/flags", [1]),
        ("segment", [0, -1, 0]),
    ],
)
def test_forged_attributes_are_refused_in_one_line(tmp_path, attr, value):
    """An attribute of the wrong type with the checksum recomputed (a forged file): exit 2 in one
    line, not an internal error."""
    import signorini.dynamics.restart.checkpoint as ckpt

    assert _cli("run", "bar2d", "--T", "0.5", "--quiet", "--out", "a", cwd=tmp_path).returncode == 0
    path = tmp_path / "a/checkpoint.h5"
    contents = ckpt.read(path)
    contents["attrs"][attr] = value
    ckpt.write(path, {"arrays": contents["arrays"], "attrs": contents["attrs"]})
    r = _cli("resume", "a", "--T", "1", "--out", "b", cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (tmp_path / "b").exists()


def test_a_checkpoint_of_the_former_layout_resumes_alike(tmp_path):
    """A checkpoint written before the parts' walk named the state's flags ``state_flags`` and the solvers' count
    ``n_solvers`` (top-level attributes): rewritten so, it resumes to the same history as the file as written."""
    import signorini.dynamics.restart.checkpoint as ckpt

    assert _cli("run", "bar2d", "--T", "0.5", "--quiet", "--out", "a", cwd=tmp_path).returncode == 0
    assert _cli("resume", "a", "--T", "1", "--quiet", "--out", "now", cwd=tmp_path).returncode == 0
    path = tmp_path / "a/checkpoint.h5"
    contents = ckpt.read(path)
    attrs = contents["attrs"]
    assert isinstance(attrs["solvers/count"], int) and attrs["solvers/count"] > 0 and "n_solvers" not in attrs
    attrs["state_flags"], attrs["n_solvers"] = attrs.pop("state/flags"), attrs.pop("solvers/count")
    ckpt.write(path, {"arrays": contents["arrays"], "attrs": attrs})
    r = _cli("resume", "a", "--T", "1", "--quiet", "--out", "former", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "now/history.csv").read_text() == (tmp_path / "former/history.csv").read_text()


#: the default suite runs these schemes on the gmsh part; the others are in the slow suite
QUICK_ON_THE_PART = ("crank-nicolson", "backward-euler", "paoli-schatzman", "moreau-jean")


@pytest.mark.parametrize("friction", [None, "coulomb:0.3"])
@pytest.mark.parametrize("mass", ["standard", "seed", "moment-preserving"])
@pytest.mark.parametrize(
    "scheme",
    [pytest.param(s, marks=() if s in QUICK_ON_THE_PART else pytest.mark.slow) for s in SCHEMES.names(aliases=False)],
)
def test_resume_on_a_gmsh_part_with_its_whole_skin_in_contact(tmp_path, scheme, mass, friction):
    """examples/cylinder_drop.toml (a committed gmsh cylinder, its whole skin tagged for contact
    with a tilted plane), 110 levels (first contact at level 50, the checkpoint at 55 in
    contact): T/2 + resume = T, bit for bit, or a refusal (scheme x mass, friction) in both."""
    from signorini.io.config import load_case

    c = load_case(Path(__file__).parents[3] / "examples" / "cylinder_drop.toml")
    p = with_friction(c.problem, friction) if friction else c.problem
    dt, T = c.dt, 110 * c.dt
    runs = _full_and_resumed(tmp_path, p, scheme, dt, T, mass)
    if runs is None:
        return
    full, r = runs
    assert full.active.max() > 0  # the impact is in the levels compared
    assert_same_run(full, r)


def test_sigint_at_a_random_moment_resumes_from_the_last_level(tmp_path):
    """SIGINT to the command line at a random moment (seeded) of a long run: exit 130, the
    result holds the checkpoint of its last level, and its resume equals the uninterrupted run."""
    import random
    import signal
    import time

    args = ["run", "bar2d", "--n", "8", "--quiet"]
    p = subprocess.Popen([sys.executable, "-m", "signorini", *args, "--T", "600", "--snapshot-every", "1000000",
                          "--out", "i"], cwd=tmp_path, stderr=subprocess.PIPE)  # fmt: skip
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob(".signorini-new.*")) and time.monotonic() < deadline:  # the loop has started
        time.sleep(0.02)
    time.sleep(random.Random(11).uniform(1.5, 3.0))  # the field writer's child starts first (~0.5 s)
    p.send_signal(signal.SIGINT)
    assert p.wait(timeout=120) == 130
    s = json.loads((tmp_path / "i/summary.json").read_text())
    assert s["status"] == "interrupted" and s["checkpoints"]["level"] == s["steps"] > 0
    _resume_equals_a_run_to(tmp_path, "i", args, s["steps"], s["dt"])


def test_a_run_stopped_at_level_0_is_resumable(tmp_path):
    """Ctrl-C between the set-up and the first step (status interrupted, no step): its result
    used to have no checkpoint, which `resume` then refused; now level 0 is checkpointed and the
    resumed run equals the uninterrupted one."""
    p, dt, T = _bar2d()
    s = Stepper(p, "cn", (dt, T), {"checkpoint": CheckpointPolicy(tmp_path / "c.h5")})
    s.interrupt("SIGINT after step 0 of 80")
    H = s.finish()
    assert H.status == "interrupted" and H.steps == 0 and H.meta["checkpoints"]["level"] == 0
    assert_same_run(simulate(p, "cn", dt, T, resume=tmp_path / "c.h5"), simulate(p, "cn", dt, T))
