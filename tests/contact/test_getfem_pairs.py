"""GetFEM's nodal contact between non-matching meshes as a live reference for contact pairs
(issue 32): two deformable bodies, the same runs by GetFEM 5.4 and by us.

``tests/getfem_reference.py`` (run with the system python, which has Debian's
``python3-getfem``) reads our two-body mesh from a Gmsh 2.2 file and runs it with GetFEM's
own elements, mass and elasticity bricks per region, time schemes (CN = Newmark(1/4, 1/2),
BE = theta 1, A0 = 0) and ``add_nodal_contact_between_nonmatching_meshes_brick`` (one
displacement on both bodies, the slave tag as rg1, the master tag as rg2), whose B_N, gap and
alpha are computed once, at the first assembly, from the reference positions: the pairing and
the master normal are frozen at t = 0, as ours with the solver option pairing = "frozen".  The
script reads the brick's B_N and gaps back (from the tangent matrix and the right-hand side of a
model of the brick alone), so the discrete conditions are compared row by row before the
histories.

Cases: (a) ``bars``: two 2D Q1 bars along y (0.1 x 0.5), the lower one 2 x 10 cells, E = 2,
nu = 0.25, rho = 1, clamped at its bottom; the upper one 3 x 15 cells (slave, the finer
side), E = 1, nu = 0.3, rho = 2, 0.05 above, moving down at 0.5; (b) ``disc``: a P1 disc of
radius 0.25 (``pole_refined_ball``, 74 nodes, its ``cap`` the slave) 0.01 above a clamped
block 1 x 0.3 (master: its top), E = 10 / 20, nu = 0.3 / 0.25, rho = 1 / 2, the disc moving at
(0.1, -0.5).  The block is *triangulated* (``rectangle(..., cell="triangle")``): a signorini
mesh holds one cell type, so a triangle disc on a quadrilateral block cannot be one mesh yet.
Each with the standard mass and ``seed`` (the elements touching a slave or a master node
massless: GetFEM's mass bricks on the other elements only), CN and BE, with our
``follow_mass=False`` and ``initial_acceleration="zero"`` (GetFEM's conventions).

Compared at every time level: the total contact force sum lambda, the mean gap of the slave
rows, the energy 1/2 V.MV + 1/2 U.SU (relative max norms over the run, as tests/dynamics/test_getfem.py),
and also the nodal forces and the gap of every row; and, before the run, the rows of B and the
initial gaps themselves.  Measured: B to 3.3e-16, initial gaps to 7e-18 (the same discrete
problem); the histories to <= 8.1e-13 in every quantity except CN with the standard mass,
1.3e-8 .. 2.8e-8 (bars, disc).  CN with the standard mass makes the contact rattle (the energy
grows 2.3x on the bars by t = 0.8, 15x on the disc), which amplifies round-off by ~10x per
0.1 s: our own run with another direct backend (cholmod against the default) differs from
ours by 1.0e-8 at t = 0.8 and 1.7e-4 at t = 1.5, GetFEM's by 1.3e-8 and 2.6e-4.  So that case
runs the bars to T = 0.8 (the other bar runs to 1.5, past the release).  Tolerances: 1e-11
(about 12x the largest measured) and 1e-6 for CN + standard (36x).

Skipped when /usr/bin/python3 cannot import getfem (``apt-get install python3-getfem``); the
disc also needs gmsh (``pip install ".[mesh]"``).
"""

from __future__ import annotations

import importlib.util
import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from signorini.contact.pairs import ContactPair
from signorini.dynamics.model.problem import Problem, RegionInitial, discretize
from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import join, rectangle, write_mesh
from signorini.fem.space import Dirichlet

SYSTEM_PYTHON = "/usr/bin/python3"
SCRIPT = Path(__file__).parents[1] / "getfem_reference.py"
HAS_GMSH = importlib.util.find_spec("gmsh") is not None
#: GetFEM's Newton: its round-off floor is ~1e-12 here (tests/dynamics/test_getfem.py, friction cases)
GETFEM_SOLVER = {"max_res": 1e-12, "max_iter": 10, "relax": 2, "polish": 2}
MASSES, SCHEMES = ("standard", "seed"), ("cn", "be")
#: (dt, T) per case; CN + standard on the bars only to 0.8 (its rattling amplifies round-off)
TIMES = {"bars": (0.01, 1.5), "disc": (0.004, 0.6)}
SHORT = {("bars", "standard", "cn"): 0.8}
CASES = [(name, m, s) for name in ("bars", "disc") for m in MASSES for s in SCHEMES]
#: relative max norms: measured <= 8.2e-13 (CN + standard: 2.8e-8)
RTOL, RTOL_RATTLE = 1e-11, 1e-6
#: the rows of B and the initial gaps: measured 3.3e-16 (O(1) entries) and 7e-18 (gaps ~0.01-0.05)
ROW_ATOL = 1e-14


def _getfem_importable() -> bool:
    try:
        out = subprocess.run([SYSTEM_PYTHON, "-c", "import getfem"], capture_output=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return out.returncode == 0


def _lame(m: IsotropicElastic) -> dict:
    return {"lam": m.lam, "mu": m.mu, "rho": m.rho}


def bars(path: Path) -> tuple[Problem, dict]:
    """(a) our Problem and GetFEM's case (mesh written to ``path``), without mass/scheme/dt/T."""
    W, L, gap, v = 0.1, 0.5, 0.05, [0.0, -0.5]
    lower, upper = rectangle(2, 10, W, L), rectangle(3, 15, W, L)
    upper.points = upper.points + [0.0, L + gap]
    mesh = join({"lower": lower, "upper": upper})
    write_mesh(mesh, path)
    LOWER, UPPER = IsotropicElastic.from_young(2.0, 0.25, 1.0), IsotropicElastic.from_young(1.0, 0.3, 2.0)
    problem = Problem(mesh, UPPER, None, None, dirichlet=[Dirichlet("lower_ymin", 0.0)], materials={"lower": LOWER},
                      initial_regions=[RegionInitial("upper", velocity=v)],
                      pairs=[ContactPair("upper_ymin", "lower_ymax")], follow_mass=False,
                      initial_acceleration="zero")  # fmt: skip
    case = {"mesh": str(path), "pair": {"slave": "upper_ymin", "master": "lower_ymax"}, "clamp": "lower_ymin",
            "params": _lame(UPPER), "materials": {"lower": _lame(LOWER)}, "velocity": {"upper": v}}  # fmt: skip
    return problem, case


def disc(path: Path) -> tuple[Problem, dict]:
    """(b) a P1 disc (gmsh) on a triangulated clamped block."""
    from signorini.fem.meshing import pole_refined_ball

    ball = pole_refined_ball(2, 0.25, math.radians(60.0), 0.03, 0.08, 0.05)
    ball.points = ball.points + [0.0, 0.01]
    block = rectangle(8, 3, 1.0, 0.3, cell="triangle")
    block.points = block.points - [0.5, 0.3]
    mesh = join({"block": block, "disc": ball})
    write_mesh(mesh, path)
    v = [0.1, -0.5]
    BLOCK, DISC = IsotropicElastic.from_young(20.0, 0.25, 2.0), IsotropicElastic.from_young(10.0, 0.3, 1.0)
    problem = Problem(mesh, DISC, None, None, dirichlet=[Dirichlet("block_ymin", 0.0)], materials={"block": BLOCK},
                      initial_regions=[RegionInitial("disc", velocity=v)],
                      pairs=[ContactPair("disc_cap", "block_ymax")], follow_mass=False,
                      initial_acceleration="zero")  # fmt: skip
    case = {"mesh": str(path), "pair": {"slave": "disc_cap", "master": "block_ymax"}, "clamp": "block_ymin",
            "params": _lame(DISC), "materials": {"block": _lame(BLOCK)}, "velocity": {"disc": v}}  # fmt: skip
    return problem, case


def _times(key: tuple) -> tuple[float, float]:
    dt, T = TIMES[key[0]]
    return dt, SHORT.get(key, T)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """GetFEM's histories of every case (one run of the script), and our problems."""
    if not _getfem_importable():
        pytest.skip("python3-getfem not installed: apt-get install python3-getfem")
    folder = tmp_path_factory.mktemp("getfem_pairs")
    problems = {"bars": bars(folder / "bars.msh")}
    if HAS_GMSH:
        problems["disc"] = disc(folder / "disc.msh")
    keys = [k for k in CASES if k[0] in problems]
    cases = []
    for key in keys:
        dt, T = _times(key)
        cases.append({**problems[key[0]][1], "mass": key[1], "scheme": key[2], "dt": dt, "T": T,
                      "solver": GETFEM_SOLVER})  # fmt: skip
    out = subprocess.run(
        [SYSTEM_PYTHON, str(SCRIPT), "-"], input=json.dumps({"cases": cases}), capture_output=True, text=True,
        timeout=600,
    )  # fmt: skip
    assert out.returncode == 0, f"getfem_reference.py failed:\n{out.stderr[-4000:]}"
    runs: dict = {k: [] for k in keys}
    for line in out.stdout.splitlines():
        row = json.loads(line)
        runs[keys[row["case"]]].append(row)
    return runs, problems


def relative(ours: np.ndarray, theirs: np.ndarray) -> float:
    """max |ours - theirs| / max |theirs| over all time levels (and rows)."""
    return float(np.max(np.abs(ours - theirs)) / np.max(np.abs(theirs)))


def compare(key: tuple, reference) -> dict[str, float]:
    """Our run of ``key`` against GetFEM's: the rows of B and the initial gaps (absolute), then
    the histories (relative max norms)."""
    runs, problems = reference
    name, mass, scheme = key
    problem = problems[name][0]
    header, rows = runs[key][0], runs[key][1:]
    assert header["inert_rows"] == [], "GetFEM paired a slave node with no master face"
    d = discretize(problem, mass)
    np.testing.assert_array_equal(d.contact.nodes, header["pair_nodes"])
    theirs_B = np.zeros(d.B.shape)
    theirs_B[header["B"]["rows"], header["B"]["cols"]] = header["B"]["vals"]
    dt, T = _times(key)
    # GetFEM's brick pairs once, at t = 0: signorini's pairing='frozen' (its default re-pairs slave
    # nodes that slide off their master facet)
    H = simulate(problem, scheme, dt, T, mass=mass, solver_options={"pairing": "frozen"})
    assert H.success, H.message
    assert len(rows) == H.t.size
    assert all(r["converged"] for r in rows), "GetFEM's Newton did not converge at some step"
    np.testing.assert_array_equal(H.nodes, header["pair_nodes"])
    col = lambda k: np.array([r[k] for r in rows])  # noqa: E731
    assert col("lambda_sum").min() < 0, "no contact in the run: nothing compared"
    return {
        "B": float(np.abs(d.B.toarray() - theirs_B).max()),
        "initial gaps": float(np.abs(d.contact.gaps - np.array(header["gap0"])).max()),
        "force": relative(H.lambda_sum, col("lambda_sum")),
        "mean gap": relative(H.gap.mean(axis=1), col("mean_gap")),
        "energy": relative(H.energy, col("energy")),
        "nodal forces": relative(H.lam, col("lambda")),
        "gaps": relative(H.gap, col("gap")),
    }


def _id(key: tuple) -> str:
    return "-".join(key)


@pytest.mark.parametrize(
    "key",
    [pytest.param(k, id=_id(k), marks=[] if k[0] == "bars" else [pytest.mark.skipif(
        not HAS_GMSH, reason='the disc needs gmsh: pip install ".[mesh]"')]) for k in CASES],
)  # fmt: skip
def test_pairs_agree_with_getfem_nonmatching_contact(key, reference):
    diff = compare(key, reference)
    rows = {k: diff.pop(k) for k in ("B", "initial gaps")}
    assert max(rows.values()) <= ROW_ATOL, rows
    tol = RTOL_RATTLE if key[1:] == ("standard", "cn") else RTOL
    assert max(diff.values()) <= tol, diff
