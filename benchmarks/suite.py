"""Benchmark suite: bar3d (n = 4, 8, 16, 32) and bar2d series, CN with the seed mass,
the Hertz ball and disc series when gmsh is installed (``pip install ".[mesh]"``; hertz3d
n = 9 is a ball of about 36k dofs with about 1.3k contact nodes, n = 14 one of about
100k dofs), the per-step cost
of every registered scheme on bar3d n = 8, and the cost of Coulomb friction against the
frictionless run (:mod:`benchmarks.bench_friction`), and the petsc backend on 1 and 2 MPI
ranks when ``.venv-mpi`` exists, with and without a factor (:mod:`benchmarks.bench_petsc`,
backends ``petsc`` and ``petsc-cg``, printed only).

Run from the repository root:  python -m benchmarks [--quick] [--out DIR] [--steps N]

For every size (each in a fresh process, so that peak memory is per size): dofs,
contact dofs, the set-up split (mesh, assembly, factorization, condensation), the time
per step, the ratio of a step to one bare forward+backward solve with the same factor
(or to one sparse matrix-vector product for the CG backend), the factor size and the
peak resident memory.  Writes ``bench.json``, ``bench.md`` and ``bench.png`` (log-log
time against dofs with fitted exponents).
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

SERIES = {
    "full": [
        ("bar3d", 4),
        ("bar3d", 8),
        ("bar3d", 16),
        ("bar3d", 32),
        ("bar2d", 8),
        ("bar2d", 16),
        ("bar2d", 32),
        ("bar2d", 64),
    ],
    "quick": [("bar3d", 4), ("bar3d", 8), ("bar2d", 8), ("bar2d", 16), ("bar2d", 32)],
}
HERTZ_SERIES = {
    "full": [("hertz3d", 3), ("hertz3d", 6), ("hertz3d", 9), ("hertz3d", 14), ("hertz2d", 16), ("hertz2d", 32)],
    "quick": [("hertz3d", 3), ("hertz3d", 6), ("hertz2d", 16)],
}
SERIES_NAMES = ("bar2d", "bar3d", "hertz2d", "hertz3d")


def series(size: str) -> list[tuple[str, int]]:
    """The bars, and the Hertz ball and disc when gmsh is importable."""
    import importlib.util

    has_gmsh = importlib.util.find_spec("gmsh") is not None
    if not has_gmsh:
        print('gmsh not installed (pip install ".[mesh]"): the hertz series is skipped', flush=True)
    return SERIES[size] + (HERTZ_SERIES[size] if has_gmsh else [])


def step_seconds(H) -> tuple[float, float]:
    """(time per step, seconds of Delassus columns computed inside the loop).

    ``simulate`` already leaves the columns out of ``step_seconds``: computing them is
    set-up work that lazy condensation does when the nodes first near contact."""
    m = H.meta
    return m["step_seconds"], m.get("in_loop_condensation_seconds", 0.0)


def measure(bench: str, n: int, steps: int, backend: str, energy: bool = True, condensation: str = "auto") -> dict:
    from signorini.dynamics.model.problem import discretize
    from signorini.dynamics.stepping.simulate import simulate
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark(bench)
    t0 = time.perf_counter()
    problem = b.problem(n)
    problem.mesh.check_cells()
    t_mesh = time.perf_counter() - t0
    disc = discretize(problem, "seed")
    dt = b.run_times(n)[0]  # h/2 for the bars, t_c/(25 n) for the Hertz impacts
    options = {"backend": backend, "condensation": condensation}
    H = simulate(disc, "cn", dt, steps * dt, energy=energy, solver_options=options)
    m = H.meta
    ref = m.get("bare_solve_seconds") or m.get("bare_spmv_seconds")
    step, in_loop = step_seconds(H)
    return {
        "benchmark": bench,
        "n": n,
        "dofs": m["dofs"],
        "contact_dofs": m["contact_nodes"],
        "backend": m["backend"],
        "steps": H.steps,
        "mesh_s": t_mesh,
        "assembly_s": m["assembly_seconds"] + m["reduction_seconds"],
        "factorization_s": m["factorization_seconds"],
        "condensation_s": m["condensation_seconds"],
        "setup_s": t_mesh + m["assembly_seconds"] + m["reduction_seconds"] + m["setup_seconds"] + in_loop,
        "step_s": step,
        "reference_op": "solve" if "bare_solve_seconds" in m else "spmv",
        "reference_s": ref,
        "step_over_reference": step / ref,
        "factor_MB": m["factor_bytes"] / 1e6,
        "peak_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3,
        "impacts": H.impacts,
        "krylov_iterations": H.counters.get("krylov_iterations", 0),
        "max_residual": float(H.residual.max()),
    }


def measure_schemes(bench: str, n: int, steps: int, backend: str) -> list[dict]:
    """Per-step time of every registered scheme on one discretization (standard mass, which
    every scheme accepts), with its ratio to one bare solve and to the CN step."""
    from signorini.dynamics.model.problem import discretize
    from signorini.dynamics.schemes import SCHEMES
    from signorini.dynamics.stepping.simulate import simulate
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark(bench)
    disc = discretize(b.problem(n), "standard")
    dt = b.h(n) / 2
    rows = []
    for entry in SCHEMES:
        H = simulate(disc, entry.name, dt, steps * dt, backend=backend)
        m = H.meta
        ref = m.get("bare_solve_seconds") or m.get("bare_spmv_seconds")
        step, _ = step_seconds(H)
        rows.append({
            "scheme": entry.name,
            "status": H.status,
            "step_ms": 1e3 * step,
            "step_over_reference": step / ref,
            "factorizations": H.counters["factorizations"],
            "solves_per_step": H.counters["linear_solves"] / max(H.steps, 1),
        })  # fmt: skip
    cn = next(r["step_ms"] for r in rows if r["scheme"] == "crank-nicolson")
    for r in rows:
        r["step_over_cn"] = r["step_ms"] / cn
    return rows


def schemes_markdown(bench: str, n: int, rows: list[dict]) -> list[str]:
    md = [f"\nPer scheme, {bench} n={n}, standard mass (one run each, same process):", ""]
    md += ["| scheme | step ms | step / bare solve | step / CN step | factorizations | solves per step |"]
    md += ["|---|---|---|---|---|---|"]
    for r in rows:
        md.append(
            f"| {r['scheme']} | {r['step_ms']:.2f} | {r['step_over_reference']:.2f} | {r['step_over_cn']:.2f} | "
            f"{r['factorizations']} | {r['solves_per_step']:.2f} |"
        )
    return md


def fit(x, y) -> float:
    x, y = np.log(np.asarray(x, float)), np.log(np.asarray(y, float))
    return float(np.polyfit(x, y, 1)[0]) if x.size > 1 else float("nan")


def run_series(series: list[tuple[str, int]], steps: int, backend: str, energy: bool) -> list[dict]:
    """Measure every (benchmark, n) in a fresh process; print one line per size."""
    rows = []
    for bench, n in series:
        cmd = [sys.executable, "-m", "benchmarks", "--one", bench, str(n), "--steps", str(steps), "--backend", backend]
        if not energy:
            cmd.append("--no-energy")
        r = json.loads(subprocess.check_output(cmd).decode().strip().splitlines()[-1])
        rows.append(r)
        print(
            f"{bench} n={n}: {r['dofs']} dofs, {r['backend']}, setup {r['setup_s']:.2f}s, "
            f"step {1e3 * r['step_s']:.2f} ms = {r['step_over_reference']:.2f} x {r['reference_op']}, "
            f"peak {r['peak_MB']:.0f} MB",
            flush=True,
        )
    return rows


def exponents(rows: list[dict]) -> dict:
    """Fitted exponents p of time ~ dofs^p for set-up and step, per benchmark."""
    exps = {}
    for bench in SERIES_NAMES:
        sel = [r for r in rows if r["benchmark"] == bench]
        if len(sel) > 1:
            exps[bench] = {
                "setup": fit([r["dofs"] for r in sel], [r["setup_s"] for r in sel]),
                "step": fit([r["dofs"] for r in sel], [r["step_s"] for r in sel]),
            }
    return exps


def markdown(rows: list[dict], exps: dict) -> list[str]:
    md = [
        "| case | n | dofs | contact | backend | mesh s | assembly s | factor s | condense s | step ms "
        "| step/ref | ref | factor MB | peak MB |",
        "|" + "---|" * 14,
    ]
    for r in rows:
        md.append(
            f"| {r['benchmark']} | {r['n']} | {r['dofs']} | {r['contact_dofs']} | {r['backend']} | "
            f"{r['mesh_s']:.2f} | {r['assembly_s']:.2f} | {r['factorization_s']:.2f} | "
            f"{r['condensation_s']:.2f} | {1e3 * r['step_s']:.2f} | {r['step_over_reference']:.2f} | "
            f"{r['reference_op']} | {r['factor_MB']:.0f} | {r['peak_MB']:.0f} |"
        )
    md += [
        "",
        "Fitted exponents (time ~ dofs^p): "
        + ", ".join(f"{k}: setup {v['setup']:.2f}, step {v['step']:.2f}" for k, v in exps.items()),
    ]
    return md


def plot(rows: list[dict], exps: dict, path: Path) -> None:
    """Log-log set-up and step time against dofs with the fitted exponents."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for bench, mk in zip(SERIES_NAMES, "osd^", strict=True):
        sel = [r for r in rows if r["benchmark"] == bench]
        if sel:
            d = [r["dofs"] for r in sel]
            p = exps.get(bench, {})
            ax.loglog(
                d, [r["setup_s"] for r in sel], mk + "-", label=f"{bench} setup (p={p.get('setup', float('nan')):.2f})"
            )
            ax.loglog(
                d, [r["step_s"] for r in sel], mk + "--", label=f"{bench} step (p={p.get('step', float('nan')):.2f})"
            )
    ax.set_xlabel("degrees of freedom")
    ax.set_ylabel("time [s]")
    ax.set_title("CN + seed mass: set-up and time per step")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--quick", action="store_true", help="skip bar3d n = 16, 32, bar2d n = 64, hertz3d n = 9 and hertz2d n = 32"
    )
    ap.add_argument("--steps", type=int, default=100, help="time steps per size (default 100)")
    ap.add_argument("--backend", default="auto", help="auto|superlu|pardiso|cholmod|cg (default auto)")
    ap.add_argument("--no-energy", action="store_true", help="switch the energy bookkeeping observer off")
    ap.add_argument(
        "--condensation", default="auto", help="auto|schur|lazy|full: Delassus matrix of direct backends (default auto)"
    )
    ap.add_argument("--out", default="out/bench", help="output directory")
    ap.add_argument("--one", nargs=2, metavar=("BENCH", "N"), help=argparse.SUPPRESS)
    ap.add_argument(
        "--schemes-on",
        nargs=2,
        metavar=("BENCH", "N"),
        default=("bar3d", "8"),
        help="benchmark and size of the per-scheme table (default bar3d 8)",
    )
    a = ap.parse_args(argv)
    if a.one:
        print(json.dumps(measure(a.one[0], int(a.one[1]), a.steps, a.backend, not a.no_energy, a.condensation)))
        return 0
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = run_series(series("quick" if a.quick else "full"), a.steps, a.backend, not a.no_energy)
    exps = exponents(rows)
    md = markdown(rows, exps)
    sbench, sn = a.schemes_on[0], int(a.schemes_on[1])
    srows = measure_schemes(sbench, sn, a.steps, a.backend)
    md += schemes_markdown(sbench, sn, srows)
    from .bench_friction import friction_markdown, friction_rows

    frows = friction_rows(a.quick)  # Coulomb against frictionless: bar3d n = 8 oblique, the ball
    md += friction_markdown(frows)
    from .bench_petsc import main as petsc_main

    # the petsc and petsc-cg backends on 1 and 2 ranks (bar3d n = 16; --quick: n = 8), when .venv-mpi exists
    for backend in ("petsc", "petsc-cg"):
        petsc_main(["--n", "8" if a.quick else "16", "--steps", "10", "--no-serial", "--backend", backend])
    (out / "bench.md").write_text("\n".join(md) + "\n")
    payload = {"rows": rows, "exponents": exps, "schemes": srows, "friction": frows}
    (out / "bench.json").write_text(json.dumps(payload, indent=1))
    plot(rows, exps, out / "bench.png")
    print("\n".join(md))
    return 0
