"""3D set-up and step time of each direct backend and ordering, on the plain install and with the extras.

Usage (from the repository root)::

    python -m benchmarks.bench_plain3d --prepare                 # needs gmsh: writes the cases once
    python -m benchmarks.bench_plain3d --runs this:auto this:superlu:nd this:cholmod:metis this:pardiso
    python -m benchmarks.bench_plain3d --python plain=/tmp/v/bin/python extras=python3 --repeat 2

Cases: ``hertz3d-9`` (the benchmark's ball at n = 9, about 34k dofs, pickled so that an
install without gmsh can run it) and ``bracket-35k`` (``examples/bracket_drop.toml`` on the
bracket of ``examples/meshes/make_parts.py`` meshed at size 0.0043 m: about 35k dofs,
its whole skin in contact).  Variants: ``BACKEND`` or ``BACKEND:ORDERING`` (``ordering``
of :func:`signorini.linalg.ordering.fill_reducing_order`: metis, nd, ...); ``auto`` is
what a run chooses.  Each (case, variant) runs in a fresh process of its install's
interpreter (``--python``), CN for ``--steps`` steps; it prints the backend and ordering
used, the set-up as a run reports it (assembly, factorization, the Delassus columns
computed before the loop), the time per step as a run reports it (without the lazy
columns computed inside the loop, whose time is printed apart and counted in the total),
and the largest difference of the contact-force and energy histories against the first
run's.  Writes ``plain3d.json`` and the table of medians and ratios ``plain3d.md`` into
``--out``.
"""

from __future__ import annotations

import argparse
import json
import pickle
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

CACHE = Path("out/bench/plain3d")
ROOT = Path(__file__).resolve().parents[1]
BRACKET_H = 0.0043  # about 11.6k nodes, 35k dofs
CASES = ("hertz3d-9", "bracket-35k")


def prepare(cache: Path = CACHE) -> None:
    """Write the cases: the Hertz ball's Problem (pickled) and the fine bracket's mesh and case file."""
    import gmsh

    from signorini.studies.benchmarks import get_benchmark

    cache.mkdir(parents=True, exist_ok=True)
    b = get_benchmark("hertz3d")
    dt, _ = b.run_times(9)
    with open(cache / "hertz3d-9.pkl", "wb") as fh:  # the mesh: the Problem holds closures
        pickle.dump({"mesh": b.problem(9).mesh, "dt": dt}, fh)

    gmsh.initialize(["-noenv"], readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.option.setNumber("Mesh.RandomSeed", 1)
    occ = gmsh.model.occ
    gmsh.model.add("bracket")
    box = occ.addBox(0, 0, 0, 0.2, 0.1, 0.05)
    h1 = occ.addCylinder(0.05, 0.05, -0.01, 0, 0, 0.07, 0.02)
    h2 = occ.addCylinder(0.15, 0.05, -0.01, 0, 0, 0.07, 0.02)
    occ.cut([(3, box)], [(3, h1), (3, h2)])
    occ.synchronize()
    body = gmsh.model.getEntities(3)
    skin = [t for _, t in gmsh.model.getBoundary(body, combined=True, oriented=False)]
    gmsh.model.addPhysicalGroup(3, [t for _, t in body], name="body")
    gmsh.model.addPhysicalGroup(2, skin, name="skin")
    gmsh.option.setNumber("Mesh.MeshSizeMax", BRACKET_H)
    gmsh.option.setNumber("Mesh.MeshSizeMin", BRACKET_H / 2)
    gmsh.model.mesh.generate(3)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write(str(cache / "bracket-35k.msh"))
    gmsh.finalize()
    text = (ROOT / "examples" / "bracket_drop.toml").read_text()
    text = text.replace('"meshes/bracket.msh"', '"bracket-35k.msh"')
    (cache / "bracket-35k.toml").write_text(text)
    print(f"cases written to {cache}")


def load(case: str, cache: Path) -> tuple:
    """(problem, dt, mass) of a case."""
    if case == "hertz3d-9":
        from signorini.studies import hertz
        from signorini.studies.benchmarks import get_benchmark

        with open(cache / "hertz3d-9.pkl", "rb") as fh:
            data = pickle.load(fh)
        hertz.pole_refined_ball = lambda *args: data["mesh"]  # the ball gmsh made at --prepare
        return get_benchmark("hertz3d").problem(9), data["dt"], "seed"
    if case == "bracket-35k":
        from signorini.io.config import load_case

        c = load_case(cache / "bracket-35k.toml")
        return c.problem, c.dt, c.mass
    raise SystemExit(f"unknown case {case!r}; known: {', '.join(CASES)}")


def measure(case: str, variant: str, steps: int, cache: Path) -> dict:
    """One (case, variant) in this process."""
    from signorini.dynamics.model.problem import discretize
    from signorini.dynamics.stepping.simulate import simulate
    from signorini.linalg import ordering

    backend, _, order = variant.partition(":")
    if order:
        ordering.ORDERING = order
    problem, dt, mass = load(case, cache)
    t0 = time.perf_counter()
    disc = discretize(problem, mass)
    t_disc = time.perf_counter() - t0
    used: list[str] = []
    chooser = ordering.fill_reducing_order

    def spy(A, method=None):
        perm, name = chooser(A) if method is None else chooser(A, method)  # an older install: no method
        used.append(name)
        return perm, name

    ordering.fill_reducing_order = spy
    H = simulate(disc, "cn", dt, steps * dt, solver_options={"backend": backend})
    m = H.meta
    in_loop = m.get("in_loop_condensation_seconds", 0.0)
    return {
        "case": case,
        "variant": variant,
        "dofs": m["free_dofs"],
        "contact_nodes": m["contact_nodes"],
        "backend": m["backend"],
        "ordering": used[-1] if used else "own",
        "discretize_s": t_disc,
        "factorization_s": m["factorization_seconds"],
        "columns_s": m["condensation_seconds"],
        "columns": H.counters.get("delassus_columns", 0),
        "setup_s": t_disc + m["setup_seconds"],  # before the loop, as a run reports it
        "in_loop_columns_s": in_loop,
        "step_ms": 1e3 * m["step_seconds"],  # without the columns computed in the loop
        "total_s": t_disc + m["setup_seconds"] + H.steps * m["step_seconds"] + in_loop,
        "factor_MB": m["factor_bytes"] / 1e6,
        "steps": H.steps,
        "lam": np.asarray(H.lam).tolist(),
        "energy": np.asarray(H.energy).tolist(),
    }


def run(python: str, case: str, variant: str, steps: int, cache: Path) -> dict:
    cmd = [python, "-m", "benchmarks.bench_plain3d", "--one", case, variant, "--steps", str(steps)]
    cmd += ["--cache", str(cache)]
    out = subprocess.check_output(cmd, cwd=ROOT).decode()
    return json.loads(out.strip().splitlines()[-1])


def _row_text(r: dict) -> str:
    return (
        f"{r['install']} {r['case']} {r['variant']}: {r['dofs']} dofs, {r['contact_nodes']} contact nodes, "
        f"{r['backend']} + {r['ordering']}, set-up {r['setup_s']:.2f} s (factor {r['factorization_s']:.2f}), "
        f"{r['columns']} columns ({r['in_loop_columns_s']:.2f} s in the loop), {r['step_ms']:.1f} ms/step, "
        f"total {r['total_s']:.1f} s, factor {r['factor_MB']:.0f} MB, histories differ by {r['lam_diff']:.1e} "
        f"(contact force) / {r['energy_diff']:.1e} (energy)"
    )


def summarize(rows: list[dict], best: str) -> list[str]:
    """Markdown: the median of the repeats per (case, install, variant) and the ratios to the
    fastest run of the install ``best`` (set-up, step and total each to its own fastest)."""
    md = [
        "| case | install | variant | backend + ordering | set-up s | ms/step | columns in loop s | total s | "
        "set-up / best | step / best | total / best | histories differ by |",
        "|" + "---|" * 12,
    ]
    for case in dict.fromkeys(r["case"] for r in rows):
        keys = list(dict.fromkeys((r["install"], r["variant"]) for r in rows if r["case"] == case))
        med = {}
        for key in keys:
            sel = [r for r in rows if r["case"] == case and (r["install"], r["variant"]) == key]
            figures = ("setup_s", "step_ms", "in_loop_columns_s", "total_s")
            med[key] = {k: float(np.median([r[k] for r in sel])) for k in figures}
            med[key].update(name=f"{sel[0]['backend']} + {sel[0]['ordering']}", n=len(sel))
            med[key]["diff"] = max(max(r["lam_diff"], r["energy_diff"]) for r in sel)
        ref = [m for (install, _), m in med.items() if install == best] or list(med.values())
        s0, t0, a0 = (min(m[k] for m in ref) for k in ("setup_s", "step_ms", "total_s"))
        for (install, variant), m in med.items():
            md.append(
                f"| {case} | {install} | {variant} | {m['name']} | {m['setup_s']:.2f} | {m['step_ms']:.1f} | "
                f"{m['in_loop_columns_s']:.1f} | {m['total_s']:.1f} | {m['setup_s'] / s0:.2f} | "
                f"{m['step_ms'] / t0:.2f} | {m['total_s'] / a0:.2f} | {m['diff']:.1e} |"
            )
    return md


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_plain3d", description=__doc__.split("\n\n")[0])
    ap.add_argument("--prepare", action="store_true", help="write the cases (needs gmsh)")
    ap.add_argument("--cases", nargs="+", default=list(CASES))
    ap.add_argument(
        "--python",
        nargs="+",
        default=[f"this={sys.executable}"],
        metavar="INSTALL=PATH",
        help="the interpreters of the installs compared (default: this one, named 'this')",
    )
    ap.add_argument(
        "--runs",
        nargs="+",
        default=None,
        metavar="INSTALL:VARIANT",
        help="what to run, in this order (default: auto on every install); VARIANT is BACKEND[:ORDERING]",
    )
    ap.add_argument("--best", default="extras", help="the install whose fastest run the ratios divide by")
    ap.add_argument("--repeat", type=int, default=1, help="runs of the whole sequence (the table takes medians)")
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--cache", type=Path, default=CACHE)
    ap.add_argument("--out", type=Path, default=Path("out/bench"))
    ap.add_argument("--one", nargs=2, metavar=("CASE", "VARIANT"), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.prepare:
        prepare(a.cache)
        return 0
    if a.one:
        print(json.dumps(measure(a.one[0], a.one[1], a.steps, a.cache)))
        return 0
    pythons = dict(item.split("=", 1) for item in a.python)
    runs = [r.split(":", 1) for r in (a.runs or [f"{tag}:auto" for tag in pythons])]
    rows = []
    for _ in range(a.repeat):
        for case in a.cases:
            first = None
            for install, variant in runs:
                r = run(pythons[install], case, variant, a.steps, a.cache)
                r["install"] = install
                lam, energy = np.asarray(r.pop("lam")), np.asarray(r.pop("energy"))
                if first is None:
                    first = (lam, energy)
                r["lam_diff"] = float(np.abs(lam - first[0]).max() / max(np.abs(first[0]).max(), 1e-300))
                r["energy_diff"] = float(np.abs(energy - first[1]).max() / max(np.abs(first[1]).max(), 1e-300))
                rows.append(r)
                print(_row_text(r), flush=True)
    md = summarize(rows, a.best)
    print("\n".join(md))
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "plain3d.json").write_text(json.dumps(rows, indent=1))
    (a.out / "plain3d.md").write_text("\n".join(md) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
