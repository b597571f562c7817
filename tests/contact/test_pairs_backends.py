"""The iterative backends on contact pairs (two deformable bodies): ``cg`` serially, ``petsc``
and ``petsc-cg`` on two MPI ranks, against the default direct backend.

Pair rows (a slave node and a master facet's nodes, :mod:`signorini.contact.pairs`) are not
orthonormal: the active-set CG imposes B_A x = c_A with P = I - B_A^T G^-1 B_A,
G = B_A B_A^T (:class:`~signorini.contact.solver.GramFactor`).  Measured here (CN, default
mass, cg rtol 1e-13; rtol 1e-14 gives 10x less):

| case | lambda_sum | gaps / size | energy / max E | min gap / size | complementarity |
|---|---|---|---|---|---|
| 2D bars, 2 against 3 cells | 2.2e-10 | 1.3e-10 | 1.1e-10 | -3.3e-16 | 3.3e-15 |
| 3D bars, 2x2 against 3x3 | 2.9e-10 | 1.2e-10 | 3.0e-10 | -6.7e-16 | 6.7e-15 |
| block on a clamped plate | 1.1e-10 | 2.9e-12 | 2.1e-11 | -1.0e-16 | 1.3e-14 |

On two ranks the block on the plate (node order morton, the contact dofs split 12 / 12
between the ranks) matches the serial direct run to 1.9e-12 (``petsc``) and 1.0e-10
(``petsc-cg``, rtol 1e-13) of each column's scale.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.sparse as sp

from signorini.contact.pairs import ContactPair, pair_rows
from signorini.contact.solver import (
    ActiveSetCGSolver,
    CondensedContactSolver,
    GramFactor,
    _projector,
    gram_factor,
)
from signorini.dynamics.model.problem import Problem
from signorini.dynamics.stepping.simulate import simulate
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import join, rectangle, write_mesh
from signorini.fem.space import Dirichlet
from test_pairs import L, W, bars
from test_petsc_run import (
    ITERATION_COUNTS,
    NODE_COUNTS,
    TOLERANCE,
    check_identities,
    check_summary,
    compare_contact,
    compare_runs,
    mpirun,
    serial,
)
from test_petsc_run import needs_venv as needs_mpi

#: cg's relative residual in these runs (its default is 1e-12)
RTOL = 1e-13
#: the plate of the block-on-plate case: 1.2 x 0.1, 12 x 2 quads, clamped at both ends; the
#: block 0.4 x 0.4 (5 x 5 quads: h 0.08 against the plate's 0.1, non-matching) 0.01 above it
PLATE = 1.2


def block_on_plate() -> Problem:
    """A 2D block falling at speed 1 on a plate clamped at both ends, through a pair with
    non-matching faces (the block's bottom, finer, is the slave)."""
    plate = rectangle(12, 2, PLATE, 0.1)
    block = rectangle(5, 5, 0.4, 0.4)
    block.points = block.points + np.array([0.4, 0.11])
    return Problem(
        join({"plate": plate, "block": block}),
        IsotropicElastic.from_young(100.0, 0.3, 1.0),
        None,
        None,
        dirichlet=[Dirichlet("plate_xmin"), Dirichlet("plate_xmax")],
        v0=lambda x: np.where(x[:, 1] > 0.105, -1.0, 0.0)[:, None] * np.array([0.0, 1.0]),
        pairs=[ContactPair("block_ymin", "plate_ymax")],
    )


# -- the projector ------------------------------------------------------------------------
def random_pair_rows(rng: np.random.Generator, d: int, m: int = 9, n_nodes: int = 30) -> sp.csr_matrix:
    """m rows as :func:`~signorini.contact.pairs.pair_rows` builds them, at random: row i =
    nu_i^T on slave node s_i and -N_j nu_i^T on the nfv nodes j of a master facet (shape
    functions N > 0 summing to 1, unit normals nu_i), the masters drawn from a pool of 6
    nodes so that rows share columns."""
    nfv = 2 if d == 2 else 4
    slaves = rng.choice(np.arange(6, n_nodes), size=m, replace=False)
    masters = np.stack([rng.choice(6, size=nfv, replace=False) for _ in range(m)])
    N = rng.uniform(0.05, 1.0, size=(m, nfv))
    N /= N.sum(axis=1, keepdims=True)
    nu = rng.normal(size=(m, d))
    nu /= np.linalg.norm(nu, axis=1, keepdims=True)
    nodes = np.concatenate([slaves[:, None], masters], axis=1)
    coef = np.concatenate([np.ones((m, 1)), -N], axis=1)
    dofs = (nodes[:, :, None] * d + np.arange(d)).reshape(m, -1)
    vals = (coef[:, :, None] * nu[:, None, :]).reshape(m, -1)
    rows = np.repeat(np.arange(m), dofs.shape[1])
    return sp.csr_matrix((vals.ravel(), (rows, dofs.ravel())), shape=(m, n_nodes * d))


def _pair_matrices(rng: np.random.Generator) -> list[sp.csr_matrix]:
    """Random pair rows in 2D and 3D, and the rows of the non-matching 3D bars' pair."""
    m = bars(3, 2, 3).mesh
    real = pair_rows(m, ContactPair("right_zmin", "left_zmax"), 3 * m.n_nodes).B
    return [random_pair_rows(rng, 2), random_pair_rows(rng, 3), real]


def test_the_projector_of_pair_rows_is_the_orthogonal_projector_onto_their_kernel(rng):
    """P x satisfies B_A P x = 0 to round-off, P is idempotent and symmetric (on random vectors,
    for random subsets A of random pair rows); the rigid-obstacle formula I - B_A^T B_A is
    none of these on such rows.  Measured over 20 seeds: |B_A P x| <= 2.0e-16 |x|,
    |P P x - P x| <= 1.7e-16 |x|, |y.P x - x.P y| <= 8.7e-17 |x||y|."""
    for B in _pair_matrices(rng):
        for _ in range(3):
            A = rng.random(B.shape[0]) < 0.7
            A[0] = True
            BA = B[A]
            gram = gram_factor(BA)
            assert isinstance(gram, GramFactor)  # pair rows are not orthonormal
            project = _projector(BA, gram)
            x, y = rng.normal(size=(2, B.shape[1]))
            Px, Py = x.copy(), y.copy()
            project(Px)
            project(Py)
            PPx = Px.copy()
            project(PPx)
            nx, ny = np.linalg.norm(x), np.linalg.norm(y)
            assert np.linalg.norm(BA @ Px) <= 1e-14 * nx
            assert np.linalg.norm(PPx - Px) <= 1e-14 * nx
            assert abs(y @ Px - x @ Py) <= 1e-14 * nx * ny
            assert np.linalg.norm(Px - x) >= 1e-3 * nx  # P is not the identity on these x
            old = x - BA.T @ (BA @ x)  # the orthonormal formula violates the constraint here
            assert np.linalg.norm(BA @ old) >= 1e-2 * nx


def test_rigid_obstacle_rows_keep_the_orthonormal_projector_bit_for_bit(rng):
    """Unit normals on distinct nodes (a zero row too: a clamped contact node) are detected as
    orthonormal: no Gram factor, and P v = v - B_r^T (B_r v) exactly as before; a row of
    another norm (a normal cut by a Dirichlet condition) is not."""
    d, n_nodes, m = 3, 12, 5
    nu = rng.normal(size=(m, d))
    nu /= np.linalg.norm(nu, axis=1, keepdims=True)
    nodes = rng.choice(n_nodes, size=m, replace=False)
    nu[2] = 0.0  # every dof of that node fixed: its row is empty
    dofs = nodes[:, None] * d + np.arange(d)
    B = sp.csr_matrix((nu.ravel(), (np.repeat(np.arange(m), d), dofs.ravel())), shape=(m, n_nodes * d))
    assert gram_factor(B) is None
    v = rng.normal(size=n_nodes * d)
    got = v.copy()
    _projector(B)(got)
    cols = np.unique(B.indices)
    want = v.copy()
    want[cols] -= B[:, cols].T.tocsr() @ (B[:, cols].tocsr() @ v[cols])
    assert np.array_equal(got, want)
    cut = B.tolil()
    cut[0, dofs[0, 0]] = 0.0  # the normal's first component on a fixed dof
    assert isinstance(gram_factor(cut.tocsr()), GramFactor)


def test_one_cg_solve_with_pair_rows_equals_the_direct_solve(rng):
    """The active-set CG solve (x_p = B_A^T G^-1 c_A, lambda_A = G^-1 B_A (K x - b)) against the
    condensed direct solve on a random SPD K with pair rows, bounds that activate some of
    them: x and lambda agree to 5e-13 and 2e-13 of their scale (measured over 20 seeds at
    cg rtol 1e-14: 7.6e-15 and 2.2e-15), no row beyond its bound (measured 1e-16)."""
    for B in _pair_matrices(rng)[:2]:
        n = B.shape[1]
        R = sp.random(n, n, density=0.1, random_state=np.random.RandomState(7))
        K = sp.csr_matrix(R @ R.T + n * sp.identity(n))
        b = rng.normal(size=n)
        x_free = np.linalg.solve(K.toarray(), b)
        bound = B @ x_free - np.where(rng.random(B.shape[0]) < 0.5, 0.5, -0.5) * np.abs(B @ x_free).max()
        direct = CondensedContactSolver(K, B, 1.0)
        x_d, lam_d, _ = direct.solve(b, bound)
        x_c, lam_c, info = ActiveSetCGSolver(K, B, 1.0, rtol=1e-14).solve(b, bound)
        assert 0 < info.active.sum() < B.shape[0] and np.array_equal(info.active, lam_d < 0)
        assert np.abs(x_c - x_d).max() <= 5e-13 * np.abs(x_d).max()
        assert np.abs(lam_c - lam_d).max() <= 2e-13 * np.abs(lam_d).max()
        assert np.all(B @ x_c - bound <= 1e-14 * np.abs(bound).max())


# -- runs ----------------------------------------------------------------------------------
CASES = {
    "bars2d": (lambda: bars(2, 2, 3), W / 6, 4.2, L),
    "bars3d": (lambda: bars(3, 2, 3), W / 6, 4.2, L),
    "block-on-plate": (block_on_plate, 0.004, 0.4, PLATE),
}


@pytest.mark.parametrize("name", list(CASES))
def test_cg_on_pairs_gives_the_direct_history(name):
    """Two bars colliding (non-matching faces, 2D and 3D) and a block falling on a clamped
    plate: backend cg (rtol 1e-13) against the default direct backend; tolerances about 70x
    the measured differences (module docstring); no penetration of the slave rows beyond
    round-off, complementarity, lambda <= 0."""
    make, dt, T, size = CASES[name]
    p = make()
    ref = simulate(p, "cn", dt, T)
    H = simulate(p, "cn", dt, T, solver_options={"backend": "cg", "rtol": RTOL})
    assert H.status == "finished" and H.meta["backend"].startswith("cg")
    assert (ref.lam < 0).any(axis=1).sum() >= 40  # tens of steps in contact
    s = np.abs(ref.lambda_sum).max()
    assert np.abs(H.lambda_sum - ref.lambda_sum).max() <= 2e-8 * s
    assert np.abs(H.gap - ref.gap).max() <= 1e-8 * size
    assert np.abs(H.energy - ref.energy).max() <= 2e-8 * np.abs(ref.energy).max()
    assert H.gap.min() >= -5e-14 * size  # measured -6.7e-16 at most
    assert H.lam.max() <= 0.0
    assert H.residual.max() <= 1e-12  # measured 1.3e-14 at most
    assert np.abs(H.lam * H.gap).max() <= 1e-14 * s * size  # measured 1.0e-16 at most
    assert H.counters["krylov_iterations"] > 0


# -- two MPI ranks ---------------------------------------------------------------------------
CASE_FILE = """# A block falling on a plate clamped at both ends through a contact pair (non-matching faces)
[mesh]
file = "block_on_plate.msh"

[material]
rho = 1.0
E = 100.0
nu = 0.3

[[dirichlet]]
tag = "plate_xmin"

[[dirichlet]]
tag = "plate_xmax"

[contact]
pairs = [{ slave = "block_ymin", master = "plate_ymax" }]

[initial]
velocity = [0.0, "-min(1, max(0, (y - 0.1) * 1e6))"]

[time]
scheme = "cn"
dt = 0.004
T = 0.4
control = "fixed"  # the grid of the runs compared (under the energy control, tests/linalg/test_petsc_run.py)
"""


@needs_mpi
@pytest.mark.parametrize("backend", ["petsc", "petsc-cg"])
def test_pairs_on_two_ranks_match_the_serial_run(tmp_path, backend):
    """The block on the plate (a gmsh file of two bodies, renumbered in Z-order on the ranks,
    the pair's rows spanning both ranks' rows) on two ranks against the serial default run:
    every column of history.csv and contact.npz to 1e-8 of its scale (measured 1.9e-12 with
    petsc, 1.0e-10 with petsc-cg at rtol 1e-13), complementarity and the energy identity."""
    write_mesh(block_on_plate().mesh, tmp_path / "block_on_plate.msh")
    (tmp_path / "case.toml").write_text(CASE_FILE)
    r = serial(["case.toml", "--out", str(tmp_path / "ser"), "--quiet"], tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    extra = ["--solver-option", f"rtol={RTOL}"] if backend == "petsc-cg" else []
    r = mpirun(2, ["case.toml", *extra, "--out", str(tmp_path / "par"), "--quiet"], tmp_path, backend=backend)
    assert r.returncode == 0, r.stderr[-3000:]
    # petsc-cg, as on a rigid obstacle (test_petsc_run): CG and a direct solve may count a node at
    # zero gap and zero force on either side, and stop one active-set iteration apart
    skip = NODE_COUNTS + ITERATION_COUNTS if backend == "petsc-cg" else ()
    assert compare_runs(tmp_path / "ser", tmp_path / "par", skip=skip) <= TOLERANCE
    compare_contact(tmp_path / "ser", tmp_path / "par")
    # the identity of a CG solve closes to CG's tolerance (rtol 1e-13: measured 1.2e-11 of E with
    # the pair's rows re-paired as the block slides), a direct one to round-off
    check_identities(tmp_path / "par", 1e-11 if backend == "petsc" else 1e-10)
    summary = json.loads((tmp_path / "par" / "summary.json").read_text())
    assert summary["ranks"] == 2 and summary["backend"].startswith(backend)
    ser = json.loads((tmp_path / "ser" / "summary.json").read_text())
    assert summary["counters"]["pair_rows_repaired"] == ser["counters"]["pair_rows_repaired"]
    assert min(summary["rank_contact_dofs"]) > 0  # the pair's dofs on both ranks
    if backend == "petsc":
        check_summary(tmp_path / "ser", tmp_path / "par", 2)
