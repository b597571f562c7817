import json
from pathlib import Path

import numpy as np
import pytest

from signorini.errors import InputError
from signorini.io.cli import main
from signorini.io.config import load_case

EXAMPLES = sorted((Path(__file__).parents[2] / "examples").glob("*.toml"))
#: examples whose run takes minutes: run (and checked) by the slow suite's own test in tests/test_examples.py
LONG_EXAMPLES = {"bracket_tumble"}


@pytest.mark.parametrize("path", [p for p in EXAMPLES if p.stem not in LONG_EXAMPLES],
                         ids=[p.stem for p in EXAMPLES if p.stem not in LONG_EXAMPLES])  # fmt: skip
def test_every_example_runs(tmp_path, path):
    out = tmp_path / "o"
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["steps"] > 0 and s["max_complementarity_residual"] < 2e-14  # relative; measured 4.4e-16
    assert (out / "case.toml").read_text() == path.read_text()


def test_case_matches_benchmark(tmp_path):
    from signorini.dynamics.stepping.simulate import simulate
    from signorini.studies.benchmarks import get_benchmark

    case = load_case(EXAMPLES[[p.stem for p in EXAMPLES].index("bar2d")])
    H1 = simulate(case.problem, case.scheme, case.dt, case.T, mass=case.mass)
    b = get_benchmark("bar2d")
    H2 = simulate(b.problem(4), "cn", b.h(4) / 2, 1.0, mass="seed")
    assert abs(H1.energy - H2.energy).max() < 1e-14 and abs(H1.lam - H2.lam).max() < 1e-14


BASE = (Path(__file__).parents[2] / "examples" / "bar2d.toml").read_text()


@pytest.mark.parametrize(
    "old, new, message",
    [
        ("dt = 0.0125", "dtt = 0.0125", "unknown key 'time.dtt'; allowed: T, control, dt, dt_min, scheme"),
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


def _case_text(extra: str) -> str:
    return (
        '[mesh]\ngenerator = "rectangle"\ncells = [2, 2]\nsize = [1.0, 1.0]\n[material]\nrho = 1.0\nE = 1.0\n'
        '[contact]\ntag = "ymin"\nobstacle = { type = "plane", point = [0.0, -0.1], normal = [0.0, 1.0] }\n'
        "[time]\ndt = 0.1\nT = 0.2\n" + extra
    )


@pytest.mark.parametrize(
    "extra, match",
    [
        (
            '[[traction]]\ntag = "xmax"\nvalue = [1.0, 0.0]\n[[traction]]\ntag = "xmax"\nvalue = [0.0, 1.0]\n',
            "repeats tag 'xmax'",
        ),
        (
            '[[dirichlet]]\ntag = "ymax"\nvalue = [0.0, 0.0]\n[[dirichlet]]\ntag = "ymax"\ncomponents = [1]\n'
            "value = [0.1]\n",
            "both prescribe component",
        ),
        ("", None),
    ],
)
def test_repeated_tractions_and_conflicting_dirichlet_blocks_are_refused(tmp_path, extra, match):
    from signorini.io.config import load_case

    path = tmp_path / "c.toml"
    path.write_text(_case_text(extra))
    if match is None:
        assert load_case(path).problem.contact_tag == "ymin"
        return
    with pytest.raises(InputError, match=match):
        load_case(path)


def test_contact_tag_list_and_where(tmp_path):
    from signorini.io.config import load_case

    path = tmp_path / "c.toml"
    text = _case_text("").replace('tag = "ymin"\nobstacle', 'tag = ["ymin", "xmin"]\nwhere = "y < 0.6"\nobstacle')
    path.write_text(text)
    p = load_case(path).problem
    assert p.contact_tag == ("ymin", "xmin")
    assert p.contact_where(np.array([[0.0, 0.5], [0.0, 1.0]])).tolist() == [True, False]
    for bad, match in (('where = "t < 1"', "x, y and z only"), ("where = 3", "expression string"),
                       ('where = "__import__(1)"', "not allowed|unknown name")):  # fmt: skip
        path.write_text(text.replace('where = "y < 0.6"', bad))
        with pytest.raises(InputError, match=match):
            load_case(path)
    path.write_text(text.replace('tag = ["ymin", "xmin"]', "tag = []"))
    with pytest.raises(InputError, match="non-empty list"):
        load_case(path)


def test_deeply_nested_toml_is_an_input_error(tmp_path):
    from signorini.io.config import load_case

    path = tmp_path / "deep.toml"
    path.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(InputError, match="TOML"):
        load_case(path)


def test_where_with_a_non_finite_value_is_refused(tmp_path):
    path = tmp_path / "c.toml"
    text = _case_text("").replace('tag = "ymin"\nobstacle', 'tag = "ymin"\nwhere = "sqrt(x - 0.5) < 1"\nobstacle')
    path.write_text(text)
    from signorini.dynamics.model.problem import discretize

    with pytest.raises(InputError, match="not finite"):
        discretize(load_case(path).problem, "standard")


def test_dirichlet_blocks_on_two_tags_must_agree_on_shared_nodes(tmp_path):
    path = tmp_path / "c.toml"
    clash = (
        '[[dirichlet]]\ntag = "ymax"\nvalue = [0.0, 0.0]\n[[dirichlet]]\ntag = "xmax"\ncomponents = [0]\n'
        "value = [0.1]\n"
    )
    path.write_text(_case_text(clash))
    from signorini.dynamics.model.problem import discretize

    with pytest.raises(InputError, match="prescribe different values"):
        discretize(load_case(path).problem, "standard")
    path.write_text(_case_text(clash.replace("[0.1]", "[0.0]")))  # agreeing: fine
    assert discretize(load_case(path).problem, "standard").fixed.size > 0
