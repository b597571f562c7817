"""The distributed backend's first step (issue 22): partition and assembly on 2 and 3 MPI ranks.

Runs ``python -m signorini.linalg.petsc.selftest`` under ``.venv-mpi/bin/mpiexec`` (made by
``bash scripts/mpi-env.sh``; CI runs the script first, so these tests never skip there).
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from signorini.errors import InputError
from signorini.linalg import petsc

VENV = Path(__file__).parents[1] / ".venv-mpi" / "bin"
needs_venv = pytest.mark.skipif(
    not (VENV / "mpiexec").exists(), reason="no .venv-mpi: run `bash scripts/mpi-env.sh` (PETSc, MPI, Python >= 3.12)"
)


@needs_venv
@pytest.mark.parametrize("ranks", [2, 3])
def test_distributed_assembly_matches_serial(ranks):
    """S and the consistent mass assembled on each rank's own cells (PT-Scotch partition,
    contiguous owned ranges) give the serial operators' products to round-off (measured 2e-16
    to 6e-16 relative), on hexahedra and tetrahedra; every cell and node is owned once."""
    run = subprocess.run(
        [str(VENV / "mpiexec"), "-n", str(ranks), str(VENV / "python"), "-m", "signorini.linalg.petsc.selftest"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    report = json.loads(run.stdout.strip().splitlines()[-1])
    assert report["ranks"] == ranks
    for mesh, cells, nodes in (("hexahedra", 80, 189), ("tetrahedra", 324, 112)):
        r = report[mesh]
        assert r["S"] <= 1e-14 and r["M"] <= 1e-14
        assert sum(r["cells"]) == cells and sum(r["owned_nodes"]) == nodes
        assert min(r["cells"]) >= 0.8 * cells / ranks  # balanced
        assert r["partitioner"] == "ptscotch"
    assert len(report["peak_memory_mib"]) == ranks


def test_missing_petsc_is_a_clear_input_error(monkeypatch):
    import builtins

    real_import = builtins.__import__

    def no_petsc(name, *args, **kwargs):
        if name.startswith(("petsc4py", "mpi4py")):
            raise ImportError(f"No module named {name!r}")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_petsc)
    with pytest.raises(InputError, match="scripts/mpi-env.sh"):
        petsc.load()
