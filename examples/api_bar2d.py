"""The README's Python API example: the paper's 2D bar, standard vs seed mass (CN).

The README shows this file verbatim (tests/test_examples.py checks both).
"""

from signorini import get_benchmark, simulate

bar = get_benchmark("bar2d")                      # the paper's 2D bar
problem = bar.problem(n=4, overrides={"gap": 0.2})
h = bar.h(4)
for mass in ("standard", "seed"):
    H = simulate(problem, "crank-nicolson", dt=h / 2, T=4.0, mass=mass)
    print(mass, "E(T)/E(0) =", H.energy[-1] / H.energy[0],
          "min gap =", H.gap.min(), "peak force =", -H.lambda_sum.min())
