"""GetFEM 5.4 as the reference of the quadratic cells (issue 54): the same runs by GetFEM and by us, Q2 and P2.

Cases (the consistent mass, GetFEM's FEM_QK(2, 2) / FEM_PK(2, 2) with the same quadrature as ours: 3 x 3 Gauss
points on Q2, the 6-point rule of degree 4 on P2):

- the paper's 2D bar (``bar2d --set order=2``, n = 2: 2 x 20 quad9), backward Euler, nodal contact at every node
  of the contact side (its vertices and mid-side nodes);
- the same bar vibrating freely, Crank-Nicolson (the plane 10 below: no contact), compared through the bottom
  side's displacements and the energy;
- the Hertz disc of ``hertz2d --set order=2`` (n = 2: curved triangle6, the mid-side nodes on the circle, GetFEM's
  GT_PK(2, 2) read from our Gmsh file), Crank-Nicolson and backward Euler.

Norm as in tests/dynamics/test_getfem.py: the relative max norm over the run, asserted <= 1e-8.  Measured: the bar
with contact 5.7e-13 (nodal forces), 3.4e-14 (gaps), 7.4e-14 (energy); free 5.2e-16 and 2.1e-14; the Hertz disc
3.1e-12 (nodal forces), 1.0e-12 (gaps), 7.1e-13 (energy).
"""

from __future__ import annotations

import dataclasses
import importlib.util

import numpy as np
import pytest

from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.mesh import write_mesh
from signorini.studies.benchmarks import get_benchmark
from test_getfem import _getfem_importable, _run_getfem, relative

RTOL = 1e-8
HAS_GMSH = importlib.util.find_spec("gmsh") is not None
#: (name, scheme, free): free = the obstacle 10 below the bar (no contact)
CASES = [("bar2d", "be", False), ("bar2d", "cn", True), ("hertz2d", "cn", False), ("hertz2d", "be", False)]


def _problem(name: str, free: bool):
    b = get_benchmark(name)
    problem = b.problem(2, {"order": 2})
    if free:
        problem = dataclasses.replace(problem, obstacle=PlaneObstacle([0.0, -10.0], [0.0, 1.0]))
    dt, T = (b.h(2) / 2, 1.0) if name == "bar2d" else b.run_times(2)
    return problem, dt, T


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    if not _getfem_importable():
        pytest.skip("python3-getfem not installed: apt-get install python3-getfem")
    folder = tmp_path_factory.mktemp("getfem-quadratic")
    cases, keys = [], []
    for name, scheme, free in CASES:
        if name == "hertz2d" and not HAS_GMSH:
            continue
        problem, dt, T = _problem(name, free)
        case = {"mass": "standard", "scheme": scheme, "dt": dt, "T": T}
        if name == "bar2d":
            case.update(benchmark="bar2d", n=2, order=2, points=problem.mesh.points.tolist())
            if free:
                case["plane"] = -10.0
        else:
            path = folder / "hertz2d-p2.msh"
            write_mesh(problem.mesh, path)
            mat = problem.material
            velocity = get_benchmark(name).params()["velocity"]
            params = {"lam": mat.lam, "mu": mat.mu, "rho": mat.rho, "velocity": velocity}
            case.update(mesh=str(path), contact="cap", params=params)
        cases.append(case)
        keys.append((name, scheme, free))
    return dict(zip(keys, _run_getfem(cases), strict=True))


@pytest.mark.parametrize("key", CASES, ids=["-".join(map(str, k)) for k in CASES])
def test_quadratic_cells_agree_with_getfem(key, reference):
    name, scheme, free = key
    if name == "hertz2d" and not HAS_GMSH:
        pytest.skip('the Hertz mesh needs gmsh: pip install ".[mesh]"')
    problem, dt, T = _problem(name, free)
    H = simulate(problem, scheme, dt, T, mass="standard")
    assert H.success, H.message
    header, rows = reference[key][0], reference[key][1:]
    assert len(rows) == H.t.size and all(r["converged"] for r in rows)
    points = np.array(header["contact_points"])
    np.testing.assert_allclose(points, H.coordinates, rtol=0, atol=1e-15)
    assert np.unique(problem.mesh.facets_of("ymin" if name == "bar2d" else "cap")).size == points.shape[0]
    force = np.array([r["lambda_sum"] for r in rows])
    plane = -10.0 if free else 0.0  # the gap: x_d + u_d - plane
    gap = points[:, -1][None, :] + np.array([r["normal_displacement"] for r in rows]) - plane
    diff = {"gap": relative(H.gap, gap), "energy": relative(H.energy, np.array([r["energy"] for r in rows]))}
    if free:
        assert np.all(force == 0) and np.all(H.lambda_sum == 0)
    else:
        assert force.min() < 0, "no contact in the run: nothing compared"
        diff["force"] = relative(H.lambda_sum, force)
        diff["nodal forces"] = relative(H.lam, np.array([r["lambda"] for r in rows]))
    assert max(diff.values()) <= RTOL, diff
