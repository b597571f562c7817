"""The ``reproducible`` solver option: Pardiso in MKL's conditional numerical reproducibility mode gives
the same bits from one factorization to the next (its parallel factorization otherwise may differ at
round-off run to run: docs/performance.md); the other backends ignore it (they always are)."""

import numpy as np
import pytest

from signorini.dynamics.model.problem import discretize
from signorini.errors import InputError
from signorini.linalg import factorize, has_pardiso
from signorini.linalg.base import solver_options
from signorini.studies.benchmarks import get_benchmark

needs_pardiso = pytest.mark.skipif(not has_pardiso(), reason="pypardiso not installed (extra 'pardiso')")


@pytest.fixture(scope="module")
def K():
    d = discretize(get_benchmark("bar3d").problem(8, {}), "standard")
    return (1e4 * d.M + d.S).tocsr()


@needs_pardiso
def test_reproducible_pardiso_gives_the_same_bits(K):
    b = np.sin(np.arange(K.shape[0], dtype=float))
    x = [factorize(K, "pardiso", reproducible=True).solve(b) for _ in range(3)]
    assert all(np.array_equal(x[0], y) for y in x[1:])
    reference = factorize(K, "superlu").solve(b)
    assert np.abs(x[0] - reference).max() <= 1e-10 * np.abs(reference).max()


def test_the_option_is_a_boolean_and_the_other_backends_ignore_it(K):
    assert solver_options({"reproducible": "true"})["reproducible"] is True
    with pytest.raises(InputError, match="reproducible"):
        solver_options({"reproducible": "maybe"})
    b = np.ones(K.shape[0])
    assert np.array_equal(factorize(K, "superlu", reproducible=True).solve(b), factorize(K, "superlu").solve(b))
