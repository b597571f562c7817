#!/usr/bin/env bash
# The MPI/PETSc environment of the petsc backend (issue 22): .venv-mpi/ with Python >= 3.12,
# this package (editable, with the mpi and test extras: the dolfinx-solver-real wheel
# brings PETSc 3.25 + petsc4py, mpi4py and the MPICH wheel) and .venv-mpi/bin/mpiexec.
# Idempotent; run from anywhere as root on a fresh Linux x86-64 machine:
#     bash scripts/mpi-env.sh
#     .venv-mpi/bin/mpiexec -n 2 .venv-mpi/bin/python -m signorini.linalg.petsc.selftest
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=.venv-mpi

find_python() {
    for cand in python3.12 python3.13 python3; do
        if command -v "$cand" >/dev/null 2>&1 && "$cand" -c 'import sys; raise SystemExit(sys.version_info < (3, 12))' 2>/dev/null; then
            command -v "$cand"; return
        fi
    done
    if command -v pyenv >/dev/null 2>&1; then  # pyenv keeps other versions out of PATH's shims
        local v
        v=$(pyenv versions --bare 2>/dev/null | grep -E '^3\.1[2-9](\.[0-9]+)?$' | sort -V | head -1 || true)
        if [ -n "$v" ]; then echo "$(pyenv root)/versions/$v/bin/python${v%.*}"; return; fi
    fi
    return 1
}

if [ ! -x "$VENV/bin/python" ]; then
    PY=$(find_python) || { echo "mpi-env: needs Python >= 3.12 (the dolfinx-solver-real wheel)" >&2; exit 1; }
    "$PY" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install --quiet --upgrade pip
"$VENV/bin/python" -m pip install --quiet -e ".[mpi,mesh,test]"
# MPICH's hydra (from the wheel) is the launcher: it runs as root and on more ranks than cores
test -x "$VENV/bin/mpiexec"
"$VENV/bin/mpiexec" -n 2 "$VENV/bin/python" -c "from mpi4py import MPI; from petsc4py import PETSc; assert MPI.COMM_WORLD.size == 2"
echo "mpi-env: $VENV ready ($("$VENV/bin/python" -c 'from mpi4py import MPI; from petsc4py import PETSc; print("PETSc", ".".join(map(str, PETSc.Sys.getVersion())), "|", MPI.Get_library_version().splitlines()[0])'))"
