"""The run-size estimate (dynamics/stepping/budget.py) and its count of MPI ranks on this machine."""

from __future__ import annotations

import pytest

from signorini.dynamics.stepping.budget import BASE_BYTES, COLUMNS_BUDGET, estimate_run
from signorini.linalg.base import estimate_factor_bytes
from signorini.parallel import local_ranks

#: (nodes, cells, nodes per cell, dim, contact nodes) of a 3D hexahedral bar
COUNTS = (150_817, 138_240, 8, 3, 625)


def test_a_serial_backend_ignores_the_ranks():
    one = estimate_run(*COUNTS, 100, backend="superlu")
    assert estimate_run(*COUNTS, 100, backend="superlu", ranks=(4, 4)).total_bytes == one.total_bytes
    assert one.factor_bytes == estimate_factor_bytes(3 * COUNTS[0], 3, "superlu")


@pytest.mark.parametrize("P, L", [(1, 1), (2, 2), (4, 2), (8, 1)])
def test_each_local_rank_holds_its_history_and_a_share_of_the_assembly_and_the_factor(P, L):
    e = estimate_run(*COUNTS, 100, backend="petsc", ranks=(P, L))
    assert (e.ranks, e.local_ranks) == (P, L)
    assert e.factor_bytes == estimate_factor_bytes(3 * COUNTS[0], 3, "pardiso")  # MUMPS: nested dissection
    per_rank = BASE_BYTES + (e.setup_bytes - BASE_BYTES) / P  # each rank assembles its own rows
    columns = min(8.0 * e.dofs * COUNTS[4], COLUMNS_BUDGET * P)  # the lazy Delassus columns, spread as the factor
    assert e.columns_bytes == columns
    expected = L * (per_rank + e.history_bytes) + (e.factor_bytes + columns) * L / P
    assert e.total_bytes == pytest.approx(expected, rel=1e-15, abs=0.0)
    if P > 1:
        assert f"{L} of {P} MPI ranks" in e.describe()


def test_petsc_cg_has_no_factor_and_cg_neither():
    for backend in ("petsc-cg", "cg"):
        e = estimate_run(*COUNTS, 100, backend=backend, ranks=(2, 2))
        assert e.factor_bytes == 0.0 and e.columns_bytes == 0.0


def test_local_ranks_from_the_process_manager(monkeypatch):
    for var in ("PMI_RANK", "PMI_SIZE", "OMPI_COMM_WORLD_RANK", "OMPI_COMM_WORLD_SIZE", "MPI_LOCALNRANKS",
                "OMPI_COMM_WORLD_LOCAL_SIZE"):  # fmt: skip
        monkeypatch.delenv(var, raising=False)
    assert local_ranks() == (1, 1)
    monkeypatch.setenv("PMI_RANK", "0")
    monkeypatch.setenv("PMI_SIZE", "8")
    assert local_ranks() == (8, 8)  # no local count: all on this machine (the safe side)
    monkeypatch.setenv("MPI_LOCALNRANKS", "2")
    assert local_ranks() == (8, 2)
    monkeypatch.setenv("MPI_LOCALNRANKS", "junk")
    assert local_ranks() == (8, 8)


def test_petscs_columns_follow_the_runs_condense_budget(monkeypatch):
    """The Delassus columns are bounded by the run's ``condense_budget`` per rank, as given
    on the command line or in the case file; a value that the options' validation will
    refuse counts as the default here (the refusal comes from the validation)."""
    small = estimate_run(*COUNTS, 100, backend="petsc", ranks=(2, 2), condense_budget=1e6)
    assert small.columns_bytes == 2e6
    seen = []
    monkeypatch.setattr("signorini.dynamics.stepping.budget.check_run_size", lambda est, *a: seen.append(est))
    from signorini.io.run_command import check_size

    monkeypatch.setattr("signorini.parallel.local_ranks", lambda: (2, 2))
    default = min(8.0 * 3 * COUNTS[0] * COUNTS[4], 2 * COLUMNS_BUDGET)
    for given, expected in ((1e6, 2e6), ("junk", default), (-1.0, default), (float("inf"), default), (None, default)):
        solver = {"backend": "petsc"} if given is None else {"backend": "petsc", "condense_budget": given}
        check_size(COUNTS, 0.1, 1.0, {}, solver)
        assert seen[-1].columns_bytes == expected, given
