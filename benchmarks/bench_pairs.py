"""Contact pairs: the pair set-up (search, projection, B) and the step of two balls against
one ball on a rigid plane, as ratios measured in one run.

    python -m benchmarks.bench_pairs [--side 100] [--n 4] [--far 0.1] [--steps 40] [--repeat 3]

1. Set-up: the nodes of a (side + 1)^2 face of one box against the side^2 quadrilateral
   facets of another (10^4 against 10^4 with side = 100, non-matching: the upper face has
   side - 1 cells), median of ``--repeat`` calls of :func:`signorini.contact.pairs.pair_rows`.
2. Step: ``collision3d`` (two balls of radius 1 through a pair) against ``hertz3d`` (one ball
   on a rigid plane) at the same level n, so that the contact candidates are the same cap
   (slave cap nodes vs cap nodes: printed); the far mesh size of the two balls is 2^(1/3)
   times the one ball's so that the two balls hold about the dofs of the one.  Time per
   step of CN + moment-preserving over ``--steps`` steps through the impact (the default
   backend), each case in a fresh process; the ratio two balls / one ball.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

import numpy as np


def setup_time(side: int, repeat: int) -> dict:
    from signorini.contact.pairs import ContactPair, pair_rows
    from signorini.fem.mesh import box, join

    a = box(side, side, 1, 1.0, 1.0, 0.1)
    b = box(side - 1, side - 1, 1, 1.0, 1.0, 0.1)
    b.points = b.points + [0.0, 0.0, 0.1]
    m = join({"lower": a, "upper": b})
    pair = ContactPair("upper_zmin", "lower_zmax")
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        rows = pair_rows(m, pair, 3 * m.n_nodes)
        times.append(time.perf_counter() - t0)
    return {"slave_nodes": int(m.nodes_of("upper_zmin").size), "master_facets": len(m.facets_of("lower_zmax")),
            "rows": int(rows.nodes.size), "seconds": float(np.median(times))}  # fmt: skip


def step_time(name: str, n: int, far: float, steps: int) -> dict:
    from signorini.dynamics.stepping.simulate import simulate
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark(name)
    over = {"far": far}
    p = b.problem(n, over)
    dt, _ = b.run_times(n, over)
    candidates = p.mesh.nodes_of(p.pairs[0].slave if p.pairs else p.contact_tag).size
    H = simulate(p, "cn", dt, steps * dt)
    return {"case": name, "dofs": int(H.meta["dofs"]), "candidates": int(candidates),
            "step_seconds": float(H.meta["step_seconds"]), "setup_seconds": float(H.meta["setup_seconds"]),
            "backend": H.meta["backend"], "active_max": int(np.max(H.active))}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--side", type=int, default=100)
    ap.add_argument("--n", type=int, default=4)
    ap.add_argument("--far", type=float, default=0.1)
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--one", nargs=4, metavar=("NAME", "N", "FAR", "STEPS"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(step_time(args.one[0], int(args.one[1]), float(args.one[2]), int(args.one[3]))))
        return 0
    s = setup_time(args.side, args.repeat)
    print(f"pair set-up: {s['slave_nodes']} slave nodes against {s['master_facets']} master facets: "
          f"{s['seconds']:.3f} s (median of {args.repeat}; {s['rows']} rows)")  # fmt: skip
    runs = {}
    for name, far in (("hertz3d", args.far), ("collision3d", args.far * 2 ** (1 / 3))):
        out = subprocess.run([sys.executable, "-m", "benchmarks.bench_pairs", "--one", name, str(args.n), str(far),
                              str(args.steps)], capture_output=True, text=True, check=True)  # fmt: skip
        runs[name] = json.loads(out.stdout.strip().splitlines()[-1])
        r = runs[name]
        print(f"{name:12s} n = {args.n}: {r['dofs']} dofs, {r['candidates']} contact candidates (at most "
              f"{r['active_max']} active), set-up {r['setup_seconds']:.2f} s, {1e3 * r['step_seconds']:.1f} ms/step "
              f"({r['backend']})")  # fmt: skip
    ratio = runs["collision3d"]["step_seconds"] / runs["hertz3d"]["step_seconds"]
    print(f"step ratio two balls / one ball: {ratio:.2f} (dofs ratio "
          f"{runs['collision3d']['dofs'] / runs['hertz3d']['dofs']:.2f})")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
