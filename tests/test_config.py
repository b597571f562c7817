import json
from pathlib import Path

import pytest

from signorini.io.cli import main
from signorini.io.config import load_case

EXAMPLES = sorted((Path(__file__).parents[1] / "examples").glob("*.toml"))


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_every_example_runs(tmp_path, path):
    out = tmp_path / "o"
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["steps"] > 0 and s["max_complementarity_residual"] < 1e-10
    assert (out / "case.toml").read_text() == path.read_text()


def test_case_matches_benchmark(tmp_path):
    from signorini.dynamics.simulate import simulate
    from signorini.studies.benchmarks import get_benchmark

    case = load_case(EXAMPLES[[p.stem for p in EXAMPLES].index("bar2d")])
    H1 = simulate(case.problem, case.scheme, case.dt, case.T, mass=case.mass)
    b = get_benchmark("bar2d")
    H2 = simulate(b.problem(4), "cn", b.h(4) / 2, 1.0, mass="seed")
    assert abs(H1.energy - H2.energy).max() < 1e-14 and abs(H1.lam - H2.lam).max() < 1e-14


BASE = (Path(__file__).parents[1] / "examples" / "bar2d.toml").read_text()


@pytest.mark.parametrize(
    "old, new, message",
    [
        ("dt = 0.0125", "dtt = 0.0125", "unknown key 'time.dtt'; allowed: T, dt, scheme"),
        ("dt = 0.0125", "dt = -0.0125", "time.dt must be > 0"),
        ("dt = 0.0125", "dt = 0.0", "time.dt must be > 0"),
        ("dt = 0.0125", 'dt = "small"', "'time.dt' must be a number"),
        ("T = 1.0", "T = 0.001", "'time.T' must be >= 'time.dt'"),
        ('tag = "ymin"', 'tag = "bottom"', "unknown boundary tag 'bottom'"),
        ('mass = "seed"', 'mass = "heavy"', "unknown solver.mass 'heavy'"),
        ('scheme = "crank-nicolson"', 'scheme = "rk4"', "unknown time.scheme 'rk4'"),
        ("rho = 1.0", "rho = -1.0", "rho"),
        ("[solver]", "[solvr]", "unknown section [solvr]"),
        ("velocity = [0.0, -0.5]", 'velocity = [0.0, "-0.5 * q"]', "unknown name(s) ['q']"),
        ("cells = [4, 40]", "cells = [4]", "'mesh.cells' must be a list of 2 positive integers"),
        ("cells = [4, 40]", "cells = [4, " + "9" * 400 + "]", "'mesh.cells[1]' = 9999"),
        ("value = [0.0, 0.2]", "value = [0.0]", "'dirichlet[0].value' must be a list of 2 numbers"),
    ],
)
def test_bad_case_files_exit_2_nothing_written(tmp_path, capsys, old, new, message):
    assert old in BASE
    case = tmp_path / "case.toml"
    case.write_text(BASE.replace(old, new, 1))
    out = tmp_path / "out"
    assert main(["run", str(case), "--out", str(out), "--quiet"]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.toml"]


def test_missing_case_file(tmp_path, capsys):
    assert main(["run", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "o")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_contact_tag_fixed_by_dirichlet(tmp_path, capsys):
    case = tmp_path / "c.toml"
    case.write_text(BASE.replace('[[dirichlet]]\ntag = "ymax"', '[[dirichlet]]\ntag = "ymin"'))
    assert main(["run", str(case), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "fixed by a Dirichlet condition" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
