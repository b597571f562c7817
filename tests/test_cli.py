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
    assert main(["study", "bar1d", "--n0", "20", "--levels", "3", "--T", "3", "--out", str(out), "--quiet"]) == 0
    import csv

    rows = list(csv.DictReader(open(out / "study.csv")))
    assert [int(r["n"]) for r in rows] == [20, 40, 80]
    e = [float(r["u_L2"]) for r in rows]
    # against the exact solution (no reference run): L2 rate ~ 1, measured ratios 1.88 and 2.13;
    # the finest error measured 0.0141
    assert 1.7 < e[0] / e[1] < 2.3 and 1.7 < e[1] / e[2] < 2.3
    assert e[2] < 0.0155
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

    from signorini.dynamics.history import COUNTER_KEYS
    from signorini.dynamics.schemes import SCHEMES
    from signorini.dynamics.simulate import simulate
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
