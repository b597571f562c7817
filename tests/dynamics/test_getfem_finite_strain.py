"""Finite strain against GetFEM's nonlinear elasticity (issue 41, verification): a block clamped on one face,
pulled sideways and along its axis by a dead traction on the other until it bends by most of its length,
computed by GetFEM 5.4's finite strain elasticity brick (``tests/getfem_reference.py``, case ``static``) and by
signorini's internal force and tangent (:mod:`signorini.fem.hyperelastic`), the same mesh, elements (Q1, 2
Gauss points per direction), law and load increments; each side's Newton to its round-off.  Asserted: the
displacement of every node at every increment to 1e-8 of the largest (measured: table in
docs/finite_strain.md).  Skipped when /usr/bin/python3 cannot import getfem, as tests/dynamics/test_getfem.py.
"""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from signorini.fem.assembly import surface_load
from signorini.fem.hyperelastic import NeoHookeanLaw, SaintVenantKirchhoffLaw, internal_force, tangent_stiffness
from signorini.fem.mesh import box, rectangle
from test_getfem import SCRIPT, SYSTEM_PYTHON, _getfem_importable

LAWS = {"saint-venant-kirchhoff": SaintVenantKirchhoffLaw, "neo-hookean": NeoHookeanLaw}
#: (counts, sizes, traction on the face x_d = 0 [force / area]): a bend of about 0.7 of the length in 3D
CASES = {
    2: ([3, 6], [0.5, 1.0], [0.25, -0.3]),
    3: ([2, 2, 4], [0.5, 0.5, 1.0], [0.3, 0.0, -0.3]),
}
LAM, MU, INCREMENTS = 1.0, 1.0, 4


def ours(dim: int, law: str) -> tuple[list[np.ndarray], np.ndarray]:
    """Our static solution at each load increment (Newton on f(U) = F on the free dofs, from the last one) and
    the mesh's points."""
    counts, sizes, traction = CASES[dim]
    mesh = rectangle(*counts, *sizes) if dim == 2 else box(*counts, *sizes)
    top, bottom = ("ymax", "ymin") if dim == 2 else ("zmax", "zmin")
    lw = LAWS[law](LAM, MU)
    F = surface_load(mesh, bottom, np.asarray(traction))
    fixed = (dim * mesh.nodes_of(top)[:, None] + np.arange(dim)).ravel()
    free = np.setdiff1d(np.arange(mesh.n_nodes * dim), fixed)
    U, out = np.zeros(mesh.n_nodes * dim), []
    for k in range(1, INCREMENTS + 1):
        load = F * k / INCREMENTS
        for _ in range(30):
            r = (internal_force(mesh, lw, U) - load)[free]
            if np.abs(r).max() <= 1e-13 * np.abs(load).max():
                break
            U[free] -= spla.spsolve(tangent_stiffness(mesh, lw, U)[free][:, free].tocsc(), r)
        else:
            raise AssertionError(f"our Newton did not converge at increment {k}")
        out.append(U.copy())
    return out, mesh.points


@pytest.fixture(scope="module")
def getfem_runs():
    if not _getfem_importable():
        pytest.skip("python3-getfem not installed: apt-get install python3-getfem")
    keys = [(dim, law) for dim in CASES for law in LAWS]
    cases = [{"static": {"counts": CASES[d][0], "sizes": CASES[d][1], "law": law, "lam": LAM, "mu": MU,
                         "traction": CASES[d][2], "increments": INCREMENTS}} for d, law in keys]  # fmt: skip
    out = subprocess.run([SYSTEM_PYTHON, str(SCRIPT), "-"], input=json.dumps({"cases": cases}), capture_output=True,
                         text=True, timeout=600)  # fmt: skip
    assert out.returncode == 0, f"getfem_reference.py failed:\n{out.stderr[-4000:]}"
    runs: dict = {}
    for line in out.stdout.splitlines():
        row = json.loads(line)
        runs.setdefault(keys[row["case"]], []).append(row)
    return runs


@pytest.mark.parametrize("law", list(LAWS))
@pytest.mark.parametrize("dim", [2, 3])
def test_a_large_static_deformation_equals_getfems(getfem_runs, dim, law):
    header, rows = getfem_runs[dim, law][0], getfem_runs[dim, law][1:]
    assert all(r["converged"] for r in rows) and len(rows) == INCREMENTS
    mine, points = ours(dim, law)
    np.testing.assert_allclose(np.array(header["points"]), points, rtol=0, atol=1e-15)  # the same node numbering
    theirs = [np.array(r["u"]) for r in rows]
    assert np.abs(theirs[-1]).max() > 0.3 * max(CASES[dim][1])  # a large deformation, not a linear one
    for k, (a, b) in enumerate(zip(mine, theirs, strict=True)):
        err = np.abs(a - b).max() / np.abs(b).max()
        assert err <= 1e-8, (k, err)
