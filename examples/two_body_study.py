"""The mass redistribution method measured on two bodies (issue 32, item 7): the tables of
docs/verification.md, "Two bodies: the method measured".

Run from the repository root: ``python3 examples/two_body_study.py`` (6 CPU minutes: 9.5
minutes on 2 cores shared with other jobs; ``--quick``: a small version, the one the tests
run, 13 s).  The ``collision3d`` rows need gmsh (``pip install ".[mesh]"``; ``--no-3d``
skips them); ``ball_on_plate`` reads the committed mesh.

For the mass variants standard, lumped, seed and moment-preserving and the schemes CN,
BE, generalized-alpha (rho_inf = 0.8) and HHT (alpha = 0.1), it prints one markdown table
per problem:

* ``collision1d`` (two free bars, exact): the contact duration, the mean force over the
  middle half of the contact and the final velocities against the closed form
  (``signorini.studies.collision``; errors relative to 2L/c, rho c v / 2 and v);
* ``collision3d`` (two balls): Hertz's duration and peak force
  (``signorini.studies.collision_balls``, relative deviations);
* ``examples/ball_on_plate.toml`` (a ball on a clamped plate, no closed form): the ball's
  restitution (its velocity out / in), the duration and peak of the contact force; and
  with CN, standard and moment-preserving, the same at dt / 10;

and for every run the oscillation index of the total contact force
(``signorini.dynamics.observe.diagnostics.oscillation_index``: 1 for one rise and fall), the energy
drift max |E - E0| / E0 (the scheme's energy) and, for the free bodies, the momentum drift
max |P - P0| / |P0| (``history`` ``momentum``).  Then the convergence in h and dt on
``collision1d``: n = 20, 40, 80 cells per bar with dt = h / (2c), the errors of the mean
force and of the duration per level and the observed rates log2(e_n / e_2n).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from signorini.dynamics.observe.diagnostics import oscillation_index
from signorini.dynamics.stepping.simulate import simulate
from signorini.io.config import load_case
from signorini.studies.benchmarks import get_benchmark
from signorini.studies.collision import CollisionMeasure
from signorini.studies.collision_balls import BallsMeasure

MASSES = ("standard", "lumped", "seed", "moment-preserving")
SCHEMES = {"cn": {}, "be": {}, "generalized-alpha": {"rho_inf": 0.8}, "hht": {"alpha": 0.1}}
LABEL = {"cn": "CN", "be": "BE", "generalized-alpha": "gen-alpha 0.8", "hht": "HHT 0.1"}
BALL_ON_PLATE = Path(__file__).parent / "ball_on_plate.toml"


def _pct(x: float | None, digits: int = 1) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{100 * x:+.{digits}f}%"


def _e(x: float | None) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{x:.1e}"


def drifts(H) -> dict:
    """Oscillation index, energy drift and momentum drift of a run."""
    E = H.energy
    P = H.momentum
    p0 = float(np.linalg.norm(P[0])) if P is not None else 0.0
    return {
        "osc": oscillation_index(H.t, -H.lambda_sum),
        "energy": float(np.max(np.abs(E - E[0])) / abs(E[0])),
        "momentum": float(np.max(np.linalg.norm(P - P[0], axis=1)) / p0) if p0 else None,
        "status": H.status,
    }


def _run(problem, scheme: str, dt: float, T: float, mass: str, observers=()):
    return simulate(problem, scheme, dt, T, mass=mass, scheme_options=SCHEMES[scheme], observers=observers,
                    handle_signals=False)  # fmt: skip


def collision1d(n: int, scheme: str, mass: str) -> dict:
    """Errors against the closed form of the collision of two bars, n cells per bar, dt = h / (2c)."""
    b = get_benchmark("collision1d")
    p = b.params({})
    dt, T = b.times(n, p)
    H = _run(b.build(n, p), scheme, dt, T, mass)
    s = CollisionMeasure(p).summary(H)["collision"]
    ex = s["exact"]
    out = drifts(H)
    if "contact_duration" in s:
        v = ex["final_velocities"][1]
        fm = s["mean_force_middle"]
        # the measured duration counts the levels with a force: exact to a step at best
        out.update(duration=s["contact_duration"] / ex["contact_duration"] - 1,
                   duration_steps=round((s["contact_duration"] - ex["contact_duration"]) / dt),
                   force=fm / ex["contact_force"] - 1 if fm is not None else None,
                   velocity=max(abs(a - b) for a, b in zip(s["final_velocities"], ex["final_velocities"],
                                                           strict=True)) / v)  # fmt: skip
    return out


def collision3d(level: int, scheme: str, mass: str, problem=None) -> dict:
    """Hertz's two-ball duration and peak force, the benchmark's default dt and T at ``level``."""
    b = get_benchmark("collision3d")
    p = b.params({})
    dt, T = b.times(level, p)
    m = BallsMeasure(3, p)
    H = _run(problem if problem is not None else b.build(level, p), scheme, dt, T, mass, m.observers())
    dev = m.summary(H)["hertz"]["relative_deviation"]
    return {**drifts(H), "duration": dev["duration"], "peak": dev["peak_force"]}


def ball_on_plate(scheme: str, mass: str, T: float | None = None, dt: float | None = None) -> dict:
    """examples/ball_on_plate.toml with this scheme and mass (its own dt and T unless given)."""
    case = load_case(BALL_ON_PLATE)
    dt = dt or case.dt
    H = _run(case.problem, scheme, dt, T or case.T, mass)
    out = drifts(H)
    out["momentum"] = None  # the plate is clamped: the momentum is not conserved
    ball = next(b for b in H.meta["bodies"] if b["regions"] == ["ball"])
    out["restitution"] = ball["momentum"][2] / ball["mass"] / 2.0  # the ball comes in at 2 m/s
    f = -H.lambda_sum
    on = np.flatnonzero(f > 0)
    out["duration"] = float((on[-1] - on[0] + 1) * dt) if on.size else 0.0
    out["peak"] = float(f.max(initial=0.0))
    return out


def table(title: str, head: list[str], rows: list[list[str]]) -> str:
    lines = [f"**{title}**", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def rate(e1: float | None, e2: float | None) -> str:
    if not e1 or not e2 or not (math.isfinite(e1) and math.isfinite(e2)):
        return "-"
    return f"{math.log2(abs(e1) / abs(e2)):.2f}"


def _steps(r: dict) -> str:
    """The duration error in steps and relative (a step is dt / (2L/c))."""
    k = r.get("duration_steps")
    return "n/a" if k is None else f"{k:+d} ({_pct(r['duration'], 2)})"


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a small version: collision1d n = 10, 20, 40; collision3d "
                    "level 1 with CN and BE, standard and moment-preserving; ball_on_plate with CN, standard and "
                    "moment-preserving, up to T = 150 us")  # fmt: skip
    ap.add_argument("--level", type=int, default=None, help="collision3d level (default 2; 1 with --quick)")
    ap.add_argument("--no-3d", action="store_true", help="skip collision3d (no gmsh)")
    a = ap.parse_args(argv)
    levels = (10, 20, 40) if a.quick else (20, 40, 80)
    n1d = levels[1]
    level = a.level or (1 if a.quick else 2)
    pairs = [(s, m) for s in SCHEMES for m in MASSES]
    few = [(s, m) for s in ("cn", "be") for m in ("standard", "moment-preserving")]  # --quick, 3D and the plate
    t0 = time.perf_counter()

    c1 = {(s, m, n): collision1d(n, s, m) for s, m in pairs for n in levels}
    rows = [[LABEL[s], m, _steps(r), _pct(r.get("force")), _pct(r.get("velocity")),
             f"{r['osc']:.2f}", _e(r["energy"]), _e(r["momentum"])]
            for s, m in pairs for r in [c1[s, m, n1d]]]  # fmt: skip
    b = get_benchmark("collision1d")
    p = b.params({})
    dt, T = b.times(n1d, p)
    print(table(f"collision1d (exact), n = {n1d} cells per bar, dt = h/(2c) = {dt:g}, T = {T:g}; defaults "
                "L = 1, gap = 0.1, v = 0.5, E = rho = 1",
                ["scheme", "mass", "duration vs 2L/c: steps (%)", "mean force vs rho c v/2",
                 "final velocities (max err / v)", "osc. index", "energy drift", "momentum drift"], rows))  # fmt: skip

    if not a.no_3d:
        b3 = get_benchmark("collision3d")
        p3 = b3.params({})
        problem = b3.build(level, p3)
        dt3, T3 = b3.times(level, p3)
        c3 = {(s, m): collision3d(level, s, m, problem) for s, m in (few if a.quick else pairs)}
        rows = [[LABEL[s], m, _pct(r["duration"]), _pct(r["peak"]), f"{r['osc']:.2f}", _e(r["energy"]),
                 _e(r["momentum"])] for (s, m), r in c3.items()]  # fmt: skip
        print(table(f"collision3d (Hertz, two equal balls R = E = rho = 1, nu = 0.3, v = 0.002), level {level} "
                    f"({problem.mesh.n_nodes * 3} dofs), dt = t_c/(25 n) = {dt3:.4g}, T = {T3:.4g}",
                    ["scheme", "mass", "duration vs Hertz", "peak force vs Hertz", "osc. index", "energy drift",
                     "momentum drift"], rows))  # fmt: skip

    T_plate = 1.5e-4 if a.quick else None
    bp = {(s, m): ball_on_plate(s, m, T_plate) for s, m in (few[:2] if a.quick else pairs)}
    case = load_case(BALL_ON_PLATE)
    rows = [[LABEL[s], m, f"{r['restitution']:.3f}", f"{1e6 * r['duration']:.0f} us", f"{r['peak']:.0f} N",
             f"{r['osc']:.2f}", _e(r["energy"]), r["status"]] for (s, m), r in bp.items()]  # fmt: skip
    print(table(f"examples/ball_on_plate.toml (no closed form), {case.problem.mesh.n_nodes * 3} dofs, "
                f"dt = {case.dt:g} s, T = {T_plate or case.T:g} s",
                ["scheme", "mass", "ball restitution", "contact duration", "peak force", "osc. index",
                 "energy drift", "status"], rows))  # fmt: skip

    if not a.quick:  # dt / 10: a step of about 2 wave transits of the finest cells (0.3 mm at c_p = 5.9 km/s)
        fine = {m: ball_on_plate("cn", m, 1.5e-4, case.dt / 10) for m in ("standard", "moment-preserving")}
        bp.update({("cn/10", m): r for m, r in fine.items()})
        rows = [["CN", m, f"{r['restitution']:.3f}", f"{1e6 * r['duration']:.1f} us", f"{r['peak']:.0f} N",
                 f"{r['osc']:.2f}", _e(r["energy"]), r["status"]] for m, r in fine.items()]  # fmt: skip
        print(table(f"examples/ball_on_plate.toml with dt = {case.dt / 10:g} s (the case's / 10), T = 1.5e-4 s",
                    ["scheme", "mass", "ball restitution", "contact duration", "peak force", "osc. index",
                     "energy drift", "status"], rows))  # fmt: skip

    rows = []
    for s, m in pairs:
        f = [c1[s, m, n].get("force") for n in levels]
        d = [c1[s, m, n] for n in levels]
        k = [r.get("duration_steps") and r["duration"] for r in d]  # 0 when exact to the step
        rows.append([LABEL[s], m, *(_pct(x, 2) for x in f), rate(f[0], f[1]), rate(f[1], f[2]),
                     *(_steps(r) for r in d), rate(k[0], k[1]), rate(k[1], k[2])])  # fmt: skip
    lv = [str(n) for n in levels]
    print(table("collision1d: convergence in h and dt (dt = h/(2c)), errors of the mean force and of the duration "
                "and the observed rates log2(e_n / e_2n) (-: an error of 0 steps)",
                ["scheme", "mass", *(f"force n={n}" for n in lv), "rate", "rate",
                 *(f"duration n={n}: steps (%)" for n in lv), "rate", "rate"], rows))  # fmt: skip
    print(f"({time.perf_counter() - t0:.0f} s)")
    return {"collision1d": c1, "collision3d": None if a.no_3d else c3, "ball_on_plate": bp}


if __name__ == "__main__":
    main()
