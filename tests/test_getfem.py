"""GetFEM as a live reference (issue 24, item 6): the same runs by GetFEM 5.4 and by us.

``tests/getfem_reference.py`` (run with the system python, which has Debian's
``python3-getfem``) rebuilds the seed paper's bars (and the Hertz disc and ball from our
gmsh meshes, written to .msh files) with GetFEM's own elements, bricks, nodal contact
with a rigid obstacle (Alart-Curnier augmented Lagrangian, Newton's method of
Model.solve at every step) and time schemes.  Both runs discretize identically (same
nodes, Q1/P1 elements with exact integration, the same mass variant: ``standard`` or
``seed`` = GetFEM's singular_mass = 1; CN = Newmark(1/4, 1/2), BE = theta 1), so they
must agree to round-off.

Compared at every time level t_0 .. t_N: the total contact force sum_i lambda_i, the
nodal forces lambda_i, the contact nodes' gap g_i - nu_i.u_i (GetFEM: x_d + u_d) and the
energy 1/2 V.MV + 1/2 U.SU.  Norm: the relative max norm over the run,
max_{n,i} |ours - GetFEM| / max_{n,i} |GetFEM|, asserted <= 1e-8.  Measured: CN + standard
mass 3e-12 to 6e-11 on the bars (its contact force oscillates and its energy grows 1.5-3.5
times: round-off differences grow with it), every other bar case <= 7e-13, the Hertz
cases <= 3e-13.  GetFEM's Newton is asked for a residual of 1e-13, but the agreement does
not depend on it (nor on the augmentation r): the nodal Alart-Curnier equations are
piecewise linear, so once the active set is right the iterate is exact up to round-off
(1 to 8 iterations per step); max_res = 1e-6 gives the same 4e-13 on bar2d n = 4 + seed.

Skipped when /usr/bin/python3 cannot import getfem (``apt-get install python3-getfem``);
the Hertz cases also need gmsh (``pip install ".[mesh]"``).
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from signorini.dynamics.simulate import simulate
from signorini.fem.mesh import write_mesh
from signorini.studies.benchmarks import get_benchmark

SYSTEM_PYTHON = "/usr/bin/python3"
SCRIPT = Path(__file__).with_name("getfem_reference.py")
RTOL = 1e-8
MASSES, SCHEMES = ("standard", "seed"), ("cn", "be")
BARS = [
    (b, n, m, s) for b, n in (("bar2d", 2), ("bar2d", 4), ("bar3d", 1), ("bar3d", 2)) for m in MASSES for s in SCHEMES
]
HERTZ = [("hertz2d", 2, m, s) for m in MASSES for s in SCHEMES]
HERTZ += [("hertz3d", 1, "seed", "cn"), ("hertz3d", 1, "standard", "be")]
HAS_GMSH = importlib.util.find_spec("gmsh") is not None


def _getfem_importable() -> bool:
    try:
        out = subprocess.run([SYSTEM_PYTHON, "-c", "import getfem"], capture_output=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return out.returncode == 0


def _times(name: str, n: int) -> tuple[float, float]:
    """(dt, T): h/2 and 1 for the bars (first impact at 0.4, release near 0.9); the Hertz
    runs' defaults t_c/(25 n) and 1.5 t_c."""
    b = get_benchmark(name)
    return (b.h(n) / 2, 1.0) if name.startswith("bar") else b.run_times(n)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """GetFEM's histories of every case (one run of the script), and the Hertz problems."""
    if not _getfem_importable():
        pytest.skip("python3-getfem not installed: apt-get install python3-getfem")
    folder = tmp_path_factory.mktemp("getfem")
    cases, keys, problems = [], [], {}
    for name, n, mass, scheme in BARS:
        dt, T = _times(name, n)
        cases.append({"benchmark": name, "n": n, "mass": mass, "scheme": scheme, "dt": dt, "T": T})
        keys.append((name, n, mass, scheme))
    for name, n, mass, scheme in HERTZ if HAS_GMSH else ():
        path = folder / f"{name}-{n}.msh"
        if (name, n) not in problems:  # our mesh, shared with GetFEM through a Gmsh file
            problems[name, n] = get_benchmark(name).problem(n)
            write_mesh(problems[name, n].mesh, path)
        mat, (dt, T) = problems[name, n].material, _times(name, n)
        params = {"lam": mat.lam, "mu": mat.mu, "rho": mat.rho, "velocity": get_benchmark(name).params()["velocity"]}
        body = {"mesh": str(path), "contact": "cap", "params": params}
        cases.append({**body, "mass": mass, "scheme": scheme, "dt": dt, "T": T})
        keys.append((name, n, mass, scheme))
    out = subprocess.run(
        [SYSTEM_PYTHON, str(SCRIPT), "-"],
        input=json.dumps({"cases": cases}),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, f"getfem_reference.py failed:\n{out.stderr[-4000:]}"
    runs: dict = {}
    for line in out.stdout.splitlines():
        row = json.loads(line)
        runs.setdefault(keys[row["case"]], []).append(row)
    return runs, problems


def relative(ours: np.ndarray, theirs: np.ndarray) -> float:
    """max |ours - theirs| / max |theirs| over all time levels (and contact nodes)."""
    return float(np.max(np.abs(ours - theirs)) / np.max(np.abs(theirs)))


def compare(key: tuple, reference) -> dict[str, float]:
    """Our run of ``key`` against GetFEM's: relative differences of force, nodal forces, gap, energy."""
    runs, problems = reference
    name, n, mass, scheme = key
    dt, T = _times(name, n)
    problem = problems.get((name, n)) or get_benchmark(name).problem(n)
    H = simulate(problem, scheme, dt, T, mass=mass)
    assert H.success, H.message
    header, rows = runs[key][0], runs[key][1:]
    assert len(rows) == H.t.size
    assert all(r["converged"] for r in rows), "GetFEM's Newton did not reach its residual at some step"
    points = np.array(header["contact_points"])
    np.testing.assert_allclose(points, H.coordinates, rtol=0, atol=1e-15)
    force = np.array([r["lambda_sum"] for r in rows])
    assert force.min() < 0, "no contact in the run: nothing compared"
    gap = points[:, -1][None, :] + np.array([r["normal_displacement"] for r in rows])  # x_d + u_d
    return {
        "force": relative(H.lambda_sum, force),
        "nodal forces": relative(H.lam, np.array([r["lambda"] for r in rows])),
        "gap": relative(H.gap, gap),
        "energy": relative(H.energy, np.array([r["energy"] for r in rows])),
    }


@pytest.mark.parametrize("key", BARS, ids=["-".join(map(str, k)) for k in BARS])
def test_bars_agree_with_getfem(key, reference):
    diff = compare(key, reference)
    assert max(diff.values()) <= RTOL, diff


@pytest.mark.skipif(not HAS_GMSH, reason='the Hertz meshes need gmsh: pip install ".[mesh]"')
@pytest.mark.parametrize("key", HERTZ, ids=["-".join(map(str, k)) for k in HERTZ])
def test_hertz_agrees_with_getfem(key, reference):
    diff = compare(key, reference)
    assert max(diff.values()) <= RTOL, diff
