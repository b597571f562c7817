"""The factor cache's owner (issue 39, item 1): one system per operator up to a positive factor,
released or kept on a ladder when the step changes, counters kept, warm starts passed on."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from signorini.dynamics.model.operator import Operator, Tangent
from signorini.dynamics.solve.factorizations import Factorizations
from signorini.errors import InputError


class _Solver:
    warm_state = ("active",)

    def __init__(self, nbytes: int):
        self.counters = {"factorizations": 1, "linear_solves": 0}
        self.factor_bytes = nbytes
        self.active = np.zeros(3, dtype=bool)
        self.released = False

    def release(self) -> None:
        self.released = True


class _System:
    def __init__(self, op: Operator, nbytes: int = 100):
        self.op, self.solver = op, _Solver(nbytes)


def test_a_multiple_of_an_operator_shares_its_system():
    f = Factorizations(_System, 0.1)
    a, s = f.system(Operator(400.0, 1.0))
    b, s2 = f.system(Operator(100.0, 0.25))  # Paoli-Schatzman's M/dt^2 + S/4 against CN's 4 M/dt^2 + S
    assert a is b and s == 1.0 and s2 == pytest.approx(0.25, rel=1e-14, abs=0.0) and len(f.current) == 1
    c, _ = f.system(Operator(1.0, 1.0))
    assert c is not a and f.counters()["factorizations"] == 2
    with pytest.raises(InputError, match="non-negative coefficients"):
        f.system(Operator(-1.0, 1.0))


def test_replace_releases_the_systems_and_keeps_their_counters():
    f = Factorizations(_System, 0.1)
    sys, _ = f.system(Operator(1.0, 1.0))
    sys.solver.counters["linear_solves"] = 7
    f.replace(0.05, [Operator(4.0, 1.0)])
    assert f.dt == 0.05 and len(f.current) == 1 and f.current[0].op == Operator(4.0, 1.0)
    assert f.counters() == {"factorizations": 2, "linear_solves": 7}


def test_the_ladder_keeps_steps_passes_warm_starts_and_drops_the_least_recently_used():
    f = Factorizations(_System, 1.0)
    first = f.system(Operator(1.0, 1.0))[0]
    first.solver.active[:] = [True, False, True]
    f.use(0.5, [Operator(4.0, 1.0)], keep_bytes=1e9)
    half = f.current[0]
    assert np.array_equal(half.solver.active, [True, False, True])  # passed on, a copy
    assert half.solver.active is not first.solver.active
    assert [dt for dt, _ in f.by_step()] == [1.0, 0.5] and len(f.every()) == 2
    f.use(1.0, [], keep_bytes=1e9)  # taken back, not factorized again
    assert f.current[0] is first and f.counters()["factorizations"] == 2
    f.use(0.25, [Operator(16.0, 1.0)], keep_bytes=150)  # two kept steps of 100 bytes: the older goes
    assert [dt for dt, _ in f.by_step()] == [1.0, 0.25]
    assert f.counters()["factorizations"] == 3  # the dropped step's counters are kept


def _tangent_system(f: Factorizations, mass: float = 1.0) -> tuple[Operator, _System]:
    op = Operator(mass, 1.0, Tangent(sp.identity(3, format="csr")))
    return op, f.system(op)[0]


def test_a_kept_tangent_serves_its_coefficients_across_steps_and_replaces_the_one_before():
    """A Newton tangent kept across levels (issue 51, item 3) leaves the step's list, is found again by its
    operator and by its coefficients whatever the current step, and is retired when another is kept in its
    place; its counters stay in the run's."""
    f = Factorizations(_System, 1.0)
    f.system(Operator(1.0, 1.0))
    op, sys = _tangent_system(f)
    f.keep(op)
    assert f.kept == [sys] and sys not in f.current and sys in f.every() and f.system(op) == (sys, 1.0)
    assert f.kept_for(Operator(1.0, 1.0)) is op and f.kept_for(Operator(4.0, 1.0)) is None
    f.use(0.5, [Operator(4.0, 1.0)], keep_bytes=1e9)  # another step: still kept (a step of its coefficients)
    assert f.kept == [sys] and f.kept_for(Operator(1.0, 1.0)) is op
    op2, sys2 = _tangent_system(f, 4.0)
    f.keep(op2)
    assert f.kept == [sys2] and sys.solver.released and f.counters()["factorizations"] == 4


def test_a_rejected_steps_kept_tangent_is_retired_and_the_one_before_kept_again():
    """While a step is on trial the tangent it replaces stays factorized: its rollback keeps it again (and
    retires the step's), its acceptance retires it."""
    f = Factorizations(_System, 1.0)
    op, sys = _tangent_system(f)
    f.keep(op)
    f.mark_kept()
    op2, sys2 = _tangent_system(f)
    f.keep(op2)
    assert f.kept == [sys2] and not sys.solver.released
    f.rollback_kept()
    assert f.kept == [sys] and sys2.solver.released and not sys.solver.released
    f.mark_kept()
    op3, sys3 = _tangent_system(f)
    f.keep(op3)
    f.release_kept()
    assert f.kept == [sys3] and sys.solver.released and not sys3.solver.released


def test_a_schedule_step_that_cannot_be_factorized_fails_the_run_keeping_its_levels(tmp_path, monkeypatch, capsys):
    """Issue 52, a hostile input: a dt schedule whose second step's operator cannot be factorized (here SuperLU's
    "Factor is exactly singular" on the second factorization of a fixed-step run, the first piece's being the set-up's).
    The run fails there with one line naming the operator, exit 3, its levels and summary written; before, the
    released systems left none for the summary and the command ended in "internal error: IndexError" (exit 1), the
    levels lost."""
    import json

    import scipy.sparse.linalg as spla

    import signorini.linalg.superlu as superlu
    from signorini.io.cli import main

    case = tmp_path / "case.toml"
    case.write_text(
        '[mesh]\ngenerator = "rectangle"\ncells = [8, 4]\nsize = [0.02, 0.01]\ncell = "quad"\n'
        "[material]\nE = 210e9\nnu = 0.3\nrho = 7850.0\n"
        '[contact]\ntag = "ymin"\nobstacle = { type = "plane", point = [0.0, -1e-6], normal = [0.0, 1.0] }\n'
        "[initial]\nvelocity = [0.0, -1.0]\n"
        '[time]\nscheme = "crank-nicolson"\ndt = [{until = 1e-5, dt = 5e-6}, {until = 3e-5, dt = 1e-6}]\n'
    )
    real, calls = spla.splu, []

    def splu(*args, **kwargs):
        calls.append(1)
        if len(calls) >= 2:
            raise RuntimeError("Factor is exactly singular")
        return real(*args, **kwargs)

    monkeypatch.setattr(superlu.spla, "splu", splu)
    out = tmp_path / "out"
    rc = main(["run", str(case), "--dt-control", "fixed", "--solver-option", "backend=superlu", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 3, err
    assert "internal error" not in err and "cannot be factorized" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["backend"] == "superlu"
    levels = np.loadtxt(out / "history.csv", delimiter=",", skiprows=1, usecols=0)
    assert levels.size == 3 and levels[-1] == pytest.approx(1e-5, rel=1e-12, abs=0.0)  # t = 0, 5 and 10 us
