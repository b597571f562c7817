"""Linear algebra: direct factorizations (SuperLU, Pardiso) and Krylov solvers."""

from .base import (
    BACKENDS,
    PRECONDITIONERS,
    SOLVER_OPTIONS,
    Factor,
    choose_backend,
    estimate_factor_bytes,
    factorize,
    has_pardiso,
    solver_options,
    total_memory,
)
from .krylov import Preconditioner, has_pyamg, make_preconditioner, projected_cg

__all__ = [
    "BACKENDS",
    "PRECONDITIONERS",
    "SOLVER_OPTIONS",
    "Factor",
    "Preconditioner",
    "make_preconditioner",
    "choose_backend",
    "estimate_factor_bytes",
    "factorize",
    "has_pardiso",
    "has_pyamg",
    "projected_cg",
    "solver_options",
    "total_memory",
]
