"""The iterative path (backend cg) with many contact nodes on a curved contact surface."""

import numpy as np
import pytest

from signorini.contact.obstacles import SphereObstacle
from signorini.dynamics.model.problem import Problem
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import box
from signorini.linalg import PRECONDITIONERS, has_pyamg, solver_options
from signorini.linalg.krylov import JacobiPreconditioner


def plate(n: int) -> tuple[Problem, float]:
    """A plate [0,1]^2 x [0, 0.05] (n x n x 2 hexahedra, (n+1)^2 contact nodes) falling
    flat at speed 0.5 on a ball of radius 2: the contact zone spreads from the centre
    over hundreds of nodes, on a curved surface."""
    R = 2.0
    p = Problem(
        mesh=box(n, n, 2, 1.0, 1.0, 0.05),
        material=IsotropicElastic(0.25, 0.5, 1.0),
        contact_tag="zmin",
        obstacle=SphereObstacle([0.5, 0.5, -R - 0.002], R),
        v0=[0.0, 0.0, -0.5],
        name="plate",
    )
    return p, 0.5 / n


def _run(p, dt, steps, **opts):
    return simulate(p, "cn", dt, steps * dt, solver_options=opts)


def _check_many_nodes(n: int, steps: int) -> None:
    p, dt = plate(n)
    cg = _run(p, dt, steps, backend="cg")
    direct = _run(p, dt, steps, backend="superlu")
    assert cg.status == "finished"
    touched = (cg.lam != 0).sum(axis=1)
    assert touched.max() >= 0.3 * (n + 1) ** 2  # hundreds of nodes in contact at once
    assert len(set(touched[touched > 0])) > steps // 4  # the contact zone keeps changing
    # no cycling: a few active-set iterations per step (the counter includes the start)
    assert cg.counters["contact_iterations"] <= 4 * (steps + 1)
    # CG (rtol 1e-12) against the direct solver: measured 3.5e-11 and 2.1e-11 relative
    assert np.abs(cg.lam - direct.lam).max() <= 2e-9 * np.abs(direct.lam).max()
    assert np.abs(cg.gap - direct.gap).max() <= 1e-9 * np.abs(direct.gap).max()
    # measured 3.4e-16; 1e-10: with CG's solves the residual is CG's tolerance, not round-off
    assert cg.residual.max() <= 1e-10


def test_active_set_cg_with_hundreds_of_curved_contact_nodes():
    _check_many_nodes(16, 12)


@pytest.mark.slow
def test_active_set_cg_with_thousands_of_curved_contact_nodes():
    _check_many_nodes(40, 40)  # 1681 contact nodes, 824 in contact at the peak


@pytest.mark.parametrize("pc", [e.name for e in PRECONDITIONERS if e.name != "amg" or has_pyamg()])
def test_every_preconditioner_gives_the_same_history(pc):
    """Against the direct solve (a run of the default cg would compare [jacobi] with itself)."""
    p, dt = plate(8)
    ref = _run(p, dt, 10, backend="superlu")
    H = _run(p, dt, 10, backend="cg", preconditioner=pc)
    assert np.abs(H.lam).max() > 0
    assert np.abs(H.lam - ref.lam).max() <= 5e-10 * np.abs(ref.lam).max()  # measured 6e-12 to 9e-12
    assert np.abs(H.gap - ref.gap).max() <= 1e-9 * np.abs(ref.gap).max()  # measured 1.5e-11 to 1.8e-11


def test_block_jacobi_inverts_the_nodal_blocks(rng):
    import scipy.sparse as sp

    from signorini.linalg.krylov import BlockJacobiPreconditioner

    A = rng.normal(size=(7, 7))
    K = sp.csr_matrix(A @ A.T + 7 * np.eye(7))
    nodes = np.array([0, 0, 0, 1, 1, 2, 2])  # a node with 2 free dofs, as after a Dirichlet condition
    P = BlockJacobiPreconditioner(K, nodes)
    D = np.zeros((7, 7))
    for blk in (slice(0, 3), slice(3, 5), slice(5, 7)):
        D[blk, blk] = K.toarray()[blk, blk]
    r = rng.normal(size=7)
    assert np.allclose(P(r), np.linalg.solve(D, r), rtol=2e-14, atol=0)  # measured 2.1e-16 relative


def test_preconditioner_names_come_from_the_registry():
    with pytest.raises(InputError, match="allowed: jacobi, block-jacobi, amg"):
        solver_options({"backend": "cg", "preconditioner": "ilu"})
    PRECONDITIONERS.register("dummy-pc", ".krylov:JacobiPreconditioner", "test entry (import path)")
    PRECONDITIONERS.register("dummy-class", JacobiPreconditioner, "test entry (a class)")
    try:
        assert solver_options({"backend": "cg", "preconditioner": "dummy-pc"})["preconditioner"] == "dummy-pc"
        p, dt = plate(4)
        for name in ("dummy-pc", "dummy-class"):
            assert _run(p, dt, 3, backend="cg", preconditioner=name).status == "finished"
    finally:
        PRECONDITIONERS.unregister("dummy-pc")
        PRECONDITIONERS.unregister("dummy-class")


def test_auto_picks_cg_when_the_delassus_matrix_would_not_fit():
    p, dt = plate(8)  # 81 contact nodes: W is 52 kB; the factor of 1.2k dofs ~ 1 MB
    nc = 81
    small = _run(p, dt, 2, backend="auto", memory_budget=0.9 * 8 * nc * nc)
    large = _run(p, dt, 2, backend="auto", memory_budget=1e9)
    assert small.meta["backend"].startswith("cg")
    assert large.meta["backend"] == "superlu"


@pytest.mark.parametrize("scheme", ["cn", "backward-euler", "generalized-alpha"])
def test_the_schemes_guess_saves_iterations_and_changes_nothing(scheme, monkeypatch):
    """Started from the scheme's Taylor estimate U + dt V + dt^2/2 A instead of U^n, CG
    needs fewer iterations and gives the same history (through the impacts)."""
    from signorini.dynamics.schemes.base import Scheme

    p, dt = plate(8)
    H = simulate(p, scheme, dt, 12 * dt, solver_options={"backend": "cg"})
    monkeypatch.setattr(Scheme, "taylor_guess", staticmethod(lambda ctx, s: s.U))
    ref = simulate(p, scheme, dt, 12 * dt, solver_options={"backend": "cg"})
    assert np.abs(ref.lam).max() > 0
    assert H.counters["krylov_iterations"] < ref.counters["krylov_iterations"]  # 3-5% here, 8% on bar3d
    assert np.abs(H.lam - ref.lam).max() <= 1e-9 * np.abs(ref.lam).max()  # CG's rtol 1e-12: measured 1.2e-11
    assert np.abs(H.gap - ref.gap).max() <= 2e-9 * np.abs(ref.gap).max()  # measured 2.7e-11


def test_a_guess_of_the_wrong_size_is_refused():
    from signorini.contact.solver import ActiveSetCGSolver

    K = np.diag([2.0, 3.0, 4.0])
    solver = ActiveSetCGSolver(K, np.zeros((0, 3)), 1.0)
    with pytest.raises(ValueError, match="shape"):
        solver.set_guess(np.zeros(2))


def test_a_direct_solve_does_not_compute_the_guess(monkeypatch):
    from signorini.dynamics.schemes.base import Scheme

    def refuse(ctx, s):
        raise AssertionError("the guess was computed for a direct solve")

    monkeypatch.setattr(Scheme, "taylor_guess", staticmethod(refuse))
    p, dt = plate(4)
    assert _run(p, dt, 3, backend="superlu").status == "finished"
