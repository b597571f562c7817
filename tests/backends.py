"""The direct backends the tests run on: each optional one only when its package is installed."""

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
