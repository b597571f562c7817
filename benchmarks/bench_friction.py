"""Cost of Coulomb friction against the frictionless run of the same problem (issue 23).

Usage: python -m benchmarks.bench_friction [--quick]

Two problems, each run twice in this process (frictionless, then Coulomb mu = 0.3) with
CN and the default mass:

* ``bar3d --n 8`` without its clamp, dropped obliquely (v0 = (0.2, 0, -0.5)) on a plane
  tilted by 10 degrees about y, 0.05 below its lowest corner: 80 steps of dt = h/2;
* the ``hertz3d`` ball (n = 9, about 36k dofs; ``--quick``: n = 3) in an oblique impact
  (tangential_velocity = velocity), its default dt and T (needs gmsh).

Prints, per problem: the time per step of both runs and their ratio, the set-up + loop
time of both and its ratio, and the friction solver's Newton iterations per contact step.
The issue's bounds: step <= 3x frictionless (bar3d), set-up + loop <= 3x (ball).
"""

from __future__ import annotations

import importlib.util
import math
import sys
import time

import numpy as np


def oblique_bar(friction: str | None):
    from signorini.contact.obstacles import PlaneObstacle
    from signorini.dynamics.model.problem import Problem
    from signorini.fem.material import IsotropicElastic
    from signorini.fem.mesh import box

    a = math.radians(10.0)
    return Problem(
        mesh=box(8, 8, 80, 0.1, 0.1, 1.0),
        material=IsotropicElastic(0.25, 0.5, 1.0),
        contact_tag="zmin",
        obstacle=PlaneObstacle([0.0, 0.0, -0.05], [math.sin(a), 0.0, math.cos(a)]),
        v0=[0.2, 0.0, -0.5],
        friction=friction,
        name="bar3d-oblique",
    )


def timed(problem, dt: float, T: float) -> dict:
    from signorini.dynamics.stepping.simulate import simulate

    t0 = time.perf_counter()
    H = simulate(problem, "cn", dt, T)
    total = time.perf_counter() - t0
    assert H.status == "finished", H.message
    contact_steps = max(int((H.active > 0).sum()), 1)
    return {
        "step": H.meta["step_seconds"],
        "total": total,
        "newton_per_contact_step": H.counters.get("friction_iterations", 0) / contact_steps,
        "fallbacks": H.counters.get("friction_fallbacks", 0),
        "dofs": H.meta["dofs"],
        "contact_nodes": H.meta["contact_nodes"],
        "contact_steps": contact_steps,
        "slip_fraction": float(np.mean(H.friction_counts()[1][H.active > 0] / np.maximum(H.active[H.active > 0], 1))),
    }


def compare(label: str, make, dt: float, T: float) -> dict:
    free = timed(make(None), dt, T)
    fric = timed(make("coulomb:0.3"), dt, T)
    out = {
        "problem": label,
        "dofs": free["dofs"],
        "contact_nodes": free["contact_nodes"],
        "step_frictionless_ms": 1e3 * free["step"],
        "step_coulomb_ms": 1e3 * fric["step"],
        "step_ratio": fric["step"] / free["step"],
        "total_frictionless_s": free["total"],
        "total_coulomb_s": fric["total"],
        "total_ratio": fric["total"] / free["total"],
        "newton_per_contact_step": fric["newton_per_contact_step"],
        "friction_fallbacks": fric["fallbacks"],
        "slip_fraction": fric["slip_fraction"],
    }
    print(
        f"{label}: {out['dofs']} dofs, {out['contact_nodes']} contact nodes; step {out['step_frictionless_ms']:.3g} ms "
        f"-> {out['step_coulomb_ms']:.3g} ms with Coulomb ({out['step_ratio']:.2f}x); set-up + loop "
        f"{out['total_frictionless_s']:.3g} s -> {out['total_coulomb_s']:.3g} s ({out['total_ratio']:.2f}x); "
        f"{out['newton_per_contact_step']:.2f} Newton iterations per contact step, {out['friction_fallbacks']} "
        f"fallbacks, {100 * out['slip_fraction']:.0f}% of the contact nodes sliding",
        flush=True,
    )
    return out


def friction_markdown(rows: list[dict]) -> list[str]:
    """The table of :func:`friction_rows` for bench.md."""
    md = ["", "## Coulomb friction (mu = 0.3) against frictionless, CN, default mass", "",
          "| problem | dofs | contact nodes | step ms | Coulomb step ms | ratio | set-up + loop ratio | Newton it. |",
          "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in rows:
        md.append(
            f"| {r['problem']} | {r['dofs']} | {r['contact_nodes']} | {r['step_frictionless_ms']:.3g} | "
            f"{r['step_coulomb_ms']:.3g} | {r['step_ratio']:.2f}x | {r['total_ratio']:.2f}x | "
            f"{r['newton_per_contact_step']:.2f} |"
        )
    return md


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    friction_rows("--quick" in argv)
    return 0


def friction_rows(quick: bool = False) -> list[dict]:
    """Both problems of the module docstring (the ball at n = 3 with ``quick``), printed as they run."""
    rows = [compare("bar3d n=8 oblique", oblique_bar, 0.1 / 8 / 2, 80 * 0.1 / 8 / 2)]
    if importlib.util.find_spec("gmsh") is not None:
        from signorini.dynamics.model.problem import with_friction
        from signorini.studies.benchmarks import get_benchmark

        b = get_benchmark("hertz3d")
        n = 3 if quick else 9
        params = {"tangential_velocity": b.params()["velocity"]}
        dt, T = b.run_times(n, params)
        ball = b.problem(n, params)
        rows.append(compare(f"hertz3d n={n} oblique", lambda f: with_friction(ball, f or "frictionless"), dt, T))
    else:
        print('gmsh not installed (pip install ".[mesh]"): the ball is skipped', flush=True)
    return rows


if __name__ == "__main__":
    sys.exit(main())
