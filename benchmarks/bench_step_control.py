"""Issue 40's figures, as ratios measured in one run: the energy control against fixed steps.

    python -m benchmarks.bench_step_control [--hertz-n 3] [--bar3d-n 8] [--no-hertz]

1. The steel block of examples/steel_block_drop.toml (2D, 462 dofs, CN, the default mass),
   dt = 5 us against a 3.3 us contact: the control (dt largest) against a fixed run at the
   smallest step the control used: levels, loop time, the largest energy drift, the rebound
   momentum.
2. A Hertz ball (hertz3d, gmsh) bouncing three times under a gravity that brings it back after
   ``--flight`` (10) contact durations t_c: the control with dt = t_c / 2 and every default (the tolerance
   and dt_min from the mesh) against a fixed run at the smallest step it used: levels and loop time, and per
   bounce the contact duration and the peak force (relative differences), the energy between bounces
   against E0.
3. The control's own cost per step (the energy indicator, the saved warm starts): bar3d at level n (CN)
   through its contact with a control that never rejects, against the same steps fixed.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

ROOT = Path(__file__).parents[1]


def _episodes(H) -> list[tuple[int, int]]:
    """(first, last) level of each contact episode (a total contact force, lambda_sum < 0)."""
    on = np.asarray(H.lambda_sum) < 0
    edges = np.flatnonzero(np.diff(on.astype(int)))
    starts = [int(e) + 1 for e in edges if not on[e]]
    ends = [int(e) for e in edges if on[e]]
    if on[-1]:
        ends.append(on.size - 1)
    return list(zip(starts, ends, strict=False))


def steel_block() -> dict:
    from signorini import simulate
    from signorini.io.config import load_case

    p = load_case(ROOT / "examples" / "steel_block_drop.toml").problem
    A = simulate(p, "cn", 5e-6, 5e-5, control="energy")
    h = A.meta["time_control"]["dt_smallest_used"]
    F = simulate(p, "cn", h, 5e-5)
    pa, pf = A.columns()["momentum_y"][-1], F.columns()["momentum_y"][-1]
    return {"case": "steel block 2D, dt = 5 us", "levels_control": int(A.t.size - 1), "levels_fixed": int(F.t.size - 1),
            "fixed_dt": h, "steps_ratio": (A.t.size - 1) / (F.t.size - 1),
            "loop_ratio": A.meta["loop_seconds"] / F.meta["loop_seconds"],
            "energy_drift_control": float(np.max(np.abs(A.energy / A.energy[0] - 1))),
            "momentum_rel_diff": float(abs(pa - pf) / abs(pf)), "rejected": A.meta["time_control"]["steps_rejected"],
            "factorizations": A.meta["time_control"]["factorizations"]}  # fmt: skip


def hertz_bounces(n: int, flight: float = 10.0) -> dict:
    from signorini import simulate
    from signorini.studies.benchmarks import get_benchmark
    from signorini.studies.hertz import _prediction

    b = get_benchmark("hertz3d")
    params = b.params({})
    p = b.problem(n, {})
    tc = _prediction(3, params).duration
    v = params["velocity"]
    g = 2 * v / (flight * tc)  # a flight of 2 v / g = flight x t_c between bounces (a steel ball's: far longer)
    p = dataclasses.replace(p, gravity=[0.0, 0.0, -g])
    dt = tc / 2
    T = round(3.2 * (flight + 1) * tc / dt) * dt  # three bounces and their flights
    A = simulate(p, "cn", dt, T, control="energy")  # every default: the tolerance and dt_min from the mesh
    h = A.meta["time_control"]["dt_smallest_used"]
    F = simulate(p, "cn", h, T)
    ea, ef = _episodes(A), _episodes(F)
    rows = []
    for (a0, a1), (f0, f1) in zip(ea, ef, strict=False):
        if a1 + 1 >= A.t.size or f1 + 1 >= F.t.size:  # an episode still on at T: not compared
            continue
        # the duration between the mid-points of the levels around the first and the last contact
        dur_a = 0.5 * (A.t[a1] + A.t[a1 + 1]) - 0.5 * (A.t[a0 - 1] + A.t[a0])
        dur_f = 0.5 * (F.t[f1] + F.t[f1 + 1]) - 0.5 * (F.t[f0 - 1] + F.t[f0])
        peak_a, peak_f = -A.lambda_sum[a0 : a1 + 1].min(), -F.lambda_sum[f0 : f1 + 1].min()
        rows.append({"duration_rel_diff": float(abs(dur_a - dur_f) / dur_f),
                     "peak_rel_diff": float(abs(peak_a - peak_f) / peak_f)})  # fmt: skip
    free = [i for i in range(A.t.size) if not np.asarray(A.lambda_sum)[i] < 0]
    tc_ = A.meta["time_control"]
    return {"case": f"hertz3d n = {n} bouncing ({int(A.meta['dofs'])} dofs), flights of {flight:g} t_c, dt = t_c / 2, "
                    f"tolerance {tc_['tolerance']:.3g} from the mesh, fixed at the smallest step used "
                    f"(dt / {dt / h:.0f})",
            "rejected": tc_["steps_rejected"], "factorizations": tc_["factorizations"],
            "unresolved": tc_["unresolved_steps"],
            "bounces_control": len(ea), "bounces_fixed": len(ef), "levels_control": int(A.t.size - 1),
            "levels_fixed": int(F.t.size - 1), "steps_ratio": (A.t.size - 1) / (F.t.size - 1),
            "loop_ratio": A.meta["loop_seconds"] / F.meta["loop_seconds"], "bounces": rows,
            "energy_between_bounces": float(np.max(np.abs(A.energy[free] / A.energy[0] - 1)))}  # fmt: skip


def overhead(n: int) -> dict:
    """The control's own cost per step (its indicator with the motion's error estimate, the solvers' saved warm
    starts, its growth bookkeeping): bar3d at level n (CN) stepped through its contact with the control set to never
    reject (tolerance 1) against the same steps fixed, the median of 60 levels from level 30, two alternated rounds,
    the best of each.  (Calling the indicator alone on one level, as before, measured its products without the
    state's cache a real step shares with the energy recorder: 110% of a step, not what a run pays.)"""
    import time

    from signorini.dynamics.stepping.stepper import Stepper
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark("bar3d")
    p = b.problem(n, {})
    dt, T = b.run_times(n, {})
    best: dict[str, float] = {}
    for _ in range(2):
        for name, control in (("fixed", "fixed"), ("energy", {"control": "energy", "tolerance": 1.0})):
            s = Stepper(p, "cn", (dt, T), {"control": control})
            for _ in range(30):
                s.step()
            times = []
            for _ in range(60):
                t0 = time.perf_counter()
                s.step()
                times.append(time.perf_counter() - t0)
            in_contact = bool(np.any(s.state.lam))
            dofs = int(s.run.ctx.disc.space.n_dofs)
            s.finish()
            best[name] = min(best.get(name, np.inf), float(np.median(times)))
    return {"case": f"bar3d n = {n}", "dofs": dofs, "step_s": best["fixed"], "in_contact": in_contact,
            "control_over_step": best["energy"] / best["fixed"] - 1.0}  # fmt: skip


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hertz-n", type=int, default=3)
    ap.add_argument("--bar3d-n", type=int, default=8)
    ap.add_argument("--no-hertz", action="store_true", help="skip the gmsh ball")
    ap.add_argument(
        "--flight", type=float, default=10.0, help="the ball's flight between bounces, in contact durations"
    )
    args = ap.parse_args(argv)
    out = {"steel": steel_block()}
    if not args.no_hertz:
        import importlib.util

        gmsh = importlib.util.find_spec("gmsh") is not None
        out["hertz"] = hertz_bounces(args.hertz_n, args.flight) if gmsh else "skipped: gmsh is not installed (.[mesh])"
    out["overhead"] = overhead(args.bar3d_n)
    print(json.dumps(out, indent=1, default=str))
    s = out["steel"]
    print(f"{s['case']}: the control takes {s['steps_ratio']:.3f} of the levels and {s['loop_ratio']:.3f} of the loop "
          f"time of a fixed run at its smallest step; energy drift {s['energy_drift_control']:.2e}, rebound momentum "
          f"{s['momentum_rel_diff']:.1e} from the fixed run's")  # fmt: skip
    h = out.get("hertz")
    if isinstance(h, dict):
        worst_d = max((r["duration_rel_diff"] for r in h["bounces"]), default=float("nan"))
        worst_p = max((r["peak_rel_diff"] for r in h["bounces"]), default=float("nan"))
        print(f"{h['case']}: {h['bounces_control']} bounces ({h['bounces_fixed']} fixed), "
              f"{h['steps_ratio']:.3f} of the levels, {h['loop_ratio']:.3f} of the loop; duration within "
              f"{worst_d:.1e}, peak force within {worst_p:.1e}; energy between bounces within "
              f"{h['energy_between_bounces']:.1e} of E0")  # fmt: skip
    o = out["overhead"]
    print(
        f"{o['case']} ({o['dofs']} dofs, a level in contact): a step under a control that never rejects costs "
        f"{100 * o['control_over_step']:.1f}% more than the same step fixed"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
