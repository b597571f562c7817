"""Lazy vs full condensation of the contact problem (set-up, steps, columns, peak memory).

    python benchmarks/bench_contact.py [--n 8 16] [--backend pardiso] [--steps 32]

Cases: ``bar3d`` (flat bottom face: every contact node touches) and ``ball`` (the same
bar dropped on a ball of radius 0.05 touching the middle of its bottom face: a contact
zone that spreads from a point and never reaches the corners, as in a Hertz impact).
The bar starts at gap 0.01 (first contact at t = 0.02) so that a few steps cover the
impact.  Each run is a fresh process (peak resident memory of that run alone).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import resource
import subprocess
import sys
import time


def one(case: str, n: int, backend: str, condensation: str, steps: int) -> dict:

    from signorini.contact.obstacles import SphereObstacle
    from signorini.dynamics.stepping.simulate import simulate
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark("bar3d")
    over = {"gap": 0.01}
    p = b.problem(n, over)
    if case == "ball":
        p = dataclasses.replace(p, obstacle=SphereObstacle([0.05, 0.05, -0.05], 0.05))
    dt = b.h(n, over) / 2
    t0 = time.perf_counter()
    H = simulate(p, "cn", dt, steps * dt, solver_options={"backend": backend, "condensation": condensation})
    total = time.perf_counter() - t0
    m = H.meta
    return {
        "case": case,
        "n": n,
        "dofs": m.get("free_dofs", m.get("dofs")),
        "nc": int(H.lam.shape[1]),
        "touched": int((H.lam != 0).any(axis=0).sum()),
        "condensation": condensation,
        "columns": H.counters["delassus_columns"],
        "setup_s": m["setup_seconds"],
        "factor_s": m.get("factorization_seconds", 0.0),
        "columns_s": m.get("condensation_seconds", 0.0),
        "step_ms": 1e3 * m["step_seconds"],
        "total_s": total,
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "lam": H.lam.tolist(),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, nargs="+", default=[8])
    ap.add_argument("--backend", default="superlu")
    ap.add_argument("--steps", type=int, default=32)
    ap.add_argument("--one", nargs=3, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    import numpy as np

    if a.one:
        print(json.dumps(one(a.one[0], int(a.one[1]), a.backend, a.one[2], a.steps)))
        return 0
    print("| case | n | dofs | contact nodes | touched | condensation | columns | set-up [s] | "
          "columns [s] | step [ms] | total [s] | peak [MB] | same lambda (1e-10) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for n in a.n:
        for case in ("bar3d", "ball"):
            rows = []
            for cond in ("full", "lazy"):
                cmd = [sys.executable, __file__, "--one", case, str(n), cond, "--backend", a.backend]
                out = subprocess.run(cmd + ["--steps", str(a.steps)], capture_output=True, text=True, check=True)
                rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
            full, lazy = (np.asarray(r["lam"]) for r in rows)
            same = np.abs(full - lazy).max() <= 1e-10 * np.abs(full).max()  # the whole history
            for r in rows:
                print(
                    f"| {r['case']} | {r['n']} | {r['dofs']} | {r['nc']} | {r['touched']} | {r['condensation']} | "
                    f"{r['columns']} | {r['setup_s']:.2f} | {r['columns_s']:.2f} | {r['step_ms']:.1f} | "
                    f"{r['total_s']:.2f} | {r['peak_mb']:.0f} | {same} |"
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
