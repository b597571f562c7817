"""The petsc and petsc-cg backends on 1 and 2 MPI ranks against the serial backends (issue 22).

Usage: python -m benchmarks.bench_petsc [--n 24] [--steps 10] [--ranks 1 2] [--no-serial]
       [--backend petsc|petsc-cg] [--preconditioner jacobi|gamg]
       [--case FILE] [--node-orders mesh auto]

Runs ``signorini run bar3d --n N --set gap=0`` (the bar touches the obstacle from the
first step, so every step has a contact solve) for ``--steps`` steps of the default dt:
once serially (this interpreter) with the default backend (against ``petsc``) or ``cg``
(against ``petsc-cg``), then with ``.venv-mpi/bin/mpiexec -n P .venv-mpi/bin/signorini
run ... --backend B`` for each P.
Each run is a fresh process; the figures come from its summary.json: set-up, time per
step (the Delassus columns computed inside the loop are reported apart, as set-up work),
factor size and peak memory per rank.  Prints the ratios of one run: the 2-rank step
against the 1-rank PETSc step (speed-up), and the 1-rank PETSc step against the serial
backend's; for the CG backends also the CG iterations per solve.

``--case FILE`` runs a case file instead (as written: set its T for a short run), e.g. a
user's gmsh part (``python3 examples/meshes/make_parts.py --cylinder-h 0.002 --out DIR``
and ``examples/cylinder_drop.toml`` pointed at it).  ``--node-orders`` runs the
distributed backend once per solver option ``node_order`` and prints, per rank count,
the cells each rank assembles (``rank_cells``) and the ratios of the step time and the
peak memory per rank between the first order and each other one.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

VENV = Path(__file__).parents[1] / ".venv-mpi" / "bin"


def run(cmd: list[str], out: Path) -> dict:
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    r = subprocess.run([*cmd, "--out", str(out), "--quiet", "--yes"], capture_output=True, text=True, env=env)
    if r.returncode != 0:
        raise SystemExit(f"bench_petsc: {' '.join(cmd)} failed ({r.returncode}): {r.stderr[-800:]}")
    s = json.loads((out / "summary.json").read_text())
    return {
        "backend": s["backend"],
        "ranks": s.get("ranks", 1),
        "dofs": s["dofs"],
        "setup": s["setup_seconds"],
        "step": s["step_seconds"],
        "factorization": s.get("factorization_seconds", 0.0),
        "bare_solve": s.get("bare_solve_seconds", 0.0),
        "columns": s.get("in_loop_condensation_seconds", 0.0),
        "factor_gb": s.get("factor_bytes", 0) / 1e9,
        "peak_gib": [m / 2**30 for m in s.get("rank_peak_memory_bytes", [])],
        "node_order": s.get("node_order", "-"),
        "rank_cells": s.get("rank_cells", []),
        "cg_iterations": s["counters"].get("krylov_iterations", 0) / max(s["counters"]["linear_solves"], 1),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--no-serial", action="store_true", help="skip the serial run")
    ap.add_argument("--backend", choices=("petsc", "petsc-cg"), default="petsc")
    ap.add_argument("--preconditioner", choices=("jacobi", "gamg"), default=None, help="of petsc-cg")
    ap.add_argument("--case", type=Path, default=None, help="a case file instead of bar3d (its own dt and T)")
    ap.add_argument(
        "--node-orders",
        nargs="+",
        choices=("auto", "mesh", "morton"),
        default=["auto"],
        help="solver option node_order",
    )
    a = ap.parse_args(argv)
    if not (VENV / "mpiexec").exists():
        print("bench_petsc: no .venv-mpi (bash scripts/mpi-env.sh): skipped")
        return 0
    dt = 0.1 / a.n / 2  # bar3d's default dt, h/2
    args = ["bar3d", "--n", str(a.n), "--set", "gap=0", "--T", repr(a.steps * dt)]
    if a.case is not None:
        args = [str(a.case.resolve())]
    rows = []
    runs: dict[tuple[int, str], dict] = {}  # (ranks, node_order asked for) -> figures
    with tempfile.TemporaryDirectory() as tmp:
        if not a.no_serial:
            ref = ["--backend", "cg"] if a.backend == "petsc-cg" else []
            rows.append(run([sys.executable, "-m", "signorini", "run", *args, *ref], Path(tmp) / "serial"))
        own = ["--backend", a.backend]
        if a.preconditioner:
            own += ["--solver-option", f"preconditioner={a.preconditioner}"]
        for p in a.ranks:
            for order in a.node_orders:
                cmd = [str(VENV / "mpiexec"), "-n", str(p), str(VENV / "signorini"), "run", *args, *own,
                       "--solver-option", f"node_order={order}"]  # fmt: skip
                rows.append(run(cmd, Path(tmp) / f"p{p}-{order}"))
                runs[(p, order)] = rows[-1]
                print(f"bench_petsc: {p} rank(s), {order} done: {json.dumps(rows[-1])}", flush=True)  # as it goes
    what = a.case.name if a.case is not None else f"bar3d n = {a.n}"
    print(f"{what}: {rows[0]['dofs']:,} dofs" + ("" if a.case is not None else f", {a.steps} steps in contact"))
    head = ("run", "set-up s", "factor s", "solve ms", "step ms", "columns s", "factor GB", "CG its")
    print(f"{head[0]:>28}" + "".join(f" {h:>9}" for h in head[1:]) + "  peak GiB per rank; cells per rank")
    for r in rows:
        name = f"{r['backend']} x{r['ranks']}" + (f" {r['node_order']}" if r["node_order"] != "-" else "")
        peaks = " ".join(f"{m:.2f}" for m in r["peak_gib"])
        figures = (r["setup"], r["factorization"], 1e3 * r["bare_solve"], 1e3 * r["step"], r["columns"], r["factor_gb"])
        its = r["cg_iterations"]
        cells = " ".join(f"{c:,}" for c in r["rank_cells"])
        print(f"{name:>28}" + "".join(f" {v:9.2f}" for v in figures) + f" {its:9.1f}  {peaks}; {cells}")
    if len(a.node_orders) > 1:
        first = a.node_orders[0]
        for p in a.ranks:
            base = runs[(p, first)]
            for o in a.node_orders[1:]:
                step = base["step"] / runs[(p, o)]["step"]
                peak = max(base["peak_gib"]) / max(runs[(p, o)]["peak_gib"])
                print(
                    f"{p} rank(s), node_order {first} / {o}: step time x{step:.2f}, largest peak per rank x{peak:.2f}"
                )
    by = {p: runs[(p, a.node_orders[0])] for p in a.ranks}
    if 1 in by and not a.no_serial:
        print(f"{by[1]['backend']} x1 step / serial {rows[0]['backend']} step: {by[1]['step'] / rows[0]['step']:.2f}")
    if 1 in by:
        for p, r in by.items():
            if p > 1:
                print(f"speed-up per step, {p} ranks against 1: {by[1]['step'] / r['step']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
