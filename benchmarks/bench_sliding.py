"""Issue 38's costs, as ratios measured in one run.

    python -m benchmarks.bench_sliding [--n 8] [--steps 40]

1. What every level now adds to a step: the reactions of the Dirichlet tags
   (:mod:`signorini.dynamics.observe.reactions`) and the check of the energy identity, each timed
   over 200 calls at a level of bar2d at level n (CN, the default mass), against the median
   step of the same run.
2. A 3D block sliding at 1 m/s across the facets of a clamped block (Coulomb 0.3, gravity,
   backward Euler, the default mass): the loop (Delassus columns computed inside it
   included) with ``pairing=small-sliding`` against ``pairing=frozen``, the same steps in
   one process, alternated twice, the best of each; the re-paired rows and the columns
   solved, the friction solver's Newton iterations and the columns' time inside the loop; on
   ``--steps`` (40) and on ``--long`` (300) steps: a re-paired row's column is updated from
   cached dof columns (``DelassusColumns.replace_rows``), whose solves are front-loaded, so the
   long slide shows the steady cost.  Issue 38 asks this ratio down to 1.3 (not reached:
   docs/performance.md).
3. Rayleigh damping's cost: the median step of bar2d at level n (CN, the default mass) with
   ``damping = {alpha: 0.1, beta: 1e-3}`` against the undamped one, alternated twice in one
   process, the best of each (two more products with M and S per step, none when undamped).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from benchmarks import median_step, per_call


def level_costs(n: int, steps: int) -> dict:
    from signorini.dynamics.stepping.simulate import Stepper
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark("bar2d")
    p = b.problem(n, {})
    dt, _ = b.run_times(n, {})
    s = Stepper(p, "cn", (dt, steps * dt))
    step = median_step(s)

    run, state = s.run, s.state
    reactions = per_call(lambda: s.recorder.reactions(run.ctx, state), 200)
    check = per_call(lambda: s.energies._check(run, s.n, check=False), 200)
    s.finish()
    return {"case": f"bar2d n = {n}", "dofs": int(run.ctx.disc.space.n_dofs), "step_s": step,
            "reactions_over_step": reactions / step, "energy_check_over_step": check / step}  # fmt: skip


def damping_cost(n: int, steps: int) -> dict:
    """The damped step against the undamped one (module docstring, item 3)."""
    import dataclasses

    from signorini.dynamics.stepping.simulate import Stepper
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark("bar2d")
    p = b.problem(n, {})
    dt, _ = b.run_times(n, {})
    best: dict[str, float] = {}
    for damping in (None, {"alpha": 0.1, "beta": 1e-3}) * 2:
        s = Stepper(dataclasses.replace(p, damping=damping), "cn", (dt, steps * dt))
        key = "damped" if damping else "undamped"
        best[key] = min(best.get(key, np.inf), median_step(s))
        s.finish()
    return {"case": f"bar2d n = {n}", "steps": steps, "damped_step_s": best["damped"],
            "undamped_step_s": best["undamped"], "damped_over_undamped": best["damped"] / best["undamped"]}  # fmt: skip


def sliding_block():
    from signorini.contact.pairs import ContactPair
    from signorini.dynamics.model.problem import Problem, RegionInitial
    from signorini.fem.material import IsotropicElastic
    from signorini.fem.mesh import box, join
    from signorini.fem.space import Dirichlet

    a = box(40, 8, 2, 0.5, 0.1, 0.05)
    b = box(9, 7, 3, 0.1, 0.08, 0.05)  # non-matching: its facets cross the lower block's as it slides
    b.points = b.points + [0.05, 0.01, 0.05]
    m = join({"lower": a, "upper": b})
    return Problem(m, IsotropicElastic.from_young(5e6, 0.3, 2000.0), None, None, dirichlet=[Dirichlet("lower_zmin")],
                   pairs=[ContactPair("upper_zmin", "lower_zmax", friction="coulomb:0.3")],
                   initial_regions=[RegionInitial("upper", velocity=[1.0, 0.0, 0.0])],
                   gravity=[0.0, 0.0, -9.81])  # fmt: skip


def sliding(steps: int) -> dict:
    """The loops of one case with both pairings (module docstring, item 2)."""
    from signorini.dynamics.stepping.simulate import simulate

    p, dt = sliding_block(), 1e-3
    loops: dict[str, float] = {}
    runs = {}
    for pairing in ("frozen", "small-sliding", "frozen", "small-sliding"):
        H = simulate(p, "be", dt, steps * dt, solver_options={"pairing": pairing})
        loops[pairing] = min(loops.get(pairing, np.inf), float(H.meta["loop_seconds"]))
        runs[pairing] = H
    s = runs["small-sliding"]
    return {"case": "3D block sliding at 1 m/s", "dofs": int(s.meta["dofs"]), "steps": steps,
            "repaired_rows": int(s.counters["pair_rows_repaired"]),
            "columns_small_sliding": int(s.counters["delassus_columns"]),
            "columns_frozen": int(runs["frozen"].counters["delassus_columns"]),
            "newton_small_sliding": int(s.counters["friction_iterations"]),
            "newton_frozen": int(runs["frozen"].counters["friction_iterations"]),
            "columns_in_loop_seconds": float(s.meta["condensation_in_loop_seconds"]),
            "loop_small_sliding_s": loops["small-sliding"], "loop_frozen_s": loops["frozen"],
            "loop_small_sliding_over_frozen": loops["small-sliding"] / loops["frozen"]}  # fmt: skip


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--long", type=int, default=300, help="steps of the long slide (0: none)")
    args = ap.parse_args(argv)
    c = level_costs(args.n, 4 * args.steps)
    slides = [sliding(k) for k in (args.steps, args.long) if k]
    d = damping_cost(args.n, 4 * args.steps)
    print(json.dumps({"level": c, "sliding": slides, "damping": d}, indent=1))
    print(f"{d['case']}, {d['steps']} steps: a damped step is x{d['damped_over_undamped']:.3f} of an undamped one")
    print(f"{c['case']} ({c['dofs']} dofs): reactions {100 * c['reactions_over_step']:.1f}% and energy check "
          f"{100 * c['energy_check_over_step']:.2f}% of a step")  # fmt: skip
    for s in slides:
        print(f"{s['case']} ({s['dofs']} dofs), {s['steps']} steps, {s['repaired_rows']} rows re-paired: loop "
              f"x{s['loop_small_sliding_over_frozen']:.2f} of the frozen pairing's ({s['columns_small_sliding']} "
              f"against {s['columns_frozen']} Delassus columns, {s['newton_small_sliding']} against "
              f"{s['newton_frozen']} Newton iterations)")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
