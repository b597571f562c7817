"""The direct backends the tests run on, and the guards of the other optional packages: each
optional test runs only when its package is installed (the plain install skips it, with the reason)."""

import importlib.util

import pytest

from signorini.linalg import has_cholmod, has_pardiso

DIRECT = [
    "superlu",
    pytest.param(
        "pardiso", marks=pytest.mark.skipif(not has_pardiso(), reason="pypardiso not installed (extra 'pardiso')")
    ),
    pytest.param(
        "cholmod", marks=pytest.mark.skipif(not has_cholmod(), reason="cvxopt not installed (extra 'cholmod')")
    ),
]

#: gmsh (extra 'mesh'): the Hertz benchmarks' meshes and the parts made by make_parts.py
HAS_GMSH = importlib.util.find_spec("gmsh") is not None
needs_gmsh = pytest.mark.skipif(not HAS_GMSH, reason="gmsh not installed (extra 'mesh')")


def gmsh_param(value, *, id: str | None = None):
    """A parameter that needs gmsh (a Hertz benchmark): skipped with the reason without it."""
    return pytest.param(value, id=id or str(value), marks=needs_gmsh)
