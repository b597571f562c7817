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

With friction and gravity (issue 31, item 4; the second half of this file): the block of
``incline2d``/``incline3d`` sliding, sticking and dropped obliquely onto the plane, Coulomb
friction, with our ``follow_mass=False`` and ``initial_acceleration="zero"`` (GetFEM's
conventions) and GetFEM's nodal friction on the slip of the step (its basic contact brick
with wt = U^n, gamma = -1).  Compared as well: the contact force's global components, the
nodal tangential forces, the slips, the three energy parts.  Measured <= 1e-9 (table in
docs/verification.md); GetFEM's own frictional rigid-obstacle brick is another law (slip
measured from t = 0) and differs as soon as a node sticks away from where it started.

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

from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.mesh import write_mesh
from signorini.studies.benchmarks import get_benchmark

SYSTEM_PYTHON = "/usr/bin/python3"
SCRIPT = Path(__file__).parents[1] / "getfem_reference.py"
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


# ----------------------------------------------------------------------------- friction and gravity
# Issue 31, item 4: with GetFEM's two conventions, Problem(follow_mass=False) (a body force is
# the consistent load int rho g phi whatever the mass) and initial_acceleration="zero" (A0 = 0),
# GetFEM's runs of the same discretization with Coulomb friction and gravity are ours to 1e-8.
#
# Cases (kind, dim, n, mass, scheme, T), dt = 0.02 / n (the inclines' default), on the block of
# incline2d/incline3d (1 x 0.25 (x 1), E = 1000, nu = 0.3, rho = 1, 4n x 2n (x 4n) Q1 cells):
#   slide   incline{d}d as it is: tilted gravity g (sin 30, -cos 30), Coulomb 0.3 < tan 30, from
#           rest on the plane y = 0: gross slip down the slope
#   stick   the same with mu = 0.7 > tan 30: it sticks (with CN and the standard mass it rocks
#           and chatters instead: chaotic, so T = 0.5; docs/verification.md)
#   drop    gravity (0, -1) (angle 0), v0 = (0.5, -0.5) (3D: (0.5, 0.25, -0.5)), the plane 0.02
#           below: an oblique impact, then slip, stick and (CN) bouncing
#   drop0   the drop without friction (GetFEM's frictionless brick: gravity and A0 only)
FRICTION = [
    *[("slide", 2, 2, m, s, 1.0) for m in MASSES for s in SCHEMES],
    ("slide", 3, 1, "standard", "be", 1.0),
    ("slide", 3, 1, "seed", "cn", 1.0),
    ("stick", 2, 2, "seed", "be", 1.0),
    ("stick", 2, 2, "standard", "cn", 0.5),
    *[("drop", 2, 1, m, s, 1.0) for m in MASSES for s in SCHEMES],
    ("drop", 2, 2, "standard", "be", 2.0),
    ("drop", 3, 1, "seed", "be", 1.0),
    ("drop0", 2, 1, "seed", "cn", 1.0),
    ("drop0", 2, 1, "standard", "be", 1.0),
]
#: longer ones (``-m slow``): 3D at n = 2 (GetFEM's assembly makes them ~15 s each), n = 4, T = 2 in 2D
SLOW_FRICTION = [
    ("slide", 3, 2, "standard", "cn", 1.0),
    ("slide", 3, 2, "seed", "be", 1.0),
    ("slide", 2, 4, "seed", "be", 2.0),
    ("slide", 2, 4, "standard", "be", 2.0),
    ("drop", 2, 2, "seed", "be", 2.0),
    ("drop", 3, 1, "standard", "cn", 1.0),
]
#: GetFEM's own frictional rigid-obstacle brick (its law acts on B_T u, the displacement since t = 0)
TOTAL_SLIP = [
    ("slide", 2, 2, "seed", "be", 1.0),
    ("drop", 2, 1, "standard", "be", 2.0),
    ("stick", 2, 2, "seed", "be", 1.0),
]
#: GetFEM's Newton target is min(|residual|_1 / |load|_1, |dU|_1 / |U|_1) <= max_res, where the
#: "load" includes the scheme's inertia terms M U^n / (beta dt^2).  Its round-off floor is 1e-12 to
#: 1e-11 on these runs (a sliding block's |U| is mostly its rigid motion; an impact's forces are
#: ~100 times the gravity load), where Newton hops between iterates and, after 20, restarts from
#: its first guess.  So a step that does not reach 1e-12 is solved again from the same guess to
#: 1e-11, then 1e-10 (``relax``; every step must converge), and is followed by 2 Newton steps
#: without a test (``polish``: in 3D the disc projection is not piecewise linear, and an iterate
#: accepted at 1e-11 was off by 7e-10 in the nodal tangential forces).
GETFEM_FRICTION_SOLVER = {"max_res": 1e-12, "max_iter": 10, "r": 1000.0, "relax": 2, "polish": 2}
DROP = {"gap": 0.02, "v0": {2: [0.5, -0.5], 3: [0.5, 0.25, -0.5]}}


def friction_problem(kind: str, dim: int, n: int, **conventions):
    """(our Problem, GetFEM's case without mass/scheme/dt/T) of a friction case; the Problem
    with GetFEM's conventions unless ``conventions`` say otherwise."""
    import dataclasses

    from signorini.contact.obstacles import PlaneObstacle
    from signorini.studies import incline

    overrides = {"slide": {}, "stick": {"mu": 0.7}, "drop": {"angle": 0.0}, "drop0": {"angle": 0.0}}[kind]
    bench = get_benchmark(f"incline{dim}d")
    p = bench.params(overrides)
    problem = bench.problem(n, overrides)
    change = {"follow_mass": False, "initial_acceleration": "zero", **conventions}
    counts, sizes = (
        ([4 * n, 2 * n], [p["width"], p["height"]])
        if dim == 2
        else ([4 * n, 4 * n, 2 * n], [p["width"]] * 2 + [p["height"]])
    )
    mat = problem.material
    case = {
        "block": {"counts": counts, "sizes": sizes},
        "params": {"rho": mat.rho, "lam": mat.lam, "mu": mat.mu},
        "gravity": incline.gravity(dim, p).tolist(),
        "friction": {"law": "coulomb", "coefficient": p["mu"]},
        "solver": GETFEM_FRICTION_SOLVER,
    }
    if kind.startswith("drop"):
        e_d = np.eye(dim)[-1]
        change.update(obstacle=PlaneObstacle(-DROP["gap"] * e_d, e_d), v0=np.array(DROP["v0"][dim]))
        case.update(plane=-DROP["gap"], v0=DROP["v0"][dim])
    if kind == "drop0":
        change["friction"] = None
        case["friction"] = {"law": "frictionless"}
    return dataclasses.replace(problem, **change), case


def _run_getfem(cases: list[dict]) -> list[list[dict]]:
    out = subprocess.run(
        [SYSTEM_PYTHON, str(SCRIPT), "-"],
        input=json.dumps({"cases": cases}),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, f"getfem_reference.py failed:\n{out.stderr[-4000:]}"
    runs: list[list[dict]] = [[] for _ in cases]
    for line in out.stdout.splitlines():
        row = json.loads(line)
        runs[row["case"]].append(row)
    return runs


def _getfem_friction_runs(keys: list[tuple]) -> dict:
    """GetFEM's histories of ``keys`` ((case, slip law) pairs), in one run of the script."""
    if not _getfem_importable():
        pytest.skip("python3-getfem not installed: apt-get install python3-getfem")
    cases = []
    for (kind, dim, n, mass, scheme, T), slip in keys:
        case = friction_problem(kind, dim, n)[1]
        if kind != "drop0":
            case["friction"] = {**case["friction"], "slip": slip}
        cases.append({**case, "mass": mass, "scheme": scheme, "dt": 0.02 / n, "T": T})
    return dict(zip(keys, _run_getfem(cases), strict=True))


@pytest.fixture(scope="module")
def friction_reference():
    """GetFEM's histories of FRICTION (slip of the step) and TOTAL_SLIP (its own brick's law), one run."""
    return _getfem_friction_runs([(k, "increment") for k in FRICTION] + [(k, "total") for k in TOTAL_SLIP])


@pytest.fixture(scope="module")
def slow_friction_reference():
    return _getfem_friction_runs([(k, "increment") for k in SLOW_FRICTION])


def _scaled(ours: np.ndarray, theirs: np.ndarray, scale: float) -> float:
    return float(np.max(np.abs(ours - theirs)) / scale) if scale > 0 else float(np.max(np.abs(ours - theirs)))


def compare_friction(key: tuple, run: list[dict], **conventions) -> dict[str, float]:
    """Our run of a friction case against GetFEM's, quantity by quantity (relative max norms).

    Forces, slips and energy: relative to their own max over the run (and nodes); the gap to
    the contact nodes' largest displacement when larger (a block resting on the plane has
    round-off gaps); the three energy parts to the largest sum of their magnitudes (the
    elastic energy 1/2 U.SU of a sliding block is a cancellation of O(|S| |U|^2) terms)."""
    kind, dim, n, mass, scheme, T = key
    problem, case = friction_problem(kind, dim, n, **conventions)
    H = simulate(problem, scheme, 0.02 / n, T, mass=mass)
    assert H.success, H.message
    header, rows = run[0], run[1:]
    assert len(rows) == H.t.size
    assert all(r["converged"] for r in rows), "GetFEM's Newton did not reach 1e-10 at some step"
    points = np.array(header["contact_points"])
    np.testing.assert_allclose(points, H.coordinates, rtol=0, atol=1e-15)
    col = lambda name: np.array([r[name] for r in rows])  # noqa: E731
    assert col("lambda_sum").min() < 0, "no contact in the run: nothing compared"
    plane = case.get("plane", 0.0)
    gap = points[:, -1][None, :] - plane + col("normal_displacement")
    parts = np.abs(col("kinetic")) + np.abs(col("elastic")) + np.abs(col("load_potential"))
    out = {
        "force": relative(H.lambda_sum, col("lambda_sum")),
        "nodal forces": relative(H.lam, col("lambda")),
        "contact force": relative(H.contact_force, col("contact_force")),
        "gap": _scaled(H.gap, gap, max(np.abs(gap).max(), np.abs(col("displacement")).max())),
        "energy": relative(H.energy, col("energy")),
        "kinetic": _scaled(H.kinetic_energy, col("kinetic"), parts.max()),
        "elastic": _scaled(H.elastic_energy, col("elastic"), parts.max()),
        "load potential": _scaled(H.load_potential, col("load_potential"), parts.max()),
    }
    if H.lam_t is not None:  # global components: our frames and GetFEM's may differ by a sign
        tangential = np.einsum("nik,ikd->nid", H.lam_t, H.tangents)
        slip = np.einsum("nik,ikd->nid", H.slip, H.tangents)
        theirs_t, theirs_s = col("tangential_force"), col("slip")
        out["tangential force"] = _scaled(tangential, theirs_t, np.abs(theirs_t).max())
        out["total tangential force"] = _scaled(
            tangential.sum(axis=1), theirs_t.sum(axis=1), np.abs(theirs_t.sum(axis=1)).max()
        )
        out["slip"] = _scaled(slip, theirs_s, np.abs(theirs_s).max())
    return out


def _fid(key: tuple) -> str:
    kind, dim, n, mass, scheme, T = key
    return f"{kind}{dim}d-n{n}-{mass}-{scheme}-T{T:g}"


@pytest.mark.parametrize("key", FRICTION, ids=[_fid(k) for k in FRICTION])
def test_friction_and_gravity_agree_with_getfem(key, friction_reference):
    diff = compare_friction(key, friction_reference[key, "increment"])
    assert max(diff.values()) <= RTOL, diff


@pytest.mark.slow
@pytest.mark.parametrize("key", SLOW_FRICTION, ids=[_fid(k) for k in SLOW_FRICTION])
def test_friction_and_gravity_agree_with_getfem_longer(key, slow_friction_reference):
    diff = compare_friction(key, slow_friction_reference[key, "increment"])
    assert max(diff.values()) <= RTOL, diff


def test_getfem_own_frictional_brick_is_another_law(friction_reference):
    """GetFEM's frictional rigid-obstacle brick as it is: Alart-Curnier on B_T u, the tangential
    displacement since t = 0, not the slip of the step.  The two laws coincide while every
    contact node slides one way from where it started (the slide: 1e-12), and differ once a
    node sticks away from its starting point (stick: there u_T != 0 and GetFEM's node slips
    back; the drop: it lands already displaced, then stops)."""
    slide, drop, stick = TOTAL_SLIP
    same = compare_friction(slide, friction_reference[slide, "total"])
    assert max(same.values()) <= RTOL, same
    for key in (drop, stick):
        diff = compare_friction(key, friction_reference[key, "total"])
        assert diff["slip"] > 0.1, diff
        assert diff["tangential force"] > 1e-3, diff


def test_each_getfem_convention_matters(friction_reference):
    """Each of the two options is needed: with our default for either one, the same runs
    differ from GetFEM's far beyond round-off (the seed mass drops half the block's mass, so
    M_used g / rho is not int rho g phi; A0 = M^-1 (F - S U0) != 0 changes CN's first steps)."""
    key = ("slide", 2, 2, "seed", "cn", 1.0)
    follow = compare_friction(key, friction_reference[key, "increment"], follow_mass=True)
    assert follow["force"] > 0.1, follow
    start = compare_friction(key, friction_reference[key, "increment"], initial_acceleration="equilibrium")
    assert start["nodal forces"] > 1e-4, start
