"""Every registered scheme on a distributed backend, run under mpiexec by tests/linalg/test_petsc_run.py.

``mpiexec -n P python tests/mpi_schemes.py OUT.json [BACKEND]``: each scheme integrates
bar3d n = 2 (40 steps through the impact, standard mass, which every scheme takes) with
backend BACKEND (``petsc``, the default, or ``petsc-cg``); rank 0 writes, per scheme, the
energy, the total contact force and the smallest gap at every level, or the refusal message.
"""

from __future__ import annotations

import json
import sys

from signorini.dynamics.schemes import SCHEMES
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.parallel import MPIComm
from signorini.studies.benchmarks import get_benchmark

STEPS, DT = 40, 0.0125


def series(backend: str) -> dict:
    problem = get_benchmark("bar3d").problem(2)
    out = {}
    for entry in SCHEMES:
        try:
            H = simulate(problem, entry.name, DT, STEPS * DT, mass="standard", solver_options={"backend": backend})
        except InputError as exc:
            out[entry.name] = {"refused": str(exc)}
            continue
        out[entry.name] = {"status": H.status, "energy": H.energy.tolist(), "lambda_sum": H.lam.sum(axis=1).tolist(),
                           "gap_min": H.gap.min(axis=1).tolist()}  # fmt: skip
    return out


if __name__ == "__main__":
    result = series(sys.argv[2] if len(sys.argv) > 2 else "petsc")
    if MPIComm().is_root:
        with open(sys.argv[1], "w") as f:
            json.dump(result, f)
