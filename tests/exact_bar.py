"""Runs of a scheme on the exact 1D bar at several levels, shared by the scheme tests.

bar1d with non-default parameters (L = 2, E = 4, gap = 0.3), dt = h/2 and T the nearest
multiple of dt to 3 (one period of the released bar); errors against the exact solution.
"""

from signorini.dynamics.stepping.simulate import simulate
from signorini.studies.benchmarks import get_benchmark
from signorini.studies.study import errors_1d

PARAMS = {"L": 2.0, "E": 4.0, "gap": 0.3}


def exact_bar_runs(scheme: str, mass: str, levels, options: dict | None = None, T: float = 3.0):
    """[(n, h, History, errors)] for every level n (errors of ``errors_1d``)."""
    b = get_benchmark("bar1d")
    out = []
    for n in levels:
        p = b.problem(n, PARAMS)
        h = b.h(n, PARAMS)
        dt = h / 2
        Tn = dt * round(T / dt)
        H = simulate(p, scheme, dt, Tn, mass=mass, snapshot_every=1, scheme_options=options)
        out.append((n, h, H, errors_1d(H, p, b.exact(b.params(PARAMS), Tn))))
    return out
