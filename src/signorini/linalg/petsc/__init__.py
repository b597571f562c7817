"""The distributed backend on PETSc (issue 22), imported only when asked for.

``petsc4py`` and ``mpi4py`` are not dependencies of ``pip install .``: they come with the
``mpi`` extra (the binary wheel ``dolfinx-solver-real``, PETSc 3.25 with MUMPS, METIS and
PT-Scotch, and the MPICH wheel), which ``scripts/mpi-env.sh`` installs in ``.venv-mpi/``
(Python >= 3.12).  :func:`load` imports them in the order the wheel needs (``mpi4py.MPI``
first, or ``petsc4py`` cannot find ``libmpi``) and says how to get them when they are
missing.

What exists (docs/parallel.md, docs/design.md "Beyond one machine"): the backend
``petsc``, a parallel MUMPS Cholesky behind the serial factor contract (:mod:`.factor`),
fed by each rank's rows of the operators (:mod:`signorini.dynamics.model.owned_rows`, on the
Z-order renumbering of :mod:`signorini.fem.node_order`).  The earlier PT-Scotch partition
and PETSc-matrix assembly that only a self-test used were removed (issue 31, item 6).
"""

from __future__ import annotations

from types import ModuleType

from ...errors import InputError
from ...parallel import INSTALL_HINT


def load() -> tuple[ModuleType, ModuleType]:
    """(mpi4py.MPI, petsc4py.PETSc), or an :class:`InputError` saying how to install them."""
    try:
        from mpi4py import MPI  # first: petsc4py's libraries link against its libmpi
        from petsc4py import PETSc
    except ImportError as exc:
        raise InputError(f"{INSTALL_HINT} ({type(exc).__name__}: {exc})") from None
    return MPI, PETSc


def available() -> bool:
    """Whether :func:`load` would succeed (without importing anything heavy when it would not)."""
    import importlib.util

    return importlib.util.find_spec("petsc4py") is not None and importlib.util.find_spec("mpi4py") is not None
