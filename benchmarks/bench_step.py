"""bar3d, CN, seed mass: setup time and per-step time vs one bare solve with the same factor.

Usage: python benchmarks/bench_step.py [n ...]   (default 4 8; 16 needs ~100 s and >10 GB with SuperLU)
"""

import sys
import time

import numpy as np

from signorini.contact.solver import ContactStepper
from signorini.dynamics.simulate import simulate
from signorini.studies.benchmarks import get_benchmark


def main(sizes):
    b = get_benchmark("bar3d")
    print(f"{'n':>3} {'dofs':>7} {'setup s':>8} {'step ms':>8} {'solve ms':>9} {'ratio':>6}")
    for n in sizes:
        p = b.problem(n)
        dt = b.h(n) / 2
        H = simulate(p, "cn", dt, 200 * dt, mass="seed")
        # bare forward+backward solve with an identical factor, measured in the same run
        from signorini.dynamics.problem import discretize

        d = discretize(p, "seed")
        st = ContactStepper((4 / dt**2 * d.M + d.S).tocsr(), d.B, d.contact.gaps)
        rhs = np.random.default_rng(0).normal(size=d.M.shape[0])
        reps = 50
        t0 = time.perf_counter()
        for _ in range(reps):
            st.factor.solve(rhs)
        solve = (time.perf_counter() - t0) / reps
        step = H.meta["step_seconds"]
        print(
            f"{n:>3} {H.meta['dofs']:>7} {H.meta['setup_seconds']:>8.2f} {1e3 * step:>8.2f} "
            f"{1e3 * solve:>9.2f} {step / solve:>6.2f}   impacts {H.impacts}, "
            f"factorization {H.meta['factorization_seconds']:.2f}s, assembly {H.meta['assembly_seconds']:.2f}s"
        )


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [4, 8])
