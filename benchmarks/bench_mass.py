"""Set-up cost of the mass variants on a ball with its whole skin in contact (issue 21).

Usage: python benchmarks/bench_mass.py [n ...]   (default 9: hertz3d with skin=1, 35,631 dofs)

In one process, for each mass variant: the time of ``discretize`` (assembly of S, the
mass variant, loads, contact set and the variant's mass_effect), best of 3; the whole
set-up of a CN run (discretize, factorization, level 0: ``simulate`` of one step, its
``setup_seconds`` plus discretize) and the time per step of 20 steps; their ratios to
``seed`` on the same mesh; and the nonzeros of M against the consistent mass.
"""

import sys
import time

VARIANTS = ("standard", "seed", "moment-preserving", "neighbour", "mass-free-surface")


def one(n: int) -> list[dict]:
    from signorini.dynamics.model.mass_effect import mass_effect
    from signorini.dynamics.model.problem import discretize
    from signorini.dynamics.stepping.simulate import simulate
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark("hertz3d")
    problem = b.problem(n, {"skin": 1.0})
    dt = b.run_times(n, {"skin": 1.0})[0]
    rows = []
    for name in VARIANTS:
        best, effect = float("inf"), float("inf")
        for _ in range(3):
            t0 = time.perf_counter()
            disc = discretize(problem, name)
            best = min(best, time.perf_counter() - t0)
            t1 = time.perf_counter()
            mass_effect(disc.M, problem.mesh, problem.material.rho)
            effect = min(effect, time.perf_counter() - t1)
        t0 = time.perf_counter()
        H = simulate(problem, "cn", dt, 20 * dt, mass=name)
        run_setup = time.perf_counter() - t0 - H.meta["loop_seconds"]
        rows.append(
            {
                "mass": name,
                "dofs": disc.space.n_dofs,
                "contact": disc.contact.size,
                "setup": best,
                "effect": effect,
                "nnz": disc.M.nnz,
                "mass_ratio": disc.mass_effect["mass_ratio"],
                "run_setup": run_setup,
                "step": H.meta["step_seconds"],
                "backend": H.meta["backend"],
            }
        )
    base = next(r for r in rows if r["mass"] == "seed")
    std = next(r for r in rows if r["mass"] == "standard")
    for r in rows:
        r["setup_vs_seed"] = r["setup"] / base["setup"]
        r["run_setup_vs_seed"] = r["run_setup"] / base["run_setup"]
        r["step_vs_seed"] = r["step"] / base["step"]
        r["nnz_vs_standard"] = r["nnz"] / std["nnz"]
    return rows


def main(argv: list[str]) -> int:
    sizes = [int(a) for a in argv] or [9]
    print(
        "| n | dofs | contact nodes | mass | discretize [s] (vs seed) | of which mass_effect [s] "
        "| run set-up [s] (vs seed) | step [ms] (vs seed) | backend | nnz(M) / consistent | mass kept |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for n in sizes:
        for r in one(n):
            print(
                f"| {n} | {r['dofs']} | {r['contact']} | {r['mass']} | {r['setup']:.3f} ({r['setup_vs_seed']:.2f}) | "
                f"{r['effect']:.3f} | {r['run_setup']:.2f} ({r['run_setup_vs_seed']:.2f}) | "
                f"{1e3 * r['step']:.1f} ({r['step_vs_seed']:.2f}) | {r['backend']} | {r['nnz_vs_standard']:.2f} | "
                f"{r['mass_ratio']:.6f} |"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
