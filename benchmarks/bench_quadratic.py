"""Quadratic cells' cost at equal dofs (issue 54): ``python -m benchmarks.bench_quadratic [--steps N]``.

The paper's 3D bar at 3,075 dofs twice: 4 x 4 x 40 hexahedra (Q1) and 2 x 2 x 20 hexahedron27 (Q2, the same
nodes), Crank-Nicolson, the default mass, the same step (the linear bar's default h / 2) through its impact.
In one process, best of two alternated rounds: the median step, one bare solve with the step's factor, their
ratios, the factor's size and the set-up (assembly, mass, factorization).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from . import median_step


def measure(order: int, n: int, dt: float, steps: int) -> dict:
    from signorini.dynamics.stepping.simulate import Stepper
    from signorini.studies.benchmarks import get_benchmark

    problem = get_benchmark("bar3d").problem(n, {"order": order})
    s = Stepper(problem, "crank-nicolson", (dt, steps * dt))
    step = median_step(s)
    H = s.finish()
    m = H.meta
    return {"order": order, "n": n, "dofs": int(m["dofs"]), "step_s": step, "bare_solve_s": m["bare_solve_seconds"],
            "setup_s": m["setup_seconds"], "factor_bytes": m.get("factor_bytes"), "backend": m.get("backend"),
            "status": H.status}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=80)
    args = ap.parse_args(argv)
    dt = 0.1 / 4 / 2  # the linear bar's default h / 2
    best: dict[int, dict] = {}
    for _ in range(2):
        for order, n in ((1, 4), (2, 2)):
            r = measure(order, n, dt, args.steps)
            if order not in best or r["step_s"] < best[order]["step_s"]:
                best[order] = r
    lin, quad = best[1], best[2]
    out = {"linear": lin, "quadratic": quad, "step_ratio": quad["step_s"] / lin["step_s"],
           "solve_ratio": quad["bare_solve_s"] / lin["bare_solve_s"]}  # fmt: skip
    print(json.dumps(out, indent=1, default=lambda o: float(o) if isinstance(o, np.floating) else str(o)))
    print(f"bar3d at {lin['dofs']} dofs: a Q2 step {1e3 * quad['step_s']:.2f} ms, a Q1 step "
          f"{1e3 * lin['step_s']:.2f} ms (x{out['step_ratio']:.2f}); a bare solve x{out['solve_ratio']:.2f}; "
          f"a step / its bare solve: Q1 x{lin['step_s'] / lin['bare_solve_s']:.1f}, "
          f"Q2 x{quad['step_s'] / quad['bare_solve_s']:.1f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
