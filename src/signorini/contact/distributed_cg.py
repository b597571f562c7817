"""The contact solve of the serial ``cg`` backend on P ranks through PETSc (backend ``petsc-cg``).

No factorization: for a factor that does not fit, the active-set (semismooth Newton)
iteration of :class:`~signorini.contact.solver.ActiveSetCGSolver` runs unchanged and
replicated on every rank, and each of its linear solves

    P K P w = P r,    P = I - B_A^T B_A  (a rigid obstacle's orthonormal rows; pairs: below),

is PETSc's conjugate gradients on the distributed K (MPIAIJ, each rank a block of whole
nodes' rows), preconditioned by ``P Q P`` with Q one of

* ``gamg``: PETSc's smoothed-aggregation algebraic multigrid with the rigid-body motions
  of the free dofs as near-null space (3 in 2D, 6 in 3D;
  :meth:`~signorini.fem.space.VectorSpace.rigid_body_modes`);
* ``jacobi``: diagonal scaling, as the serial default (K = c_M M + c_S S is close to its
  mass part when dt is about a wave's crossing time of a cell).

``auto`` (the default) takes ``jacobi`` when the operator is mass-dominated (the test by
which ``auto`` picks the serial ``cg``) and ``gamg`` otherwise: on bar3d, 40 Jacobi
iterations per solve cost half the time of 15 GAMG ones (docs/performance.md).

The rows of one contact node stay on one rank (the row blocks end at node boundaries,
:func:`node_row_bounds`), so for the orthonormal rows of a rigid obstacle the projection
P = I - B_A^T B_A is local: no communication beyond the products and dot products of CG
itself.  The rows of contact pairs (:mod:`~signorini.contact.pairs`: a slave node and a
master facet's nodes, possibly on two ranks) are not orthonormal: there
P = I - B_A^T G^-1 B_A with G = B_A B_A^T factored once per active set on every rank
(:class:`~signorini.contact.solver.GramFactor`), and an application of P costs one
``Allreduce`` of |A| numbers (the sum of the ranks' parts of B_A v).  CG stops as the
serial one does, when |P (r - K w)| <= rtol |P r| (unpreconditioned 2-norm), started from
the previous solution (``set_guess``: a scheme's predictor).

The state vectors stay replicated (docs/parallel.md): a solve hands each rank its rows of
the right-hand side and the start, and one ``Allgatherv`` gives every rank the solution.
PETSc options pass through under the prefix ``signorini_`` to the preconditioner
(``--solver-option petsc.pc_gamg_threshold=0.02``); the Krylov method itself stays CG.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from ..errors import ConvergenceError, InputError
from ..linalg.petsc import load
from ..linalg.petsc.factor import PREFIX, _options_text
from ..linalg.row_block import RowBlock, node_row_bounds
from ..parallel import run_comm
from .solver import ActiveSetCGSolver, ContactSolver, GramFactor, _best_time

#: preconditioners of ``petsc-cg`` (PETSc PC types)
PRECONDITIONERS = ("gamg", "jacobi")


class _Projected:
    """``y = P Q P x`` with the solver's current local projection P around ``apply(x, y)``:
    petsc4py's Python matrix (``mult``, Q = K) and Python preconditioner (``apply``, Q the inner PC)."""

    def __init__(self, apply, solver: DistributedCGSolver, vec):
        self.inner, self.solver = apply, solver
        self.t = vec.duplicate()

    def apply(self, _owner, x, y) -> None:
        x.copy(self.t)
        self.solver._project_vec(self.t)
        self.inner(self.t, y)
        self.solver._project_vec(y)

    mult = apply


class DistributedCGSolver(ActiveSetCGSolver):
    """Projected CG on PETSc under the serial active-set iteration (see the module docstring).

    Parameters
    ----------
    K : (n, n) the operator on the free dofs (the same scipy matrix on every rank).
    B : (nc, n) the contact rows: a unit normal on one node's dofs (rigid obstacle), or a
        slave node's and a master facet's (contact pairs, rows that may span two ranks).
    nodes : (n,) the mesh node of each row (row blocks end at node boundaries).
    modes : (n, k) orthonormal rigid-body motions of the rows (``gamg``'s near-null space).
    """

    def __init__(
        self,
        K: sp.spmatrix,
        B: sp.csr_matrix,
        gap_scale: float,
        nodes: np.ndarray,
        modes: np.ndarray | None,
        preconditioner: str = "jacobi",
        rtol: float = 1e-12,
        max_iter: int = 2000,
        max_newton: int = 30,
    ):
        ContactSolver.__init__(self)
        MPI, PETSc = load()
        self.MPI, self.PETSc = MPI, PETSc
        if preconditioner not in PRECONDITIONERS:
            raise InputError(
                f"solver option 'preconditioner' of backend petsc-cg must be one of {', '.join(PRECONDITIONERS)}; "
                f"got {preconditioner!r}"
            )
        t0 = time.perf_counter()
        comm = self.comm = PETSc.COMM_WORLD
        if not isinstance(K, RowBlock):  # the same matrix on every rank: blocks of whole nodes' rows
            K = RowBlock.of(K, node_row_bounds(nodes, comm.size), run_comm("petsc-cg"))
        self.B = sp.csr_matrix(B)
        n = self.n = K.shape[0]
        self.bounds = K.bounds
        lo, hi = self.lo, self.hi = K.lo, K.hi
        self.counts = np.diff(self.bounds).astype(np.int64)
        self._K = K
        self._rows_layout()

        bs = _block(nodes) if np.all(self.counts % _block(nodes) == 0) else 1
        # jacobi: the upper triangle in d x d blocks (SBAIJ) reads about half the bytes of a
        # product; GAMG takes AIJ only  -- docs/performance.md
        A = _matrix(PETSc, comm, K.local, n, lo, bs, symmetric=preconditioner == "jacobi")
        A.setOption(PETSc.Mat.Option.SPD, True)
        A.assemble()
        if modes is not None and preconditioner == "gamg":
            vecs = []
            for col in modes.T:
                v = A.createVecRight()
                v.setArray(col[lo:hi])
                vecs.append(v)
            A.setNearNullSpace(PETSc.NullSpace().create(vectors=vecs, comm=comm))
        inner = PETSc.PC().create(comm=comm)
        inner.setOptionsPrefix(PREFIX)
        inner.setOperators(A)
        inner.setType(preconditioner)
        try:
            inner.setFromOptions()
            if inner.getType() != preconditioner:
                raise InputError(
                    f"backend petsc-cg takes its preconditioner from the solver option 'preconditioner' "
                    f"({', '.join(PRECONDITIONERS)}), not from petsc.pc_type; the petsc.* options were "
                    f"{_options_text()}"
                )
            inner.setUp()
        except PETSc.Error as exc:
            raise InputError(
                f"PETSc refused the preconditioner {preconditioner!r} with the petsc.* options ({_options_text()}): "
                f"error {exc.ierr}"
            ) from None
        self.A, self.inner = A, inner
        shell = _Projected(A.mult, self, A.createVecRight())
        op = PETSc.Mat().createPython(((hi - lo, n), (hi - lo, n)), shell, comm=comm)
        op.setUp()
        ksp = PETSc.KSP().create(comm=comm)
        ksp.setType(PETSc.KSP.Type.CG)
        ksp.setOperators(op, A)
        ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
        ksp.setTolerances(rtol=rtol, atol=0.0, divtol=1e300, max_it=max_iter)
        ksp.setInitialGuessNonzero(True)
        pc = ksp.getPC()
        pc.setType(PETSc.PC.Type.PYTHON)
        pc.setPythonContext(_Projected(inner.apply, self, A.createVecLeft()))
        ksp.setUp()
        self.ksp, self.op = ksp, op
        self.xv, self.bv = A.createVecRight(), A.createVecLeft()
        self._local_projection = None
        self.name = f"petsc-cg+{preconditioner}"
        self.condensation = "none"
        self.rtol, self.max_iter, self.max_newton = rtol, max_iter, max_newton
        self.c = float(np.mean(K.diagonal()))
        #: K's rows at the contact dofs (replicated, small): the active-set step's products
        self.contact_dofs = np.unique(self.B.indices)
        self.K_contact = K.rows(self.contact_dofs)
        self.active = np.zeros(self.B.shape[0], dtype=bool)
        self.U_prev = np.zeros(n)
        self.gap_scale = max(gap_scale, 1e-300)
        self.timings = {"factorization": time.perf_counter() - t0, "condensation": 0.0}
        self.timings["bare_spmv"] = _best_time(self._spmv, n)
        self._bare = {"bare_spmv": (self._spmv, n)}

    def _rows_layout(self) -> None:
        """Whether some row of B spans two ranks (a pair's slave and master nodes): the projection
        is then shared (:attr:`straddles`)."""
        owner = np.searchsorted(self.bounds, self.B.indices, side="right") - 1
        row_of = np.repeat(np.arange(self.B.shape[0]), np.diff(self.B.indptr))
        split = np.zeros(self.B.shape[0], dtype=bool)
        np.logical_or.at(split, row_of, owner != owner[np.searchsorted(row_of, row_of)])
        #: some row spans two ranks (a pair's slave and master nodes): the projection is shared
        self.straddles = bool(split.any())

    def replace_rows(self, rows: np.ndarray, B: sp.csr_matrix) -> None:
        """The new B (every rank the same, in step): its layout across the ranks and K's rows at
        its contact dofs (a collective when they changed)."""
        self.B = sp.csr_matrix(B)
        self._rows_layout()
        dofs = np.unique(self.B.indices)
        if not np.array_equal(dofs, self.contact_dofs):
            self.contact_dofs = dofs
            self.K_contact = self._K.rows(dofs)

    def _rows_of_K(self, rows: np.ndarray) -> sp.csr_matrix:
        """K's rows at active contact dofs, from the replicated contact rows (no rank holds K)."""
        return self.K_contact[np.searchsorted(self.contact_dofs, rows)]

    # -- the projection of the active set, on this rank's rows -------------------------
    def _projector(self, BA: sp.csr_matrix, gram: GramFactor | None = None):
        """P on this rank's rows: :class:`_LocalProjection` for orthonormal rows that stay
        on their ranks (``gram`` None, as a rigid obstacle's: no communication), else
        :class:`_SharedProjection` (one ``Allreduce`` per application); None when P = I here.

        Parameters
        ----------
        BA : (m, n) the active rows of B (the same on every rank).
        gram : the factor of B_A B_A^T (:func:`~signorini.contact.solver.gram_factor`).
        """
        if BA.shape[0] == 0:
            return None
        if gram is not None or self.straddles:
            mine = np.unique(BA.indices[(BA.indices >= self.lo) & (BA.indices < self.hi)])
            Bc = BA[:, mine].tocsr()  # (m, k): every rank takes part in the sum, k = 0 included
            return _SharedProjection(mine - self.lo, Bc, Bc.T.tocsr(), gram, self.comm.tompi4py(), self.MPI)
        mine = (BA.indices >= self.lo) & (BA.indices < self.hi)
        rows_of = np.repeat(np.arange(BA.shape[0]), np.diff(BA.indptr))
        keep = np.unique(rows_of[mine])
        if keep.size == 0:
            return None
        Bl = BA[keep]
        cols = np.unique(Bl.indices)
        Br = Bl[:, cols].tocsr()
        return _LocalProjection(cols - self.lo, Br, Br.T.tocsr())

    def _project_local(self, v: np.ndarray, projection) -> None:
        if projection is not None:
            projection(v)

    def _project_vec(self, vec) -> None:
        if self._local_projection is not None:
            with vec as a:
                self._project_local(a, self._local_projection)

    # -- products and solves -----------------------------------------------------------
    def _gather(self, local: np.ndarray) -> np.ndarray:
        out = np.empty(self.n)
        self.comm.tompi4py().Allgatherv(
            np.ascontiguousarray(local), [out, self.counts, self.counts.cumsum() - self.counts, self.MPI.DOUBLE]
        )
        return out

    def _spmv(self, x: np.ndarray) -> np.ndarray:
        """A distributed product K x (the bare cost of one CG iteration's product)."""
        self.xv.setArray(x[self.lo : self.hi])
        self.A.mult(self.xv, self.bv)
        return self.bv.getArray(readonly=True)

    def _cg(self, rhs: np.ndarray, x0: np.ndarray, project) -> np.ndarray:
        self._local_projection = project
        lo, hi = self.lo, self.hi
        b = np.array(rhs[lo:hi], dtype=np.float64)
        x = np.array(x0[lo:hi], dtype=np.float64)
        self._project_local(b, project)
        self._project_local(x, project)
        self.bv.setArray(b)
        self.xv.setArray(x)
        self.ksp.solve(self.bv, self.xv)
        reason, its = self.ksp.getConvergedReason(), self.ksp.getIterationNumber()
        self._local_projection = None
        self.counters["linear_solves"] += 1
        self.counters["krylov_iterations"] += its
        if reason < 0:
            names = {v: k for k, v in vars(self.PETSc.KSP.ConvergedReason).items() if isinstance(v, int)}
            raise ConvergenceError(
                f"PETSc CG did not converge in {its} iterations ({names.get(reason, 'reason')} {reason}, "
                f"rtol {self.rtol:g}, max_iter {self.max_iter}); an indefinite preconditioner (DIVERGED_INDEFINITE_PC) "
                "comes from petsc.* options that do not suit a mass with massless dofs"
            )
        return self._gather(self.xv.getArray(readonly=True))


class _LocalProjection:
    """v_loc <- (I - B_r^T B_r) v_loc on this rank's rows: B_r (m_r, k) the orthonormal active
    rows that this rank holds, on their columns ``idx`` (k,) (local row numbers)."""

    def __init__(self, idx: np.ndarray, Br: sp.csr_matrix, BrT: sp.csr_matrix):
        self.idx, self.Br, self.BrT = idx, Br, BrT

    def __call__(self, v: np.ndarray) -> None:
        v[self.idx] -= self.BrT @ (self.Br @ v[self.idx])


class _SharedProjection:
    """v_loc <- (P v)_loc, P = I - B_A^T G^-1 B_A, for rows that span ranks:

        y = sum over ranks of B_c v_loc[idx]   (m,) one Allreduce,
        v_loc[idx] -= B_c^T G^-1 y,

    with B_c (m, k) the columns of B_A in this rank's rows (``idx`` (k,) local numbers,
    k = 0 possible: the rank still adds its zeros) and ``gram`` the factor of G
    (None: G = I, orthonormal rows).  Collective: every rank applies it together."""

    def __init__(self, idx: np.ndarray, Bc: sp.csr_matrix, BcT: sp.csr_matrix, gram: GramFactor | None, comm, MPI):
        self.idx, self.Bc, self.BcT, self.gram, self.comm, self.MPI = idx, Bc, BcT, gram, comm, MPI

    def __call__(self, v: np.ndarray) -> None:
        part = np.ascontiguousarray(self.Bc @ v[self.idx], dtype=np.float64)
        y = np.empty_like(part)
        self.comm.Allreduce(part, y, op=self.MPI.SUM)
        z = y if self.gram is None else self.gram.solve(y)
        v[self.idx] -= self.BcT @ z


def _matrix(PETSc, comm, Kr: sp.csr_matrix, n: int, lo: int, bs: int, symmetric: bool):
    """This rank's rows Kr (m, n) of K, from row ``lo`` on, as a distributed PETSc matrix with
    block size d: MPISBAIJ (the d x d blocks on and above the diagonal) when ``symmetric``,
    else MPIAIJ (what GAMG takes)."""
    hi = lo + Kr.shape[0]
    if symmetric:
        C = Kr.tocoo()
        keep = C.col // bs >= (C.row + lo) // bs
        Kr = sp.csr_matrix((C.data[keep], (C.row[keep], C.col[keep])), shape=Kr.shape)
    itype = PETSc.IntType
    if not symmetric:
        Kr.sort_indices()
        csr = (Kr.indptr.astype(itype), Kr.indices.astype(itype), Kr.data.astype(PETSc.ScalarType))
        return PETSc.Mat().createAIJ(size=((hi - lo, n), (hi - lo, n)), bsize=bs, csr=csr, comm=comm)
    Br = sp.bsr_matrix(Kr, blocksize=(bs, bs))
    Br.sort_indices()
    csr = (Br.indptr.astype(itype), Br.indices.astype(itype), Br.data.reshape(-1).astype(PETSc.ScalarType))
    return PETSc.Mat().createSBAIJ(size=((hi - lo, n), (hi - lo, n)), bsize=bs, csr=csr, comm=comm)


def _block(nodes: np.ndarray) -> int:
    """d when every node has the same number d of consecutive rows, else 1."""
    nodes = np.asarray(nodes)
    if nodes.size == 0:
        return 1
    runs = np.diff(np.flatnonzero(np.r_[True, nodes[1:] != nodes[:-1], True]))
    return int(runs[0]) if np.all(runs == runs[0]) else 1
