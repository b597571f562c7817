"""Our time per step against GetFEM 5.4's on the same finite-strain problem (issue 51's performance line).

    python -m benchmarks.bench_getfem [--n 2] [--model neo-hookean] [--steps 40] [--scheme crank-nicolson]
                                      [--backend auto]

The seed paper's 3D bar (``bar3d`` at level n: clamped on top, dropped on the plane) with a finite-strain law and
the consistent mass, the first ``--steps`` levels of the benchmark's step (through the impact), solved by
signorini in this process and by GetFEM's own Newton (its finite strain elasticity brick, its Newmark scheme 1/4,
1/2 or theta = 1, its nodal contact brick with an augmented Lagrangian; ``tests/getfem_reference.py`` run by
Debian's ``/usr/bin/python3``, which has ``python3-getfem``).  Printed: each one's median step (GetFEM's Newton and
shift timed in its script, ours the step of :class:`~signorini.dynamics.stepping.simulate.Stepper`, with
``tangent=modified``, the default, and ``full``), their ratio (issue 51 asks at most 0.1 with Crank-Nicolson), the
Newton iterations, and the largest difference of the two contact-force histories relative to their largest value
(a check that both solved the same problem; GetFEM's Newton stops at ``max_res`` 1e-10 of its load, ours at
``newton_tol``).  Without ``python3-getfem``: a message, exit 0.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
from pathlib import Path

import numpy as np

from benchmarks import median_step

SYSTEM_PYTHON = "/usr/bin/python3"
SCRIPT = Path(__file__).resolve().parents[1] / "tests" / "getfem_reference.py"
SCHEMES = {"crank-nicolson": "cn", "backward-euler": "be"}


def getfem_available() -> bool:
    try:
        return subprocess.run([SYSTEM_PYTHON, "-c", "import getfem"], capture_output=True, timeout=60).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def ours(
    n: int, model: str, steps: int, scheme: str, tangent: str, backend: str = "auto"
) -> tuple[float, np.ndarray, float]:
    """(median step [s], the contact force sum_i lambda_i at each level, Newton iterations a step) with the solver
    option ``tangent``."""
    from signorini.dynamics.stepping.simulate import Stepper
    from signorini.fem.material import with_model
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark("bar3d")
    dt = b.run_times(n)[0]
    p = b.problem(n)
    p = dataclasses.replace(p, material=with_model(p.material, model))
    options = {"mass": "standard", "solver_options": {"tangent": tangent, "backend": backend}}
    s = Stepper(p, scheme, (dt, steps * dt), options)
    step = median_step(s)
    H = s.finish()
    return step, np.asarray(H.lambda_sum), float(np.nanmean(H.nonlinear_iterations[1:]))


def getfem(n: int, model: str, steps: int, scheme: str) -> tuple[dict, list[dict]]:
    """GetFEM's header and rows (level 0 first) of the same run."""
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark("bar3d")
    dt = b.run_times(n)[0]
    case = {"benchmark": "bar3d", "n": n, "mass": "standard", "scheme": SCHEMES[scheme], "dt": dt, "T": steps * dt,
            "model": model, "params": {k: v for k, v in b.params({}).items() if k in ("rho", "lam", "mu")}}  # fmt: skip
    spec = {"cases": [case], "solver": {"max_res": 1e-10}}
    out = subprocess.run([SYSTEM_PYTHON, str(SCRIPT), "-"], input=json.dumps(spec), capture_output=True, text=True,
                         timeout=3600, check=False)  # fmt: skip
    if out.returncode != 0:
        raise RuntimeError(f"getfem_reference.py failed:\n{out.stderr[-2000:]}")
    lines = [json.loads(line) for line in out.stdout.splitlines()]
    return lines[0], lines[1:]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2)
    ap.add_argument("--model", default="neo-hookean", choices=["neo-hookean", "saint-venant-kirchhoff", "linear"])
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--scheme", default="crank-nicolson", choices=list(SCHEMES))
    ap.add_argument("--backend", default="auto", help="our linear solver backend (default auto)")
    args = ap.parse_args(argv)
    if not getfem_available():
        print(f"GetFEM: skipped ({SYSTEM_PYTHON} cannot import getfem: apt-get install python3-getfem)")
        return 0
    header, rows = getfem(args.n, args.model, args.steps, args.scheme)
    theirs = float(np.median([r["seconds"] for r in rows[1:]]))
    lam_g = np.array([r["lambda_sum"] for r in rows])
    result = {"case": f"bar3d n = {args.n}, {args.model}, {args.scheme}, standard mass, {args.steps} steps",
              "getfem": header.get("getfem"), "getfem_step_s": theirs,
              "getfem_newton_per_step": float(np.mean([r["newton_iterations"] for r in rows[1:]])),
              "getfem_converged": all(r["converged"] for r in rows[1:])}  # fmt: skip
    for tangent in ("modified", "full"):
        step, lam, newton = ours(args.n, args.model, args.steps, args.scheme, tangent, args.backend)
        diff = float(np.abs(lam - lam_g).max() / max(np.abs(lam_g).max(), np.abs(lam).max(), 1e-300))
        result[tangent] = {"step_s": step, "over_getfem": step / theirs, "newton_per_step": newton,
                           "contact_force_difference": diff}  # fmt: skip
    print(json.dumps(result, indent=1))
    for tangent in ("modified", "full"):
        r = result[tangent]
        print(f"{result['case']}, tangent={tangent}: our step {1e3 * r['step_s']:.2f} ms against GetFEM "
              f"{result['getfem']}'s {1e3 * theirs:.2f} ms (x{r['over_getfem']:.3f}; Newton {r['newton_per_step']:.2f} "
              f"against {result['getfem_newton_per_step']:.2f} iterations a step); the contact forces differ by "
              f"{r['contact_force_difference']:.1e} of their largest")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
