"""The distributed backend's loading: a clear input error without PETSc.  (The runs on
several ranks are tests/linalg/test_petsc_run.py; the first step's partition and assembly
self-test went with the modules it tested, issue 31 item 6.)"""

from __future__ import annotations

import pytest

from signorini.errors import InputError
from signorini.linalg import petsc


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
