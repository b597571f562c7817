"""Friction from the command line and case files: options, outputs, refusals (docs/friction.md)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from cases import falling_rectangle
from signorini.io.cli import main

ROOT = Path(__file__).parents[2]


def _rows(out: Path) -> dict[str, np.ndarray]:
    with open(out / "history.csv") as fh:
        rows = list(csv.reader(fh))
    return {name: np.array([float(r[k]) for r in rows[1:]]) for k, name in enumerate(rows[0])}


def test_incline_run_writes_the_friction_outputs(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["run", "incline2d", "--n", "1", "--scheme", "be", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "closed form g (sin a - mu cos a) = 0.240192" in text and "friction coefficient 0.3 (coulomb)" in text
    cols = _rows(out)
    for name in ("contact_force_x", "contact_force_y", "stick_nodes", "slip_nodes", "friction_dissipation"):
        assert name in cols
    assert "contact_force_z" not in cols
    # the plane holds the block: the normal force averages the weight m g cos a = 0.25 cos 30
    late = cols["t"] > 1.0
    assert abs(cols["contact_force_y"][late].mean() / (0.25 * np.cos(np.radians(30))) - 1) <= 0.01
    # gross slip: the tangential force is -mu times the normal one at every level
    # measured 1.4e-17; kept at 1e-10: the friction Newton stops at its tolerance (1e-12 relative), not at round-off
    assert np.abs(cols["contact_force_x"][late] + 0.3 * cols["contact_force_y"][late]).max() <= 1e-10
    assert np.all(np.diff(cols["friction_dissipation"]) >= -1e-15)
    z = np.load(out / "contact.npz")
    assert {"lambda_n", "lambda_t", "slip", "status", "tangents"} <= set(z.files)
    assert z["lambda_t"].shape == (z["t"].size, z["lam"].shape[1], 1)
    s = json.loads((out / "summary.json").read_text())
    assert s["friction"] == {"law": "coulomb", "coefficient": 0.3}
    assert s["cone_residual_max"] <= 1e-12  # the Newton's tolerance (measured 4.0e-16): kept
    assert s["counters"]["friction_iterations"] > 0 and s["counters"]["friction_fallbacks"] == 0
    assert abs(s["incline"]["relative_deviation"]) <= 1e-9  # measured 7.0e-12


def test_frictionless_runs_have_the_new_columns(tmp_path):
    out = tmp_path / "r"
    assert main(["run", "bar2d", "--n", "1", "--T", "0.5", "--out", str(out), "--quiet"]) == 0
    cols = _rows(out)
    assert np.all(cols["stick_nodes"] == 0) and np.all(cols["friction_dissipation"] == 0)
    assert np.array_equal(cols["slip_nodes"], cols["active_contacts"])
    s = json.loads((out / "summary.json").read_text())
    assert s["friction"] == {"law": "frictionless"}
    assert np.allclose(-cols["contact_force_y"], cols["lambda_sum"], rtol=1e-14, atol=0.0)  # nu = -e_y


def test_example_case_with_friction(tmp_path):
    out = tmp_path / "r"
    assert main(["run", str(ROOT / "examples" / "block_on_slope.toml"), "--out", str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["friction"] == {"law": "coulomb", "coefficient": 0.3}
    assert s["status"] == "finished" and s["energy_identity_residual"] <= 1e-11


def test_friction_option_overrides_the_case(tmp_path):
    out = tmp_path / "r"
    case = str(ROOT / "examples" / "block_on_slope.toml")
    assert main(["run", case, "--friction", "tresca:100", "--T", "-1", "--out", str(out), "--quiet"]) == 2
    assert not out.exists()  # a bad --T: refused before anything is written
    assert main(["run", case, "--friction", "tresca:100", "--out", str(out), "--quiet"]) == 0
    assert json.loads((out / "summary.json").read_text())["friction"] == {"law": "tresca", "threshold": 100.0}


def test_friction_option_replaces_a_pairs_own_law(tmp_path):
    out = tmp_path / "r"
    case = str(ROOT / "examples" / "block_on_block.toml")  # its pair: coulomb 0.3
    argv = ["run", case, "--friction", "frictionless", "--scheme", "cn", "--T", "0.002", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["friction"] == {"law": "frictionless"}
    # the summary says what the command line changed (a new user found only --T recorded)
    assert s["overrides"]["friction"] == {"case_file": "coulomb:0.3", "command_line": "frictionless"}
    assert s["overrides"]["scheme"] == {"case_file": "backward-euler", "command_line": "crank-nicolson"}
    cols = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    assert np.all(cols["friction_dissipation"] == 0) and np.all(cols["stick_nodes"] == 0)


@pytest.mark.parametrize(
    "friction, message",
    [
        ('{ law = "coulomb", coefficient = -1 }', "contact.friction.coefficient"),
        ('{ law = "coulomb" }', "needs 'coefficient'"),
        ('{ law = "tresca", coefficient = 0.3 }', "unknown option 'coefficient'"),
        ('{ law = "viscous", coefficient = 0.3 }', "unknown contact law 'viscous'"),
        ('"coulomb"', "needs a value"),
        ("0.3", "must be a table"),
        ('{ law = "coulomb", coefficient = "0.3" }', "contact.friction.coefficient must be a number, got '0.3'"),
        ('{ law = "tresca", threshold = true }', "contact.friction.threshold must be a number, got True"),
    ],
)
def test_bad_friction_in_a_case_file(tmp_path, capsys, friction, message):
    case = tmp_path / "case.toml"
    case.write_text(falling_rectangle((4, 2), (1.0, 0.5), 100.0, contact_extra=f"friction = {friction}\n", dt=0.01))
    out = tmp_path / "out"
    assert main(["run", str(case), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["run", "bar1d", "--friction", "coulomb:0.3"], "2D or 3D"),
        (["run", "bar2d", "--friction", "coulomb:0.3", "--scheme", "ps"], "paoli-schatzman cannot carry friction"),
        (["run", "bar2d", "--friction", "coulomb:0.3", "--backend", "cg"], "not cg"),
        (["run", "bar2d", "--friction", "tresca:-1"], "threshold"),
        (["compare", "bar2d", "--schemes", "ps", "--masses", "seed", "--friction", "coulomb:0.3"],
         "paoli-schatzman cannot carry friction"),
    ],
)  # fmt: skip
def test_bad_friction_options(tmp_path, capsys, argv, message):
    out = tmp_path / "out"
    assert main([*argv, "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_compare_with_friction(tmp_path):
    out = tmp_path / "c"
    argv = ["compare", "bar2d", "--schemes", "cn,be,ps", "--masses", "moment-preserving", "--levels", "1",
            "--friction", "coulomb:0.3", "--out", str(out), "--quiet"]  # fmt: skip
    assert main(argv) == 0
    result = json.loads((out / "compare.json").read_text())
    assert result["friction"] == {"law": "coulomb", "coefficient": 0.3}
    assert "Contact law: coulomb (coefficient 0.3) in every run." in (out / "compare.md").read_text()
    status = {p["scheme"]: {r["status"] for r in p["runs"]} for p in result["pairs"]}
    assert status == {"crank-nicolson": {"finished"}, "backward-euler": {"finished"}, "paoli-schatzman": {"n/a"}}
    (why,) = {r["reason"] for p in result["pairs"] if p["scheme"] == "paoli-schatzman" for r in p["runs"]}
    assert "paoli-schatzman cannot carry friction" in why  # the scheme's own refusal, kept like a mass refusal


def test_a_friction_refusal_lists_the_schemes_that_also_run_finite_strain():
    from signorini.contact.friction import make_friction
    from signorini.dynamics.schemes import finite_strain_schemes, friction_schemes
    from signorini.dynamics.schemes.checks import check_friction_schemes
    from signorini.errors import InputError

    law = make_friction("coulomb:0.3")
    for finite in (False, True):
        with pytest.raises(InputError) as err:
            check_friction_schemes(law, ["crank-nicolson", "paoli-schatzman"], finite=finite)
        listed = str(err.value).split(": ")[-1].split(", ")
        expected = [s for s in friction_schemes() if not finite or s in finite_strain_schemes()]
        assert listed == expected and ("moreau-jean" in listed) is not finite


def test_a_users_scheme_is_judged_by_its_own_friction_refusal():
    """A scheme given as a class (``--scheme module:Class``, a subclass passed to ``simulate``) needs no registry
    name: a subclass of crank-nicolson named otherwise carries friction like it; one that refuses friction is
    refused by its own name and reason."""
    from signorini.dynamics.model.problem import with_friction
    from signorini.dynamics.schemes import CrankNicolson
    from signorini.dynamics.schemes.checks import check_friction_schemes
    from signorini.dynamics.stepping.simulate import simulate
    from signorini.errors import InputError
    from signorini.studies.benchmarks import get_benchmark

    class MyCN(CrankNicolson):
        name = "my-cn"

    class Frictionless(CrankNicolson):
        name = "my-frictionless-cn"
        friction_refusal = "it is a test"

    p = with_friction(get_benchmark("bar2d").problem(4), "coulomb:0.3")
    H = simulate(p, MyCN, 1e-3, 0.002)
    assert H.status == "finished" and H.lam_t is not None
    with pytest.raises(InputError, match="scheme my-frictionless-cn cannot carry friction .*: it is a test"):
        check_friction_schemes(p.friction, [Frictionless()])
