"""Finite strain's costs (issue 41), as ratios measured in one run.

    python -m benchmarks.bench_finite_strain [--cells 12] [--steps 20] [--bracket 200] [--assembly 32] [--turning 64]

A 3D Neo-Hookean block (cells x cells/2 x cells/2 hexahedra, 40 x 20 x 20 mm, rubber) thrown spinning
at a plane, its whole skin in contact, energy-momentum at dt = 2e-5 s, the default backend, in one
process, alternated twice (the best of each):

1. the median step with ``tangent=modified`` (the default) against ``tangent=full``, with their Newton
   iterations and tangent factorizations per step;
2. the median finite-strain step against the linear (``model = "linear"``) step of the same run, and
   against one bare solve with the linear step's factor;
3. the parts of a step: one internal force, one tangent assembly, one factorization of the step
   operator with that tangent, each timed over a few calls;
4. ``hertz3d`` at its default level and dt (the ball touching the plane at t = 0: every step inside the
   impact, mass-dominated), Crank-Nicolson and the default mass: the median Neo-Hookean step against the
   linear one (issue 41 asks at most x3), with the Newton iterations and factorizations per step, and the same
   at dt / 10 and dt / 100, where the mass dominates the step's operator, each with and without Anderson's mixing
   of the Newton iterates (solver option ``acceleration``; needs gmsh: skipped with a message otherwise);
5. a 2k-dof 3D gmsh part: examples/bracket_tumble.toml (2,853 dofs, tetrahedra, energy-momentum, its whole skin
   in contact), the median step of its first ``--bracket`` (200) levels with Neo-Hookean against the same run with
   the linear model (issue 51 asks at most x10), with its Newton iterations and tangent factorizations;
6. the tangent assembly of a Neo-Hookean (and Saint Venant-Kirchhoff) cube of ``--assembly`` (32)^3
   hexahedra (about 100k dofs) against the linear stiffness assembly, on the structured grid (whose
   cells are translates: the linear assembly computes one element matrix) and on the same grid with its
   points moved by up to 20% of a cell (every element its own); issue 41 asks at most x2;
7. a spinning part's kept tangent turned with its bodies (:mod:`signorini.dynamics.solve.turning`): ``spin3d``
   (Crank-Nicolson, the default mass, its first ``--turning`` (64) steps, a tenth of a turn each) and the bracket's
   flight (its first 75 levels, before its corner touches the plane), each with the turn and without it (the run's
   turning switched off), against the linear model's step: median steps, Newton iterations and tangent
   factorizations.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from benchmarks import median_step, per_call


def block(cells: int, model: str):
    from signorini.contact.obstacles import PlaneObstacle
    from signorini.dynamics.model.problem import Problem
    from signorini.fem.material import MATERIAL_MODELS
    from signorini.fem.mesh import box

    m = box(cells, cells // 2, cells // 2, 0.04, 0.02, 0.02)
    c, w = np.array([0.02, 0.01, 0.01]), np.array([0.0, 20.0, 60.0])
    return Problem(m, MATERIAL_MODELS[model].from_young(5e6, 0.45, 1100.0),
                   ["xmin", "xmax", "ymin", "ymax", "zmin", "zmax"], PlaneObstacle([0, 0, -0.006], [0, 0, 1.0]),
                   v0=lambda x: np.cross(w, x - c) + [0.0, 0.0, -1.0])  # fmt: skip


def run(cells: int, steps: int) -> dict:
    from signorini.dynamics.stepping.simulate import Stepper

    best: dict[str, float] = {}
    info: dict[str, dict] = {}
    for _ in range(2):
        for key, model, tangent in (("modified", "neo-hookean", "modified"), ("full", "neo-hookean", "full"),
                                    ("linear", "linear", "modified")):  # fmt: skip
            s = Stepper(
                block(cells, model), "energy-momentum", (2e-5, steps * 2e-5), {"solver_options": {"tangent": tangent}}
            )
            step = median_step(s)
            H = s.finish()
            best[key] = min(best.get(key, np.inf), step)
            n = max(H.steps, 1)
            info[key] = {"newton_per_step": float(H.nonlinear_iterations[1:].mean()) if H.steps else 0.0,
                         "tangent_factorizations_per_step": H.counters.get("tangent_factorizations", 0) / n,
                         "dofs": int(H.meta["dofs"]), "backend": H.meta.get("backend")}  # fmt: skip
    s = Stepper(block(cells, "neo-hookean"), "energy-momentum", (2e-5, 2e-5))
    ctx = s.run.ctx
    U = 1e-4 * np.sin(50.0 * ctx.disc.problem.mesh.points).ravel()
    shifts = iter(range(1, 100))
    force = per_call(lambda: ctx.elastic.force(U * (1.0 + 1e-9 * next(shifts))), 5)  # (the last one is cached)
    tangent = per_call(lambda: ctx.elastic.tangent(U), 3)
    from signorini.dynamics.model.operator import Operator, Tangent

    K = ctx.elastic.tangent(U)
    op = s.run.scheme.step_operator(ctx, 2e-5)

    def factorize():
        o = Operator(op.mass, op.stiffness, Tangent(K))
        ctx.factors.system(o)
        ctx.factors.release(o)

    factor = per_call(factorize, 3)
    sys_, _ = ctx.factors.system(op)
    b = np.random.default_rng(0).standard_normal(ctx.free.size)
    t0 = time.perf_counter()
    for _ in range(5):
        sys_.solver.solve_linear(b)
    bare = (time.perf_counter() - t0) / 5
    s.finish()
    return {"case": f"3D Neo-Hookean block {cells} x {cells // 2} x {cells // 2} hexahedra, whole skin in contact",
            "dofs": info["modified"]["dofs"], "backend": info["modified"]["backend"], "steps": steps,
            "step_modified_s": best["modified"], "step_full_s": best["full"], "step_linear_s": best["linear"],
            "modified_over_full": best["modified"] / best["full"],
            "finite_over_linear": best["modified"] / best["linear"], "finite_over_bare_solve": best["modified"] / bare,
            "newton": info, "internal_force_s": force, "tangent_s": tangent, "factorization_s": factor,
            "bare_solve_s": bare}  # fmt: skip


def hertz(steps: int, divisor: int = 1) -> dict | None:
    """Item 4 of the module docstring, at the default dt / ``divisor``."""
    import dataclasses
    import importlib.util

    if importlib.util.find_spec("gmsh") is None:
        return None
    from signorini.dynamics.stepping.simulate import Stepper
    from signorini.fem.material import with_model
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark("hertz3d")
    n = b.n_default()
    p = b.problem(n)
    dt = b.run_times(n)[0] / divisor
    best: dict[str, float] = {}
    info: dict[str, dict] = {}
    runs = {"neo-hookean": ("neo-hookean", "anderson"), "neo-hookean, no acceleration": ("neo-hookean", "none"),
            "linear": ("linear", "anderson")}  # fmt: skip
    for _ in range(2):
        for key, (model, acceleration) in runs.items():
            q = dataclasses.replace(p, material=with_model(p.material, model))
            s = Stepper(q, "crank-nicolson", (dt, steps * dt), {"solver_options": {"acceleration": acceleration}})
            best[key] = min(best.get(key, np.inf), median_step(s))
            H = s.finish()
            info[key] = {"newton_per_step": float(np.nanmean(H.nonlinear_iterations[1:])),
                         "tangent_factorizations": int(H.counters.get("tangent_factorizations", 0)),
                         "dofs": int(H.meta["dofs"]), "backend": H.meta.get("backend")}  # fmt: skip
    return {"case": f"hertz3d n = {n}, dt = {dt:.3g}, crank-nicolson, {steps} steps",
            "step_finite_s": best["neo-hookean"], "step_linear_s": best["linear"],
            "finite_over_linear": best["neo-hookean"] / best["linear"],
            "plain_over_linear": best["neo-hookean, no acceleration"] / best["linear"],
            "newton": info}  # fmt: skip


def bracket(levels: int) -> dict:
    """Item 5 of the module docstring: the case file as it is, its model replaced for the linear run."""
    import dataclasses
    from pathlib import Path

    from signorini.dynamics.stepping.simulate import Stepper
    from signorini.fem.material import with_model
    from signorini.io.config import load_case

    case = load_case(Path(__file__).resolve().parents[1] / "examples" / "bracket_tumble.toml")
    best: dict[str, float] = {}
    info: dict[str, dict] = {}
    for _ in range(2):
        for model in ("neo-hookean", "linear"):
            q = dataclasses.replace(case.problem, material=with_model(case.problem.material, model))
            options = {"mass": case.mass, "scheme_options": case.scheme_options, "solver_options": case.solver_options}
            s = Stepper(q, case.scheme, (case.dt, levels * case.dt), options)
            best[model] = min(best.get(model, np.inf), median_step(s))
            H = s.finish()
            info[model] = {"newton_per_step": float(np.nanmean(H.nonlinear_iterations[1:])),
                           "tangent_factorizations": int(H.counters.get("tangent_factorizations", 0)),
                           "dofs": int(H.meta["dofs"])}  # fmt: skip
    return {"case": f"examples/bracket_tumble.toml, {case.scheme}, {levels} levels",
            "step_finite_s": best["neo-hookean"], "step_linear_s": best["linear"],
            "finite_over_linear": best["neo-hookean"] / best["linear"], "newton": info}  # fmt: skip


def turned(levels: int) -> list[dict]:
    """Item 7 of the module docstring."""
    import dataclasses
    from pathlib import Path
    from unittest import mock

    import signorini.dynamics.solve.turning as turning
    from signorini.dynamics.stepping.simulate import Stepper
    from signorini.fem.material import with_model
    from signorini.io.config import load_case
    from signorini.studies.benchmarks import get_benchmark

    spin = get_benchmark("spin3d")
    dt = spin.run_times(1)[0]
    case = load_case(Path(__file__).resolve().parents[1] / "examples" / "bracket_tumble.toml")
    options = {"mass": case.mass, "scheme_options": case.scheme_options, "solver_options": case.solver_options}
    runs = {  # name -> (problem, scheme, (dt, T), options)
        f"spin3d, crank-nicolson, {levels} steps": (spin.problem(1), "crank-nicolson", (dt, levels * dt), {}),
        f"examples/bracket_tumble.toml, {case.scheme}, its flight (75 levels)": (
            case.problem, case.scheme, (case.dt, 75 * case.dt), options),
    }  # fmt: skip
    out = []
    for name, (p, scheme, times, opts) in runs.items():
        row: dict = {"case": name}
        for label, model, made in (("turned", None, turning.body_turning), ("not turned", None, lambda ctx: None),
                                   ("linear", "linear", turning.body_turning)):  # fmt: skip
            q = p if model is None else dataclasses.replace(p, material=with_model(p.material, model))
            with mock.patch("signorini.dynamics.solve.context.body_turning", made):
                s = Stepper(q, scheme, times, opts)
                step = median_step(s)
                H = s.finish()
            row[label] = {"step_s": step, "newton_per_step": float(np.nanmean(H.nonlinear_iterations[1:])),
                          "tangent_factorizations": int(H.counters.get("tangent_factorizations", 0))}  # fmt: skip
        out.append(row)
    return out


def assembly(cells: int) -> list[dict]:
    """Item 6 of the module docstring."""
    from signorini.fem.assembly import stiffness_matrix
    from signorini.fem.hyperelastic import NeoHookeanLaw, SaintVenantKirchhoffLaw, tangent_stiffness
    from signorini.fem.material import IsotropicElastic
    from signorini.fem.mesh import box

    mat = IsotropicElastic.from_young(1.0, 0.3, 1.0)
    rng = np.random.default_rng(1)
    out = []
    for label in ("structured", "moved points"):
        mesh = box(cells, cells, cells, 1.0, 1.0, 1.0)
        if label == "moved points":
            mesh.points = mesh.points + 0.2 / cells * rng.uniform(-1.0, 1.0, mesh.points.shape)
        U = 1e-3 * rng.standard_normal(mesh.n_nodes * 3)
        # each timed after one call: the mesh's cached pattern and geometry are built once per run, not per step
        linear = per_call(lambda: stiffness_matrix(mesh, mat), 4, warm=True)  # noqa: B023
        for law in (NeoHookeanLaw(mat.lam, mat.mu), SaintVenantKirchhoffLaw(mat.lam, mat.mu)):
            t = per_call(lambda: tangent_stiffness(mesh, law, U), 4, warm=True)  # noqa: B023
            out.append({"mesh": f"{cells}^3 hexahedra, {label}", "dofs": 3 * mesh.n_nodes, "law": law.name,
                        "linear_s": linear, "tangent_s": t, "tangent_over_linear": t / linear})  # fmt: skip
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=12)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--bracket", type=int, default=200, help="levels of the gmsh bracket (0: none)")
    ap.add_argument("--assembly", type=int, default=32, help="cells per side of the assembly cube (0: none)")
    ap.add_argument("--turning", type=int, default=64, help="steps of spin3d for item 7 (0: none)")
    args = ap.parse_args(argv)
    r = run(args.cells, args.steps)
    h = hertz(args.steps)
    smaller = [hertz(args.steps, k) for k in (10, 100)] if h is not None else []
    br = bracket(args.bracket) if args.bracket else None
    a = assembly(args.assembly) if args.assembly else []
    t = turned(args.turning) if args.turning else []
    print(json.dumps({**r, "hertz3d": h, "hertz3d_smaller_steps": smaller, "bracket": br, "assembly": a,
                      "turned": t}, indent=1))  # fmt: skip
    print(f"{r['case']} ({r['dofs']} dofs, {r['backend']}): a step with tangent=modified is "
          f"x{r['modified_over_full']:.2f} of full's, x{r['finite_over_linear']:.1f} of the linear model's and "
          f"x{r['finite_over_bare_solve']:.0f} of one bare solve; internal force {1e3 * r['internal_force_s']:.1f} ms, "
          f"tangent {1e3 * r['tangent_s']:.1f} ms, factorization {1e3 * r['factorization_s']:.1f} ms")  # fmt: skip
    if h is None:
        print("hertz3d: skipped (gmsh not installed: pip install '.[mesh]')")
    else:
        dofs = h["newton"]["linear"]["dofs"]
        for x in [h, *smaller]:
            plain = x["newton"]["neo-hookean, no acceleration"]
            print(f"{x['case']} ({dofs} dofs): a Neo-Hookean step is x{x['finite_over_linear']:.2f} of the linear one"
                  f" ({x['newton']['neo-hookean']['newton_per_step']:.2f} Newton iterations per step, "
                  f"{x['newton']['neo-hookean']['tangent_factorizations']} tangent factorizations); "
                  f"without Anderson's mixing x{x['plain_over_linear']:.2f} "
                  f"({plain['newton_per_step']:.2f} iterations)")  # fmt: skip
    if br is not None:
        nh = br["newton"]["neo-hookean"]
        print(f"{br['case']} ({nh['dofs']} dofs): a Neo-Hookean step is x{br['finite_over_linear']:.1f} of the linear "
              f"one ({1e3 * br['step_finite_s']:.1f} against {1e3 * br['step_linear_s']:.2f} ms; "
              f"{nh['newton_per_step']:.2f} Newton iterations per step, {nh['tangent_factorizations']} tangent "
              "factorizations)")  # fmt: skip
    for x in t:
        yes, no, lin = x["turned"], x["not turned"], x["linear"]
        print(f"{x['case']}: the kept tangent turned with the body, a step {1e3 * yes['step_s']:.2f} ms "
              f"(x{yes['step_s'] / lin['step_s']:.1f} of the linear model's, {yes['newton_per_step']:.2f} iterations, "
              f"{yes['tangent_factorizations']} tangents), not turned {1e3 * no['step_s']:.2f} ms "
              f"(x{no['step_s'] / lin['step_s']:.1f}, {no['newton_per_step']:.2f}, {no['tangent_factorizations']}): "
              f"x{yes['step_s'] / no['step_s']:.2f}")  # fmt: skip
    for x in a:
        print(f"tangent assembly, {x['law']}, {x['mesh']} ({x['dofs']} dofs): x{x['tangent_over_linear']:.2f} of the "
              f"linear stiffness assembly ({x['tangent_s']:.3f} against {x['linear_s']:.3f} s)")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
