"""Checkpoints: the cost of writing one, of a run with ``--checkpoint-every 10``, and of a
resume's set-up and first step, as ratios measured in one run.

    python -m benchmarks.bench_checkpoint [--n 16] [--steps 20]

bar3d at level n, CN, the default mass and backend.  Printed: the median step, the write
of a checkpoint of the last level (best of 3) and its ratio to the step; the loop with a
checkpoint every 10 steps against the loop without (same run, same steps, alternated twice
in one process, the best of each); a resume's set-up against the fresh
set-up, and its first step (which solves the Delassus columns of the log again).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np


def measure(n: int, steps: int) -> dict:
    from signorini.dynamics.stepping.run_options import CheckpointPolicy
    from signorini.dynamics.stepping.simulate import Stepper
    from signorini.studies.benchmarks import get_benchmark

    bench = get_benchmark("bar3d")
    problem = bench.problem(n, {})
    dt, _ = bench.run_times(n, {})
    where = Path(tempfile.mkdtemp(prefix="bench-checkpoint-"))
    out: dict = {"n": n, "steps": steps}
    loops: dict[int, float] = {}
    for every in (0, 10, 0, 10):  # alternated, the best of two each: the first run warms the process
        t0 = time.perf_counter()
        s = Stepper(problem, "cn", (dt, steps * dt), {"checkpoint": CheckpointPolicy(where / f"c{every}.h5", every)})
        setup = time.perf_counter() - t0
        times = []
        t_loop = time.perf_counter()
        while s.status == "running":
            t1 = time.perf_counter()
            s.step()
            times.append(time.perf_counter() - t1)
        loops[every] = min(loops.get(every, np.inf), time.perf_counter() - t_loop)
        if every == 0 and "setup_s" not in out:
            out.update(dofs=int(s.run.ctx.disc.space.n_dofs), setup_s=setup, median_step_s=float(np.median(times)))
            writes = []
            for _ in range(3):
                t1 = time.perf_counter()
                s.save_checkpoint(where / "c.h5")
                writes.append(time.perf_counter() - t1)
            out["checkpoint_s"] = min(writes)
            out["checkpoint_MB"] = (where / "c.h5").stat().st_size / 2**20
        s.finish()
    out["loop_every10_over_none"] = loops[10] / loops[0]
    t0 = time.perf_counter()
    r = Stepper.resume(where / "c.h5", problem, "cn", (dt, (steps + 2) * dt))
    out["resume_setup_s"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    r.step()
    out["resumed_first_step_s"] = time.perf_counter() - t1
    r.finish()
    out["checkpoint_over_step"] = out["checkpoint_s"] / out["median_step_s"]
    out["resume_setup_over_fresh"] = out["resume_setup_s"] / out["setup_s"]
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=16)
    p.add_argument("--steps", type=int, default=20)
    args = p.parse_args(argv)
    r = measure(args.n, args.steps)
    print(json.dumps(r, indent=1))
    print(f"bar3d n = {r['n']} ({r['dofs']:,} dofs): a checkpoint costs {r['checkpoint_over_step']:.2f} steps "
          f"({r['checkpoint_MB']:.1f} MB); --checkpoint-every 10: loop x{r['loop_every10_over_none']:.3f}; resume "
          f"set-up {r['resume_setup_over_fresh']:.2f} x the fresh set-up")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
