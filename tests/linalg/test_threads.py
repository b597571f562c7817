"""linalg/threads.py: the BLAS pools are limited inside the time loop, and only there."""

import numpy as np
import pytest
from threadpoolctl import threadpool_info

from signorini.dynamics.observe.observers import Observer
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.linalg.threads import blas_threads
from signorini.studies.benchmarks import get_benchmark


def openblas_threads() -> list[int]:
    np.ones(4) @ np.ones(4)  # make sure numpy's BLAS is loaded
    return [d["num_threads"] for d in threadpool_info() if d["internal_api"] == "openblas"]


def test_blas_threads_limits_and_restores():
    before = openblas_threads()
    assert before, "numpy's wheel ships OpenBLAS"
    with blas_threads(1):
        assert openblas_threads() == [1] * len(before)
    assert openblas_threads() == before
    with blas_threads(0):  # 0: leave the libraries alone
        assert openblas_threads() == before


class ThreadSpy(Observer):
    """Reads the OpenBLAS thread counts at every step."""

    def __init__(self):
        self.seen = []

    def record(self, run, n, state):
        self.seen.append(openblas_threads())


@pytest.mark.parametrize("threads", [0, 1])
def test_simulate_limits_blas_inside_the_loop_only(threads):
    before = openblas_threads()
    spy = ThreadSpy()
    problem = get_benchmark("bar1d").problem(4)
    H = simulate(problem, "cn", 0.125, 0.5, observers=[spy], solver_options={"loop_blas_threads": threads})
    assert H.status == "finished" and len(spy.seen) == 4
    expected = [1] * len(before) if threads == 1 else before
    assert all(s == expected for s in spy.seen)
    assert openblas_threads() == before
    assert H.meta["solver_options"]["loop_blas_threads"] == threads


def test_loop_blas_threads_rejects_negative():
    with pytest.raises(InputError, match="loop_blas_threads"):
        simulate(get_benchmark("bar1d").problem(4), "cn", 0.125, 0.5, solver_options={"loop_blas_threads": -1})
