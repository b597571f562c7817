"""Self-test of the distributed assembly: ``mpiexec -n P python -m signorini.linalg.petsc.selftest``.

On ``bar3d`` n = 2 (hexahedra) and a tetrahedral box, every rank partitions the mesh,
assembles S and the consistent mass on its own cells (PETSc MPIAIJ, block size d), and
multiplies them by a vector that is the same on every rank; the owned rows are compared
with the serial scipy operators on the same vector (renumbered).  Rank 0 prints one JSON
line: per mesh the largest relative difference, the cells, owned nodes and ghosts per
rank, and the peak resident memory per rank [MiB].
"""

from __future__ import annotations

import json
import resource

import numpy as np

from . import load


def check(mesh, material, comm, PETSc) -> dict:
    from ...fem.assembly import mass_matrix, stiffness_matrix
    from .assemble import consistent_mass, stiffness
    from .partition import partition_mesh

    part = partition_mesh(mesh, comm, PETSc)
    d = mesh.dim
    n = d * mesh.n_nodes
    x_old = np.random.default_rng(7).normal(size=n)
    new_dof = (d * part.new_of_old[:, None] + np.arange(d)).ravel()  # new index of every old dof
    x_new = np.empty(n)
    x_new[new_dof] = x_old
    lo, hi = part.dofmap.owned_dofs
    out = {}
    for name, A, serial in (
        ("S", stiffness(mesh, material, part, comm, PETSc), stiffness_matrix(mesh, material)),
        ("M", consistent_mass(mesh, material.rho, part, comm, PETSc), mass_matrix(mesh, material.rho)),
    ):
        x = A.createVecRight()
        x.setArray(x_new[lo:hi])
        y = A.createVecLeft()
        A.mult(x, y)
        ref_new = np.empty(n)
        ref_new[new_dof] = serial @ x_old
        err = float(np.max(np.abs(y.getArray() - ref_new[lo:hi]), initial=0.0))
        scale = float(np.max(np.abs(ref_new)))
        out[name] = comm.allreduce(err, op=__import__("mpi4py.MPI", fromlist=["MPI"]).MAX) / scale
        A.destroy()
    out["cells"] = comm.allgather(int(part.cells.size))
    out["owned_nodes"] = comm.allgather(int(part.dofmap.owned_nodes))
    out["ghosts"] = comm.allgather(int(part.dofmap.ghosts.size))
    out["partitioner"] = part.method
    return out


def main() -> int:
    MPI, PETSc = load()
    from ...fem.material import IsotropicElastic
    from ...fem.mesh import box

    comm = MPI.COMM_WORLD
    material = IsotropicElastic(0.25, 0.5, 1.0)
    report = {"ranks": comm.size, "petsc": ".".join(map(str, PETSc.Sys.getVersion()))}
    report["hexahedra"] = check(box(2, 2, 20, 0.1, 0.1, 1.0), material, comm, PETSc)
    report["tetrahedra"] = check(box(3, 3, 6, 1.0, 1.0, 2.0, cell="tetra"), material, comm, PETSc)
    report["peak_memory_mib"] = comm.allgather(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
    if comm.rank == 0:
        print(json.dumps(report))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
