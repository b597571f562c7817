import csv
import json

import numpy as np
import pytest

from signorini.io.cli import main


def test_version_and_help(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert "signorini" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    assert "--mass" in capsys.readouterr().out


def test_run_writes_results(tmp_path):
    out = tmp_path / "r"
    rc = main(
        [
            "run",
            "bar2d",
            "--scheme",
            "backward-euler",
            "--mass",
            "standard",
            "--n",
            "2",
            "--T",
            "0.6",
            "--set",
            "velocity=1",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert rc == 0
    rows = list(csv.DictReader(open(out / "history.csv")))
    for col in (
        "t",
        "energy",
        "kinetic_energy",
        "elastic_energy",
        "lambda_sum",
        "gap_mean",
        "gap_min",
        "active_contacts",
        "newton_iterations",
    ):
        assert col in rows[0]
    s = json.loads((out / "summary.json").read_text())
    assert s["steps"] == len(rows) - 1 == 24
    assert s["dofs"] == 2 * 3 * 21 and s["contact_nodes"] == 3
    assert s["parameters"]["velocity"] == 1.0
    assert {"setup_seconds", "loop_seconds"} <= set(s)
    npz = np.load(out / "contact.npz")
    assert npz["gap"].shape == (25, 3) and npz["coordinates"].shape == (3, 2)
    assert float(rows[-1]["t"]) == pytest.approx(0.6, rel=1e-14, abs=0)  # n dt: round-off


@pytest.mark.parametrize(
    "args, message",
    [
        (["--dt", "-0.1"], "dt must be > 0"),
        (["--dt", "0"], "dt must be > 0"),
        (["--T", "0.001"], "T must be >= dt"),
        (["--scheme", "rk4"], "unknown scheme"),
        (["--mass", "heavy"], "unknown mass"),
        (["--set", "gapp=1"], "unknown parameter 'gapp'"),
        (["--set", "gap"], "NAME=VALUE"),
        (["--set", "rho=-1"], "rho"),
        (["--n", "0"], "positive integer"),
    ],
)
def test_bad_inputs_exit_2_without_output(tmp_path, capsys, args, message):
    out = tmp_path / "bad"
    base = ["run", "bar2d", "--out", str(out), "--quiet"] + ([] if "--n" in args else ["--n", "2"])
    rc = main(base + args)
    assert rc == 2
    assert message in capsys.readouterr().err
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_unknown_benchmark_and_no_overwrite(tmp_path, capsys):
    assert main(["run", "bar4d", "--out", str(tmp_path / "x")]) == 2
    assert "allowed: bar1d" in capsys.readouterr().err
    out = tmp_path / "keep"
    out.mkdir()
    (out / "precious.txt").write_text("x")
    assert main(["run", "bar1d", "--n", "4", "--out", str(out), "--quiet"]) == 2
    assert (out / "precious.txt").read_text() == "x"
    # --overwrite replaces only what signorini wrote: a directory without its marker is refused
    assert main(["run", "bar1d", "--n", "4", "--out", str(out), "--quiet", "--overwrite"]) == 2
    assert (out / "precious.txt").read_text() == "x" and not (out / "history.csv").exists()
    (out / "precious.txt").unlink()
    assert main(["run", "bar1d", "--n", "4", "--out", str(out), "--quiet"]) == 0  # empty: no flag needed
    assert main(["run", "bar1d", "--n", "4", "--out", str(out), "--quiet", "--overwrite"]) == 0  # ours now


def test_study_command_1d_and_2d(tmp_path, capsys):
    out = tmp_path / "s1"
    # without --T: one period of bar1d (T = 3, its contact on [1, 2)); the default was 1, where the contact stress
    # exists at one instant only and its column read 1.0 at every level, rate 0
    assert main(["study", "bar1d", "--n0", "20", "--levels", "3", "--out", str(out), "--quiet"]) == 0
    import csv

    rows = list(csv.DictReader(open(out / "study.csv")))
    assert [int(r["n"]) for r in rows] == [20, 40, 80]
    e = [float(r["u_L2"]) for r in rows]
    # against the exact solution (no reference run): L2 rate ~ 1, measured ratios 1.88 and 2.13;
    # the finest error measured 0.0141
    assert 1.7 < e[0] / e[1] < 2.3 and 1.7 < e[1] / e[2] < 2.3
    assert e[2] < 0.0155
    # the contact stress's L2(0, T) error against the exact -1/2 on [1, 2): measured 0.349, 0.259, 0.192 (rates 0.43,
    # 0.44: spec section 3.3's 0.3-0.5)
    stress = np.array([float(r["stress"]) for r in rows])
    rates = np.log2(stress[:-1] / stress[1:])
    assert np.all((rates > 0.3) & (rates < 0.6)) and stress[-1] < 0.21, stress
    assert json.loads((out / "study.json").read_text())["T"] == 3.0
    assert "rate 20->40" in (out / "study.md").read_text()
    out2 = tmp_path / "s2"
    assert main(["study", "bar2d", "--scheme", "be", "--levels", "2", "--out", str(out2), "--quiet"]) == 0
    rows = list(csv.DictReader(open(out2 / "study.csv")))
    assert float(rows[1]["u_H1"]) < float(rows[0]["u_H1"])
    assert main(["study", "bar2d", "--levels", "1", "--out", str(tmp_path / "s3")]) == 2
    assert main(["study", "bar2d", "--ref-level", "3", "--out", str(tmp_path / "s3")]) == 2
    assert not (tmp_path / "s3").exists()


def test_run_fields_last_level_and_summary_counters(tmp_path):
    """24 steps with --snapshot-every 7: levels 0, 7, 14, 21 and the last one, 24, are in
    fields.xdmf (read back, equal to the API run's fields); summary.json has every
    counter key and the scheme's energy definition."""
    import meshio

    from signorini.dynamics.observe.history import COUNTER_KEYS
    from signorini.dynamics.schemes import SCHEMES
    from signorini.dynamics.stepping.simulate import simulate
    from signorini.studies.benchmarks import get_benchmark

    out = tmp_path / "r"
    args = ["run", "bar2d", "--n", "2", "--T", "0.6", "--snapshot-every", "7", "--out", str(out), "--quiet"]
    assert main(args) == 0
    b = get_benchmark("bar2d")
    H = simulate(b.problem(2), "cn", b.h(2) / 2, 0.6, snapshot_every=7)
    assert H.steps == 24
    with meshio.xdmf.TimeSeriesReader(str(out / "fields.xdmf")) as r:
        r.read_points_cells()
        levels = [r.read_data(k) for k in range(r.num_steps)]
    t = np.array([lv[0] for lv in levels])
    assert np.allclose(t, np.array([0, 7, 14, 21, 24]) * H.t[1], rtol=1e-14, atol=0)
    assert np.allclose(H.snapshots["t"], t, rtol=1e-14, atol=0)
    for (_, pd, _), u, v in zip(levels, H.snapshots["u"], H.snapshots["v"], strict=True):
        # the same doubles written and read back: measured 0
        assert np.allclose(pd["displacement"][:, :2], u.reshape(-1, 2), rtol=1e-14, atol=1e-15)
        assert np.allclose(pd["velocity"][:, :2], v.reshape(-1, 2), rtol=1e-14, atol=1e-15)
    assert np.allclose(levels[-1][1]["displacement"][:, :2], H.snapshots["u"][-1].reshape(-1, 2), rtol=0, atol=0)
    s = json.loads((out / "summary.json").read_text())
    assert set(COUNTER_KEYS) <= set(s["counters"])
    assert s["counters"]["steps"] == s["steps"] == 24 and s["counters"]["factorizations"] == 1
    assert s["counters"]["linear_solves"] >= 24 and s["counters"]["fallbacks"] == 0
    assert s["counters"]["contact_iterations"] > 0  # there was contact
    assert s["energy_definition"] == SCHEMES.get("cn").obj.energy_definition == "E = 1/2 V.MV + 1/2 U.SU - U.F(t)"


def test_factorization_tip_only_for_large_3d_superlu_runs(monkeypatch):
    from signorini import linalg
    from signorini.io.cli import factorization_tip

    monkeypatch.setattr(linalg, "has_cholmod", lambda: False)
    monkeypatch.setattr(linalg, "has_pardiso", lambda: False)
    big = {"dim": 3, "dofs": 140_000, "free_dofs": 139_000, "backend": "superlu"}
    assert ".[cholmod,metis]" in factorization_tip(big)
    assert factorization_tip({**big, "dim": 2}) == ""
    assert factorization_tip({**big, "free_dofs": 20_000}) == ""
    assert factorization_tip({**big, "backend": "cg+jacobi"}) == ""
    monkeypatch.setattr(linalg, "has_cholmod", lambda: True)
    assert factorization_tip(big) == ""


def test_backend_given_twice_must_agree(tmp_path, capsys):
    out = tmp_path / "o"
    args = ["run", "bar1d", "--n", "4", "--out", str(out), "--quiet", "--backend", "superlu"]
    assert main([*args, "--solver-option", "backend=cg"]) == 2
    assert "disagree" in capsys.readouterr().err and not out.exists()
    assert main([*args, "--solver-option", "backend=superlu"]) == 0


def test_reproduce_says_when_hertz_was_skipped_and_how_to_get_it(tmp_path, capsys, monkeypatch):
    """Without gmsh the main command's own output (not only report.md) says that section 7 was
    skipped and how to install it."""
    import signorini.studies.report as report

    def fake(out, size, progress=None):
        (out / "report.md").write_text("# report\n")
        return {"hertz": None, "bar2d_histories": {}}

    monkeypatch.setattr(report, "reproduce", fake)
    assert main(["reproduce", "--quick", "--out", str(tmp_path / "r")]) == 0
    out = capsys.readouterr().out
    assert "section 7 (Hertz impact) skipped: gmsh is not installed" in out and 'pip install ".[mesh]"' in out


def test_the_cli_page_lists_every_column_of_history_csv(tmp_path):
    """docs/cli.md's list of history.csv columns is the header a 2D run writes (x, y of the
    vector columns; the page writes `name_x` (`_y`, `_z`))."""
    import re
    from pathlib import Path

    readme = (Path(__file__).parents[2] / "docs" / "cli.md").read_text()
    text = readme[readme.index("`run` writes `history.csv`") :]
    text = text[: text.index("; `energy` =")]
    listed = []
    for name in re.findall(r"[a-z_]+", " ".join(re.findall(r"`([^`]*)`", text)).replace("<tag>", "ymax")):
        listed += [name, name[:-1] + "y"] if name.endswith("_x") else [name] if not name.startswith("_") else []
    assert main(["run", "bar2d", "--n", "1", "--T", "0.1", "--quiet", "--out", str(tmp_path / "o")]) == 0
    header = (tmp_path / "o" / "history.csv").read_text().splitlines()[0].split(",")
    assert [c for c in listed if c not in ("run", "history", "csv")] == header


def test_a_batch_log_gets_plain_progress_lines_at_a_bounded_rate(tmp_path):
    """stderr not a terminal (a cluster job's log): plain lines (no carriage return), the first
    with the set-up time, then step, elapsed and ETA, a last one when done; --quiet: none.
    SIGNORINI_PROGRESS_EVERY=0 lifts the rate bound (default: after 10 s, then every 30 s)."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "SIGNORINI_PROGRESS_EVERY": "0"}
    args = [sys.executable, "-m", "signorini", "run", "bar2d", "--n", "1", "--T", "0.1", "--out"]
    r = subprocess.run([*args, str(tmp_path / "a")], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    lines = [x for x in r.stderr.splitlines() if x.startswith("bar2d:")]
    assert "\r" not in r.stderr
    assert len(lines) == 2  # 2 steps of dt = h/2 = 0.05
    assert lines[0].startswith("bar2d: set-up ") and "step 1/2 (50%)" in lines[0] and "ETA" in lines[0]
    assert "step 2/2 (100%)" in lines[-1] and lines[-1].endswith("done")
    r = subprocess.run([*args, str(tmp_path / "b"), "--quiet"], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0 and r.stderr == ""
    r = subprocess.run([*args, str(tmp_path / "c")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and not any(x.startswith("bar2d:") for x in r.stderr.splitlines())  # a short run


def test_progress_lines_are_bounded_in_rate(monkeypatch):
    """With the default bounds, 1,000 steps over 100 simulated seconds give the first line after
    10 s and then one per 30 s: 4 lines with the last."""
    import io

    from signorini.io import summary

    clock = iter(np.linspace(0.0, 100.0, 1002))
    monkeypatch.setattr(summary.time, "perf_counter", lambda: float(next(clock)))
    monkeypatch.delenv("SIGNORINI_PROGRESS_EVERY", raising=False)
    out = io.StringIO()
    p = summary.Progress(False, "job", stream=out)
    for i in range(1, 1001):
        p(i, 1000)
    lines = out.getvalue().splitlines()
    assert len(lines) == 4 and lines[-1].endswith("done") and lines[0].startswith("job: set-up 0.1 s; step 101/")
    assert "step 402/1000 (40%), 40 s elapsed, ETA 60 s" in lines[1]


def test_progress_under_the_energy_control_states_its_total_as_an_estimate(monkeypatch):
    """The control changes the step total as it goes (400, then 1,389, then 658 on a case of issue 52): the line
    says it is an estimate; a fixed step's total is exact and said plainly."""
    import io

    from signorini.io import summary

    monkeypatch.setenv("SIGNORINI_PROGRESS_EVERY", "0")
    lines = {}
    for estimated in (False, True):
        clock = iter(np.linspace(0.0, 10.0, 10))
        monkeypatch.setattr(summary.time, "perf_counter", lambda c=clock: float(next(c)))
        out = io.StringIO()
        p = summary.Progress(False, "job", stream=out, estimated=estimated)
        for i, n in ((1, 400), (2, 1389), (3, 658)):
            p(i, n)
        lines[estimated] = out.getvalue().splitlines()
    assert "step 2/1389 (0%)" in lines[False][1] and "~" not in lines[False][1]
    assert "step 2/~1389 (estimated)" in lines[True][1]
