"""Timings that used to be assertions in the tests (issue 31, item 5), printed, not asserted.

Usage: python benchmarks/bench_moved_timings.py

The tests now assert counts instead (tests/io/test_expressions.py: tree nodes compiled before
a rejection, vectorized operations per evaluation; tests/io/test_fuzz_cases.py: the sleep the
time limit interrupts).  The times they bounded, on this machine:

- the rejection of each expensive or overflowing expression (the test bounded it by 1 s);
- one evaluation of the largest allowed expression over 1e5 points (bounded by 2 s);
- the fuzz harness's time limit (0.2 s) interrupting a 30 s hang (bounded by 5 s).
"""

import signal
import time

import numpy as np

REJECTED = [
    "9**9**9**9",
    "10**400",
    "x**x",
    "2**(1+1)",
    "-" * 150 + "x",
    "(" * 300 + "x" + ")" * 300,
    "x" * 3000,
    "1e999",
]


def _best(f, repeat: int = 5) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t0)
    return best


def rejections() -> list[tuple[str, float]]:
    from signorini.errors import InputError
    from signorini.io.expressions import MAX_NODES, Expression

    def reject(text):
        try:
            Expression("k", text)
        except InputError:
            return
        raise AssertionError(f"{text[:40]!r} was accepted")

    texts = [*REJECTED, "+".join(["x"] * (MAX_NODES + 1))]
    return [(t, _best(lambda t=t: reject(t))) for t in texts]


def evaluation() -> float:
    from signorini.io.expressions import MAX_NODES, Expression

    e = Expression("k", "+".join(["sin(x)*cos(y)"] * (MAX_NODES // 10)))
    pts = np.random.default_rng(0).random((100_000, 2))
    return _best(lambda: e(pts))


class _Alarm(Exception):
    pass


def interrupted_hang(limit: float = 0.2) -> float:
    def alarm(signum, frame):
        raise _Alarm

    old = signal.signal(signal.SIGALRM, alarm)
    t0 = time.perf_counter()
    try:
        signal.setitimer(signal.ITIMER_REAL, limit)
        try:
            time.sleep(30)
        except _Alarm:
            pass
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
    finally:
        signal.signal(signal.SIGALRM, old)
    return time.perf_counter() - t0


def main() -> int:
    print("expression rejected (best of 5)")
    for text, s in rejections():
        shown = text if len(text) <= 24 else f"{text[:20]}... ({len(text)} chars)"
        print(f"  {shown:<40} {s * 1e6:10.1f} us")
    print(f"largest allowed expression over 1e5 points (best of 5): {evaluation() * 1e3:.1f} ms")
    print(f"a 30 s hang interrupted by a 0.2 s time limit after {interrupted_hang():.3f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
