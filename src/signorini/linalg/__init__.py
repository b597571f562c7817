"""Linear algebra: direct factorizations (SuperLU, Pardiso, CHOLMOD), orderings and Krylov solvers."""

from .base import (
    BACKENDS,
    PRECONDITIONERS,
    SOLVER_OPTIONS,
    BackendTraits,
    Factor,
    backend_traits,
    choose_backend,
    estimate_factor_bytes,
    factor_class,
    factorize,
    has_cholmod,
    has_pardiso,
    solver_options,
    total_memory,
)
from .krylov import Preconditioner, has_pyamg, make_preconditioner, projected_cg
from .ordering import fill_reducing_order, has_metis, nested_dissection

__all__ = [
    "BACKENDS",
    "PRECONDITIONERS",
    "SOLVER_OPTIONS",
    "BackendTraits",
    "Factor",
    "backend_traits",
    "Preconditioner",
    "make_preconditioner",
    "choose_backend",
    "estimate_factor_bytes",
    "factor_class",
    "factorize",
    "has_cholmod",
    "has_pardiso",
    "has_metis",
    "has_pyamg",
    "fill_reducing_order",
    "nested_dissection",
    "projected_cg",
    "solver_options",
    "total_memory",
]
