"""Exit codes and one-line messages for every kind of failure (issue: hard inputs)."""

import errno
import json

import pytest

from signorini.dynamics.observe.history import COUNTER_KEYS
from signorini.io.cli import main

BAR1D = (
    '[mesh]\ngenerator = "interval"\ncells = [8]\nsize = [1.0]\n[material]\nrho = 1.0\nE = 1.0\n'
    '[[dirichlet]]\ntag = "xmax"\nvalue = [0.2]\n[contact]\ntag = "xmin"\n'
    'obstacle = { type = "plane", point = [0.0], normal = [1.0] }\n[initial]\ndisplacement = [0.2]\n'
    "velocity = [-0.5]\n[time]\ndt = 0.0625\nT = 1.0\n"
)


def _run(tmp_path, capsys, args):
    rc = main(args)
    cap = capsys.readouterr()
    assert "Traceback" not in cap.err + cap.out
    return rc, cap.err


def _one_line(err: str, prefix: str = "signorini: error:") -> None:
    assert err.count("\n") == 1 and err.startswith(prefix), err


def test_dt_not_dividing_T_names_both_and_the_nearest_valid_steps(tmp_path, capsys):
    rc, err = _run(tmp_path, capsys, ["run", "bar1d", "--dt", "0.45", "--T", "1", "--out", str(tmp_path / "o")])
    assert rc == 2
    _one_line(err)
    assert "T = 1 is not an integer multiple of dt = 0.45" in err and "0.3333333333 (3 steps) or 0.5 (2 steps)" in err
    assert not (tmp_path / "o").exists()


def test_large_runs_need_confirmation(tmp_path, capsys):
    out = str(tmp_path / "o")
    rc, err = _run(tmp_path, capsys, ["run", "bar1d", "--n", "4", "--T", "1e7", "--out", out])
    assert rc == 2
    _one_line(err)
    assert "80,000,000 steps" in err and "GiB" in err and "--yes" in err
    rc, err = _run(tmp_path, capsys, ["run", "bar1d", "--n", "4", "--T", "6", "--max-steps", "10", "--out", out])
    assert rc == 2 and "more than --max-steps 10 steps" in err
    rc, err = _run(tmp_path, capsys, ["run", "bar1d", "--n", "4", "--T", "1", "--max-memory", "1e-6", "--out", out])
    assert rc == 2 and "more than --max-memory" in err
    rc, _ = _run(tmp_path, capsys, ["run", "bar1d", "--n", "4", "--T", "6", "--max-steps", "10", "--yes",
                                    "--out", out, "--quiet"])  # fmt: skip
    assert rc == 0


def test_case_file_limits(tmp_path, capsys):
    case = tmp_path / "c.toml"
    case.write_text(BAR1D + "[limits]\nmax_steps = 4\n")
    rc, err = _run(tmp_path, capsys, ["run", str(case), "--out", str(tmp_path / "o"), "--quiet"])
    assert rc == 2 and "16 steps" in err
    case.write_text(BAR1D + "[limits]\nmax_steps = 4\nyes = true\n")
    assert _run(tmp_path, capsys, ["run", str(case), "--out", str(tmp_path / "o"), "--quiet"])[0] == 0
    case.write_text(BAR1D + '[limits]\nyes = "please"\n')
    rc, err = _run(tmp_path, capsys, ["run", str(case), "--out", str(tmp_path / "o2"), "--quiet"])
    assert rc == 2 and "'limits.yes' must be true or false" in err


def test_inside_a_sphere_says_so(tmp_path, capsys):
    case = tmp_path / "c.toml"
    case.write_text(BAR1D.replace('{ type = "plane", point = [0.0], normal = [1.0] }',
                                  '{ type = "sphere", center = [0.1], radius = 0.5 }'))  # fmt: skip
    rc, err = _run(tmp_path, capsys, ["run", str(case), "--out", str(tmp_path / "o")])
    assert rc == 2
    _one_line(err)
    assert "starts inside the ball" in err and "radius 0.5" in err


def test_file_that_is_not_a_mesh(tmp_path, capsys):
    (tmp_path / "bad.msh").write_text("garbage\n")
    case = tmp_path / "c.toml"
    case.write_text(BAR1D.replace('generator = "interval"\ncells = [8]\nsize = [1.0]', 'file = "bad.msh"'))
    rc, err = _run(tmp_path, capsys, ["run", str(case), "--out", str(tmp_path / "o")])
    assert rc == 2
    _one_line(err)
    assert "cannot read mesh file" in err and "bad.msh" in err


def test_non_finite_operators_fail_with_status_and_exit_3(tmp_path, capsys):
    """rho = 1e100 with dt = 1e-150 overflows rho/dt^2: exit 3, status failed in summary.json, one line."""
    case = tmp_path / "c.toml"
    case.write_text(
        BAR1D.replace("rho = 1.0", "rho = 1e100").replace("dt = 0.0625\nT = 1.0", "dt = 1e-150\nT = 1.6e-149")
    )
    rc, err = _run(tmp_path, capsys, ["run", str(case), "--out", str(tmp_path / "o"), "--quiet"])
    assert rc == 3
    _one_line(err, "signorini: failed:")
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["status"] == "failed" and not s["success"] and "non-finite entries" in s["message"]
    assert s["counters"] == dict.fromkeys(COUNTER_KEYS, 0) and s["steps"] == 0


@pytest.mark.parametrize(
    "exc, code, text",
    [
        (MemoryError(), 4, "out of memory"),
        (OSError(errno.ENOSPC, "No space left on device"), 4, "No space left on device"),
        (TypeError("a bug"), 1, "internal error: TypeError: a bug"),
    ],
)
def test_environment_failures_and_bugs_are_one_line(tmp_path, capsys, monkeypatch, exc, code, text):
    import signorini.dynamics.stepping.simulate as sim

    def boom(*a, **k):
        raise exc

    monkeypatch.setattr(sim, "simulate", boom)
    rc, err = _run(tmp_path, capsys, ["run", "bar1d", "--n", "4", "--T", "1", "--out", str(tmp_path / "o")])
    assert rc == code
    assert err.count("\n") == 1 and text in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "source, message",
    [("import sys\nsys.exit(0)\n", "called sys.exit(0)"), ("import sys\nsys.exit('bye')\n", "called sys.exit('bye')"),
     ("raise ValueError('boom')\n", "raised ValueError: boom"), ("x = 1 / 0\n", "raised ZeroDivisionError"),
     ("import no_such_module_here\n", "cannot import it"), ("class X:\n    pass\n", "not a subclass")],
)  # fmt: skip
def test_a_scheme_plugin_that_fails_on_import_is_an_input_error_naming_scheme(tmp_path, capsys, source, message):
    """The user's module exiting or raising while imported is their input's failure: exit 2,
    one line naming --scheme and why, nothing written (not exit 0 with no result, nor an
    internal error of signorini)."""
    plugin = tmp_path / "plugin.py"
    plugin.write_text(source)
    rc, err = _run(tmp_path, capsys, ["run", "bar1d", "--scheme", f"{plugin}:X", "--out", str(tmp_path / "o")])
    assert rc == 2
    _one_line(err)
    assert "--scheme" in err and message in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("scheme", ["", "  "])
def test_an_empty_scheme_is_refused_not_the_default(tmp_path, capsys, scheme):
    rc, err = _run(tmp_path, capsys, ["run", "bar1d", "--scheme", scheme, "--out", str(tmp_path / "o")])
    assert rc == 2 and "--scheme must not be empty" in err and "crank-nicolson" in err
    assert not (tmp_path / "o").exists()


def _case_with(tmp_path, **replace) -> str:
    text = BAR1D
    for old, new in replace.items():
        text = text.replace(old, new)
    path = tmp_path / "case.toml"
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize("where", ["x", "x + 1", "2", "not x", "x < 1 and y"])
def test_where_must_be_a_condition(tmp_path, capsys, where):
    """A number is not taken as ``!= 0``: ``where`` is a comparison or and/or/not of them."""
    case = _case_with(tmp_path, **{'tag = "xmin"\n': f'tag = "xmin"\nwhere = "{where}"\n'})
    rc, err = _run(tmp_path, capsys, ["run", case, "--out", str(tmp_path / "o")])
    assert rc == 2 and "'contact.where' must be a condition" in err
    _one_line(err)
    assert not (tmp_path / "o").exists()


def _mesh_case(tmp_path, mesh_name: str) -> str:
    gen = '[mesh]\ngenerator = "interval"\ncells = [8]\nsize = [1.0]\n'
    return _case_with(tmp_path, **{gen: f'[mesh]\nfile = "{mesh_name}"\n'})


@pytest.mark.parametrize(
    "kind, message",
    [("empty", "the file is empty"), ("directory", "is a directory, not a mesh file"),
     ("fifo", "is a named pipe (FIFO)"), ("missing", "does not exist"),
     ("huge-header", "a corrupt header or a truncated file"), ("huge-header-22", "a corrupt header")],
)  # fmt: skip
def test_a_mesh_file_that_is_not_one_says_what_it_is(tmp_path, capsys, kind, message):
    """Exit 2 and the real reason: not 'does not exist' for a directory or a FIFO, not 'out of
    memory' for a header that declares 1e12 nodes in a 93-byte file."""
    import os

    m = tmp_path / "part.msh"
    if kind == "empty":
        m.write_bytes(b"")
    elif kind == "directory":
        m.mkdir()
    elif kind == "fifo":
        os.mkfifo(m)
    elif kind == "huge-header":
        m.write_text(
            "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 999999999999 1 999999999999\n2 1 0 999999999999\n1\n"
        )
    elif kind == "huge-header-22":
        m.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n99999999999999\n1 0 0 0\n")
    rc, err = _run(tmp_path, capsys, ["run", _mesh_case(tmp_path, "part.msh"), "--out", str(tmp_path / "o")])
    assert rc == 2 and message in err, err
    _one_line(err)
    assert not (tmp_path / "o").exists()


def test_simulate_refuses_what_is_not_a_problem_and_a_float32_step():
    import numpy as np

    from signorini.dynamics.stepping.simulate import simulate
    from signorini.errors import InputError
    from signorini.studies.benchmarks import get_benchmark

    with pytest.raises(InputError, match="must be a signorini Problem or Discretization, got NoneType"):
        simulate(None, "cn", 0.1, 1.0)
    with pytest.raises(InputError, match=r"got float32 0\.1, which is 0\.10000000149011612 in double"):
        simulate(get_benchmark("bar1d").problem(10), "cn", np.float32(0.1), 1.0)


def test_memory_failures_are_recognized_whatever_their_type():
    from signorini.errors import is_memory_failure

    assert is_memory_failure(MemoryError())
    assert is_memory_failure(ImportError("libgfortran.so.5: failed to map segment from shared object"))
    assert is_memory_failure(OSError(errno.ENOMEM, "Cannot allocate memory"))
    assert not is_memory_failure(ImportError("No module named 'gmsh'"))
    assert not is_memory_failure(OSError(errno.ENOENT, "No such file"))
