"""A parallel MUMPS Cholesky factor of K behind the serial :class:`~signorini.linalg.Factor` contract.

K (the free block of a scheme's operator) comes as each rank's own block of rows, a
:class:`~signorini.linalg.row_block.RowBlock` (the run's context forms only those rows,
in blocks of whole nodes; a scipy matrix given whole on every rank is split evenly,
:func:`row_bounds`): rank r inserts rows [lo_r, hi_r) into an MPIAIJ matrix, marked
SPD, and MUMPS factors it once (``-pc_type cholesky -pc_factor_mat_solver_type mumps``: its own parallel analysis
and mapping, so the input distribution only decides who sends which rows).  A solve
takes a right-hand side that is the same on every rank, shape (n,) or (n, k), gives each
rank its rows, runs MUMPS's distributed forward/backward substitution (``MatSolve``, or
``MatMatSolve`` for a block of k columns: the Delassus columns) and gathers the answer
on every rank, so that everything after it (the Delassus matrix W, the contact law)
runs unchanged and identically on every rank.

PETSc options pass through under the prefix ``signorini_`` (``--solver-option
petsc.mat_mumps_icntl_14=80`` sets ``-signorini_mat_mumps_icntl_14 80``), as dolfinx
does with its own prefixes.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ...errors import InputError
from ...parallel import run_comm
from ..base import Factor
from ..row_block import RowBlock, row_bounds
from . import load

PREFIX = "signorini_"


def _given(options: dict) -> dict[str, str]:
    """The ``petsc.NAME=VALUE`` solver options as PETSc option names (``signorini_NAME``)."""
    return {PREFIX + k[len("petsc.") :]: str(v) for k, v in options.items() if k.startswith("petsc.")}


def set_options(options: dict) -> None:
    """Put ``petsc.NAME=VALUE`` solver options into PETSc's database as ``-signorini_NAME VALUE``
    (removed again by :func:`clear_options`; PETSc's own report of unused options at
    exit is off: :func:`check_options_used` refuses them instead)."""
    _, PETSc = load()
    db = PETSc.Options()
    db["options_left"] = "0"
    for name, value in _given(options).items():
        db[name] = value


def clear_options(options: dict) -> None:
    """Remove the ``petsc.`` options from PETSc's database: the next run in this process
    starts from a clean one."""
    _, PETSc = load()
    db = PETSc.Options()
    for name in _given(options):
        db.delValue(name)


def check_options_used(options: dict, reader: str = "PETSc's MUMPS Cholesky") -> None:
    """InputError naming the ``petsc.`` options that PETSc did not read (misspelled, or not
    an option of ``reader``, the PETSc object that reads them: PETSc itself would ignore
    them silently)."""
    _, PETSc = load()
    db = PETSc.Options()
    unused = [k for k in options if k.startswith("petsc.") and not db.used(PREFIX + k[len("petsc.") :])]
    if unused:
        raise InputError(
            f"solver option(s) {', '.join(map(repr, unused))} were not used by {reader} "
            "(misspelled, or options of another PETSc object); see `-help` of a PETSc program or docs/parallel.md"
        )


def _options_text() -> str:
    """The ``signorini_`` options now in PETSc's database, as the user gave them."""
    _, PETSc = load()
    opts = PETSc.Options().getAll()
    given = [f"petsc.{k[len(PREFIX) :]}={v}" for k, v in opts.items() if k.startswith(PREFIX)]
    return ", ".join(given) or "none"


#: MUMPS instances of factors released (:meth:`PetscFactor.release`), kept for the next factorization of the
#: same pattern (a Newton iterate's tangent, finite strain).  With PETSc 3.25's MUMPS a process that destroyed
#: each instance right after its last use failed inside MUMPS after 400-500 of them (MUMPS_LOAD_RECV_MSGS,
#: measured on 2 ranks); destroyed later (an adversarial review: 1,500 instances with one kept) or reused (a
#: kept instance refactorizes new values on its own analysis, 1,000 times measured) it runs.  Every rank
#: keeps the same list in the same order (releases are collective), a pattern is each rank's own rows, so an
#: instance is taken back only where every rank's pattern matches (:func:`_take_kept`), and the oldest goes
#: beyond :data:`KEPT_MAX` (each holds its factor's memory).
KEPT: list[tuple[tuple, tuple]] = []
KEPT_MAX = 2


def _same(a: tuple, b: tuple) -> bool:
    return a[:4] == b[:4] and np.array_equal(a[4], b[4]) and np.array_equal(a[5], b[5])


def _take_kept(pattern: tuple, comm) -> tuple | None:
    """The first kept instance whose pattern is this one on every rank (a collective), taken out of the list."""
    MPI, _ = load()
    mine = np.array([_same(p, pattern) for p, _ in KEPT] or [False], dtype=np.int32)
    every = np.empty_like(mine)
    comm.tompi4py().Allreduce(mine, every, op=MPI.MIN)
    if not KEPT or not every.any():
        return None
    return KEPT.pop(int(np.argmax(every)))[1]


def _keep(pattern: tuple, objects: tuple) -> None:
    _, PETSc = load()
    KEPT.append((pattern, objects))
    while len(KEPT) > KEPT_MAX:
        for obj in KEPT.pop(0)[1]:
            if not PETSc.Sys.isFinalized():
                obj.destroy()


class PetscFactor(Factor):
    """MUMPS Cholesky of K on every rank of ``COMM_WORLD`` (see the module docstring)."""

    name = "petsc"
    #: its solves give each rank its own rows (:meth:`solve_owned`): the contact solver keeps
    #: the Delassus columns distributed (:mod:`signorini.contact.distributed_columns`)
    distributed = True

    def __init__(self, K: sp.spmatrix):
        super().__init__()
        MPI, PETSc = load()
        self.MPI, self.PETSc = MPI, PETSc
        comm = self.comm = PETSc.COMM_WORLD
        if not isinstance(K, RowBlock):  # the same matrix on every rank: an even block of rows each
            K = RowBlock.of(K, row_bounds(K.shape[0], comm.size), run_comm("petsc"))
        n = K.shape[0]
        self.bounds = K.bounds
        lo, hi = K.lo, K.hi
        self.lo, self.hi, self.n = lo, hi, n
        Kr = K.local
        Kr.sort_indices()
        indptr, indices = Kr.indptr.astype(PETSc.IntType), Kr.indices.astype(PETSc.IntType)
        self._pattern = (n, lo, hi, _options_text(), indptr, indices)
        kept = _take_kept(self._pattern, comm)
        if kept is not None:  # the same pattern factorized before: its MUMPS instance factorizes the new values
            A, pc, x, b = kept
            A.setValuesCSR(indptr, indices, Kr.data.astype(PETSc.ScalarType))
            A.assemble()
            pc.setOperators(A)
            db = PETSc.Options()  # the same petsc.* options (part of the pattern), read at its first set-up:
            for name in db.getAll():  # queried again, so that check_options_used finds them used
                if name.startswith(PREFIX):
                    db.getString(name)
        else:
            A, pc = self._new_instance(indptr, indices, Kr.data.astype(PETSc.ScalarType), lo, hi)
            x, b = A.createVecRight(), A.createVecLeft()
        self._set_up(pc)
        self.A, self.pc, self.x, self.b = A, pc, x, b
        self.F = pc.getFactorMatrix()
        self.counts = (np.diff(self.bounds)).astype(np.int64)

    def _new_instance(self, indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, lo: int, hi: int) -> tuple:
        """(A, pc): this rank's rows as an SPD MPIAIJ matrix and a MUMPS Cholesky PC on it, not yet set up."""
        PETSc, comm, n = self.PETSc, self.comm, self.n
        A = PETSc.Mat().createAIJ(size=((hi - lo, n), (hi - lo, n)), csr=(indptr, indices, data), comm=comm)
        A.setOption(PETSc.Mat.Option.SPD, True)
        A.assemble()
        pc = PETSc.PC().create(comm=comm)
        pc.setOptionsPrefix(PREFIX)
        pc.setOperators(A)
        pc.setType(PETSc.PC.Type.CHOLESKY)
        pc.setFactorSolverType("mumps")
        try:
            pc.setFromOptions()
        except PETSc.Error as exc:
            raise InputError(
                f"PETSc refused the petsc.* solver options ({_options_text()}): error {exc.ierr}"
            ) from None
        if pc.getType() != PETSc.PC.Type.CHOLESKY or pc.getFactorSolverType() != "mumps":
            raise InputError(
                f"the petsc backend is a MUMPS Cholesky factorization; the petsc.* options ({_options_text()}) made it "
                f"{pc.getType()} with {pc.getFactorSolverType()}: leave pc_type and pc_factor_mat_solver_type alone"
            )
        return A, pc

    def _set_up(self, pc) -> None:
        """Factorize (MUMPS's analysis once per instance, then its numeric factorization)."""
        PETSc = self.PETSc
        try:
            pc.setUp()
        except PETSc.Error as exc:
            given = _options_text()
            if given != "none":  # a value PETSc or MUMPS rejects (e.g. icntl_14=abc)
                raise InputError(
                    f"the MUMPS Cholesky factorization failed with the petsc.* solver options ({given}): PETSc error "
                    f"{exc.ierr}; check their names and values, or run without them"
                ) from None
            raise RuntimeError(f"MUMPS Cholesky failed (PETSc error {exc.ierr})") from None
        try:
            info = int(pc.getFactorMatrix().getMumpsInfog(1))
        except (AttributeError, PETSc.Error):  # pragma: no cover - an older petsc4py
            info = 0
        if info < 0:  # PETSc does not raise when MUMPS fails numerically: its solves would be NaN
            raise RuntimeError(
                f"MUMPS Cholesky failed (INFOG(1) = {info}: -9 and -8 are too small a workspace, raise "
                "petsc.mat_mumps_icntl_14; -10 a singular matrix)"
            )

    def release(self) -> None:
        """No longer of use (a Newton iterate's tangent done with): its MUMPS instance is kept for the next
        factorization of the same pattern (:data:`KEPT`).  Called on every rank at the same point of the run
        (a collective: never from a finalizer, whose time differs from rank to rank)."""
        if self.pc is not None:
            _keep(self._pattern, (self.A, self.pc, self.x, self.b))
            self.A = self.pc = self.F = self.x = self.b = None

    @property
    def nbytes(self) -> int:
        """Entries of the factor over all ranks (MUMPS INFOG(29), 8 bytes each, plus 4
        per integer of INFOG(10))."""
        try:
            entries = self.F.getMumpsInfog(29)
            ints = self.F.getMumpsInfog(10)
        except (AttributeError, self.PETSc.Error):  # pragma: no cover - an older petsc4py
            return 0
        entries = entries if entries >= 0 else -entries * 1_000_000  # MUMPS: negative = millions
        return int(8 * entries + 4 * max(ints, 0))

    def _gather(self, local: np.ndarray, k: int) -> np.ndarray:
        """The full (n, k) array from every rank's rows (the same result on every rank)."""
        out = np.empty((self.n, k))
        counts = self.counts * k
        recv = [out, counts, counts.cumsum() - counts, self.MPI.DOUBLE]
        self.comm.tompi4py().Allgatherv(np.ascontiguousarray(local), recv)
        return out

    def _solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=float)
        return self.gather(self._solve_owned(b[self.lo : self.hi]))

    def solve_owned(self, b: np.ndarray) -> np.ndarray:
        """This rank's rows of K^-1 b from this rank's rows of b, (m,) or (m, k); no gather
        (the distributed Delassus columns keep their Z rows where they are computed)."""
        self.solves += 1 if b.ndim == 1 else int(b.shape[1])
        return self._solve_owned(b)

    def _solve_owned(self, b: np.ndarray) -> np.ndarray:
        lo, hi = self.lo, self.hi
        if b.ndim == 1:
            self.b.setArray(b)
            self.F.solve(self.b, self.x)
            return self.x.getArray(readonly=True).copy()
        k = b.shape[1]
        PETSc = self.PETSc
        Bm = PETSc.Mat().createDense(((hi - lo, self.n), (k, k)), array=np.asfortranarray(b), comm=self.comm)
        Xm = PETSc.Mat().createDense(((hi - lo, self.n), (k, k)), comm=self.comm)
        Xm.setUp()
        self.F.matSolve(Bm, Xm)
        out = np.array(Xm.getDenseArray(readonly=True))  # (hi - lo, k)
        Bm.destroy()
        Xm.destroy()
        return out

    def gather(self, local: np.ndarray) -> np.ndarray:
        """The full (n,) or (n, k) array from every rank's rows, on every rank."""
        if local.ndim == 1:
            return self._gather(local, 1).ravel()
        return self._gather(np.ascontiguousarray(local), local.shape[1])

    def allreduce(self, a: np.ndarray) -> np.ndarray:
        """The sum over the ranks of ``a`` (the same shape on every rank)."""
        out = np.empty_like(a)
        self.comm.tompi4py().Allreduce(np.ascontiguousarray(a), out, op=self.MPI.SUM)
        return out
