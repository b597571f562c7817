"""PETSc's SNES VI against petsc-cg's active-set CG on one contact step (issue 22's measurement).

Usage (under the MPI environment, P ranks)::

    .venv-mpi/bin/mpiexec -n P .venv-mpi/bin/python -m benchmarks.bench_snes_vi [--n 16] [--repeat 3]

The step: bar3d n with its contact face on the obstacle (``--set gap=0``), the
Crank-Nicolson operator K = 4 M / dt^2 + S of the default dt (K as ``petsc-cg`` builds it,
on the free dofs), and the right-hand side b = K u_p of a uniform downward motion
u_p = dt v_0 e_z, which pushes every contact node into the obstacle by dt |v_0|.  The
solution x of  K x = b + B^T lambda,  B x <= 0,  lambda <= 0,  complementarity,  puts the
face back on the obstacle.  Solved by

* ``petsc-cg``: the serial active-set (semismooth Newton) iteration over PETSc's
  projected CG with Jacobi (:class:`~signorini.contact.distributed_cg.DistributedCGSolver`),
  started from zero;
* SNES ``vinewtonrsls`` (reduced-space active set): F(x) = K x - b with the bounds of the
  contact dofs (the normals of bar3d are coordinate axes, so B x <= 0 is a bound on one
  dof per node), the same CG + Jacobi on the reduced system (MPIAIJ: it extracts
  submatrices), started from zero, stopped when |F| on the free set is below 1e-10 of
  |b|.

Prints, per solver, the best of ``--repeat`` wall times, the Newton (active-set)
iterations, the CG iterations, and the difference of the two solutions and of their
total contact forces.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse as sp


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)

    from signorini.contact.distributed_cg import DistributedCGSolver, _matrix
    from signorini.dynamics.model.operator import Operator
    from signorini.dynamics.model.problem import discretize
    from signorini.dynamics.solve.context import Context
    from signorini.linalg.petsc import load
    from signorini.linalg.row_block import node_row_bounds
    from signorini.linalg.sparse import principal_combination
    from signorini.studies.benchmarks import get_benchmark

    MPI, PETSc = load()
    comm = PETSc.COMM_WORLD
    bench = get_benchmark("bar3d")
    dt = bench.run_times(a.n, {"gap": 0.0})[0]
    disc = discretize(bench.problem(a.n, {"gap": 0.0}), "moment-preserving")
    ctx = Context(disc, dt, {"backend": "petsc-cg", "preconditioner": "jacobi"})
    f = ctx.free
    op = Operator(4.0 / dt**2, 1.0)
    if ctx.fixed.size:
        K = principal_combination(op.mass, ctx.M, op.stiffness, ctx.S, f, ctx.fixed)[0].tocsr()
    else:
        K = op.matrix(ctx.M, ctx.S).tocsr()
    B = ctx.rows.Bf.tocsr()
    B.data[np.abs(B.data) < 1e-14] = 0.0  # the tangential components of an axis normal
    B.eliminate_zeros()
    nodes = disc.space.dofmap.nodes_of(f)
    v0 = float(np.abs(disc.space.interpolate(disc.problem.v0)[2::3]).max())
    up = np.zeros(disc.space.n_dofs)
    up[2::3] = -dt * v0
    b = K @ up[f]
    bound = np.zeros(B.shape[0])

    def best(fn):
        times, out = [], None
        for _ in range(a.repeat):
            comm.tompi4py().Barrier()
            t0 = time.perf_counter()
            out = fn()
            times.append(time.perf_counter() - t0)
        return min(times), out

    # -- petsc-cg: the active-set iteration over projected CG ------------------------
    cg = DistributedCGSolver(K, B, 1.0, nodes, None, "jacobi")

    def run_cg():
        cg.active[:] = False
        cg.U_prev = np.zeros(K.shape[0])
        before = dict(cg.counters)
        x, lam, info = cg.solve(b, bound)
        its = {k: cg.counters[k] - before[k] for k in ("contact_iterations", "krylov_iterations")}
        return x, lam, its

    t_cg, (x_cg, lam_cg, its_cg) = best(run_cg)

    # -- SNES VI (reduced space) on the same K, bounds on the contact dofs -------------
    rows = np.repeat(np.arange(B.shape[0]), np.diff(B.indptr))
    if np.any(np.diff(B.indptr) != 1):
        raise SystemExit("bench_snes_vi: the contact rows are not single dofs (a curved obstacle): not a box")
    bounds = node_row_bounds(nodes, comm.size)
    lo, hi = int(bounds[comm.rank]), int(bounds[comm.rank + 1])
    A = _matrix(PETSc, comm, sp.csr_matrix(K)[lo:hi], K.shape[0], lo, 3, symmetric=False)
    A.assemble()
    n = K.shape[0]
    upper = np.full(n, PETSc.INFINITY)
    lower = np.full(n, PETSc.NINFINITY)
    c = B.data
    upper[B.indices[c > 0]] = (bound[rows] / c)[c > 0]
    lower[B.indices[c < 0]] = (bound[rows] / c)[c < 0]
    xl, xu, x, r, bv = (A.createVecRight() for _ in range(5))
    xl.setArray(lower[lo:hi])
    xu.setArray(upper[lo:hi])
    bv.setArray(b[lo:hi])

    def residual(snes, X, F):
        A.mult(X, F)
        F.axpy(-1.0, bv)

    snes = PETSc.SNES().create(comm=comm)
    snes.setType("vinewtonrsls")
    snes.setFunction(residual, r)
    snes.setJacobian(lambda *args: None, A, A)
    snes.setVariableBounds(xl, xu)
    snes.setTolerances(rtol=1e-10, atol=1e-10 * float(np.linalg.norm(b)), max_it=50)
    ksp = snes.getKSP()
    ksp.setType("cg")
    ksp.getPC().setType("jacobi")
    ksp.setTolerances(rtol=1e-12, atol=0.0, max_it=5000)
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)

    def run_vi():
        x.set(0.0)
        snes.solve(None, x)
        if snes.getConvergedReason() <= 0:
            raise SystemExit(f"bench_snes_vi: SNES VI did not converge (reason {snes.getConvergedReason()})")
        full = np.empty(n)
        counts = np.diff(bounds)
        comm.tompi4py().Allgatherv(x.getArray(readonly=True).copy(), [full, counts, bounds[:-1], MPI.DOUBLE])
        return full, {"newton": snes.getIterationNumber(), "cg": snes.getLinearSolveIterations()}

    t_vi, (x_vi, its_vi) = best(run_vi)
    lam_vi = B @ (K @ x_vi - b)  # lambda = B (K x - b) on the active rows (0 elsewhere, to CG's tolerance)
    if comm.rank == 0:
        scale = float(np.abs(x_cg).max())
        print(f"bar3d n = {a.n}: {n:,} free dofs, {B.shape[0]} contact nodes, {comm.size} rank(s), best of {a.repeat}")
        print(f"  petsc-cg (active set + projected CG, Jacobi): {1e3 * t_cg:8.1f} ms, "
              f"{its_cg['contact_iterations']} Newton, {its_cg['krylov_iterations']} CG iterations")  # fmt: skip
        print(f"  SNES vinewtonrsls (CG, Jacobi):               {1e3 * t_vi:8.1f} ms, "
              f"{its_vi['newton']} Newton, {its_vi['cg']} CG iterations")  # fmt: skip
        print(f"  SNES VI / petsc-cg time: {t_vi / t_cg:.2f}")
        print(f"  |x_vi - x_cg|_inf / |x_cg|_inf = {np.abs(x_vi - x_cg).max() / scale:.2e}; "
              f"total force {lam_cg.sum():.6e} (petsc-cg) against {lam_vi.sum():.6e} (SNES VI)")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
