"""Benchmarks: ``python -m benchmarks`` (the suite) and one module per question (``bench_*``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any


def median_step(stepper: Any, stop: Callable[[Any, int], bool] = lambda s, k: False) -> float:
    """Step ``stepper`` until it ends or ``stop(stepper, steps taken)``; the median step time [s]."""
    import numpy as np

    times = []
    while stepper.status == "running" and not stop(stepper, len(times)):
        t0 = time.perf_counter()
        stepper.step()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def per_call(f: Callable[[], Any], calls: int, warm: bool = False) -> float:
    """The mean time of ``calls`` calls of ``f`` [s] (after one untimed call when ``warm``)."""
    if warm:
        f()
    t0 = time.perf_counter()
    for _ in range(calls):
        f()
    return (time.perf_counter() - t0) / calls
