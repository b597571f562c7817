"""Sparse factorizations of the CN operator K = 4/dt^2 M + S (seed mass, free dofs) side by side.

Usage: python -m benchmarks.bench_factor [--cases bar3d-8 tet-8 ...] [--methods superlu cholmod ...]
                                          [--out out/bench]

Cases: ``bar3d-N`` is the benchmark's bar (Q1 hexahedra, N x N x 10N cells, dt = h/2);
``tet-N`` the same box cut into six P1 tetrahedra per cube with its nodes numbered at
random (a stand-in for an unstructured mesh's numbering).  Methods: every registered
direct backend (``backend:NAME``, e.g. ``backend:superlu``) and the experimental
variants of :data:`VARIANTS` (SuperLU with other column orderings, SuperLU on a matrix
pre-permuted by METIS, CHOLMOD through cvxopt, QDLDL).

Each (case, method) runs in a fresh process; it prints factor size (values + indices of
the stored factor, 12 bytes per entry, where the library reports it; else the resident
memory the factor holds once built), factorization time, time of one solve with 1 and
with 64 right-hand sides, peak resident memory and the relative residual
|K x - b| / |b|.  Writes ``factor.json`` and ``factor.md`` into ``--out``.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

CACHE = Path("out/bench/factor-cache")


def operator(case: str) -> sp.csc_matrix:
    """K on the free dofs of ``case`` (cached as .npz so that each process only loads it)."""
    path = CACHE / f"{case}.npz"
    if path.exists():
        return sp.load_npz(path).tocsc()
    import dataclasses

    from signorini.dynamics.model.problem import discretize
    from signorini.fem.mesh import box
    from signorini.studies.benchmarks import get_benchmark

    kind, n = case.rsplit("-", 1)
    n = int(n)
    b = get_benchmark("bar3d")
    problem = b.problem(n)
    if kind == "tet":
        problem = dataclasses.replace(problem, mesh=box(n, n, 10 * n, 0.1, 0.1, 1.0, cell="tetra"))
    d = discretize(problem, "seed")
    dt = b.h(n) / 2
    f = d.free
    K = (4 / dt**2 * d.M + d.S).tocsr()[f][:, f]
    if kind == "tet":  # random numbering of the nodes (dof triplets kept together)
        rng = np.random.default_rng(0)
        nodes = rng.permutation(K.shape[0] // 3)
        p = (3 * nodes[:, None] + np.arange(3)).ravel()
        K = K[p][:, p]
    else:
        p = np.arange(K.shape[0])
    K = sp.csc_matrix(K)
    CACHE.mkdir(parents=True, exist_ok=True)
    sp.save_npz(path, K)
    # contact dofs (3 per contact node) in K's numbering, for the Schur complement
    full_to_free = -np.ones(d.M.shape[0], dtype=np.int64)
    full_to_free[f] = np.arange(f.size)
    where = np.empty_like(p)
    where[p] = np.arange(p.size)
    contact = where[full_to_free[(3 * d.contact.nodes[:, None] + np.arange(3)).ravel()]]
    np.save(CACHE / f"{case}-contact.npy", np.sort(contact))
    return K


def _rss_now() -> int:
    """Current resident memory [bytes]."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * resource.getpagesize()


def _metis_order(K: sp.csc_matrix, nodal: bool) -> np.ndarray:
    """Nested-dissection ordering of K's graph by METIS (pymetis), on the dofs or on the
    nodes (dof triplets) expanded back to dofs."""
    from signorini.linalg.ordering import metis_nested_dissection

    if nodal:
        return metis_nested_dissection(K)
    import pymetis

    G = sp.csr_matrix((np.ones(K.nnz), K.indices, K.indptr), shape=K.shape)
    G.setdiag(0)
    G.eliminate_zeros()
    perm, _ = pymetis.nested_dissection(pymetis.CSRAdjacency(G.indptr, G.indices))
    return np.asarray(perm)


def _nd_order(K: sp.csc_matrix) -> np.ndarray:
    from signorini.linalg.ordering import nested_dissection

    t0 = time.perf_counter()
    p = nested_dissection(K)
    print(f"ordering {time.perf_counter() - t0:.2f} s", file=sys.stderr)
    return p


class _Variant:
    """A factor built by one of the experimental methods: ``solve``, ``nbytes``."""

    nbytes = 0

    def solve(self, b):  # pragma: no cover - interface
        raise NotImplementedError


class _SuperLU(_Variant):
    def __init__(self, K, permc="MMD_AT_PLUS_A", order=None):
        import scipy.sparse.linalg as spla

        self.p = order
        A = K if order is None else K[order][:, order]
        self._lu = spla.splu(sp.csc_matrix(A), permc_spec=permc, diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        self.nbytes = 12 * (self._lu.L.nnz + self._lu.U.nnz)

    def solve(self, b):
        if self.p is None:
            return self._lu.solve(b)
        x = np.empty_like(b)
        x[self.p] = self._lu.solve(b[self.p])
        return x


class _CvxoptCholmod(_Variant):
    def __init__(self, K, order=None):
        import cvxopt
        import cvxopt.cholmod

        L = sp.tril(K, format="coo")
        A = cvxopt.spmatrix(L.data, L.row.astype(int), L.col.astype(int), K.shape)
        p = None if order is None else cvxopt.matrix(np.asarray(order, dtype=int))
        self._F = cvxopt.cholmod.symbolic(A, p=p, uplo="L")
        cvxopt.cholmod.numeric(A, self._F)
        self._cvxopt = cvxopt

    def solve(self, b):
        B = self._cvxopt.matrix(np.asarray(b, dtype=float).reshape(b.shape[0], -1))
        self._cvxopt.cholmod.solve(self._F, B)
        return np.array(B).reshape(b.shape)


class _QDLDL(_Variant):
    def __init__(self, K):
        import qdldl

        self._s = qdldl.Solver(sp.csc_matrix(K))
        self.nbytes = 12 * self._s.factors()[0].nnz

    def solve(self, b):
        if b.ndim == 1:
            return self._s.solve(b)
        return np.column_stack([self._s.solve(b[:, j]) for j in range(b.shape[1])])


class _Cholespy(_Variant):
    def __init__(self, K):
        import cholespy

        A = sp.csc_matrix(K)
        self._s = cholespy.CholeskySolverD(
            A.shape[0], A.indptr.astype(np.int32), A.indices.astype(np.int32), A.data, cholespy.MatrixType.CSC
        )

    def solve(self, b):
        b = np.ascontiguousarray(b, dtype=float)
        x = np.empty_like(b)
        self._s.solve(b, x)
        return x


def _mumps_context(K: sp.spmatrix, schur: np.ndarray | None = None, keep: bool = True):
    """A python-mumps context on the upper triangle of K in SPD mode (SYM = 1), METIS
    ordering, no pivoting; with ``schur`` the Schur complement on those dofs is formed
    (dense, centralized) and the factor of the rest kept when ``keep``."""
    import mumps
    from mumps import _mumps
    from mumps.mumps import _make_assembled_from_coo

    ctx = mumps.Context()
    a = sp.triu(K, format="coo")
    dtype, row, col, data = _make_assembled_from_coo(a, False)
    ctx.mumps_instance = _mumps.dmumps(False, 1)
    ctx.dtype, ctx.n, ctx.row, ctx.col, ctx.data = dtype, K.shape[0], row, col, data
    ctx.mumps_instance.set_assembled_matrix(K.shape[0], row, col, data)
    S = None
    if schur is not None:
        from mumps.mumps import _makemumps_index_array

        idx = _makemumps_index_array(np.asarray(schur))
        S = np.zeros((idx.size, idx.size), order="C")
        ctx.mumps_instance.icntl[19] = 1
        ctx.mumps_instance.icntl[31] = 0 if keep else 1
        ctx.mumps_instance.set_schur(S, idx)
    ctx.analyze(ordering="metis")
    ctx.factor(reuse_analysis=True, pivot_tol=0.0)
    return ctx, S


class _Mumps(_Variant):
    def __init__(self, K):
        self._ctx, _ = _mumps_context(K)
        self.nbytes = 12 * self._ctx.factor_stats.nonzeros

    def solve(self, b):
        return self._ctx.solve(np.array(b, dtype=float, order="F"))


VARIANTS = {
    "superlu-colamd": ("SuperLU, COLAMD column ordering", lambda K: _SuperLU(K, "COLAMD")),
    "superlu-mmd-ata": ("SuperLU, MMD on A^T A", lambda K: _SuperLU(K, "MMD_ATA")),
    "superlu-metis-dofs": (
        "SuperLU NATURAL on K pre-permuted by METIS nested dissection of the dof graph",
        lambda K: _SuperLU(K, "NATURAL", _metis_order(K, nodal=False)),
    ),
    "superlu-metis-nodes": (
        "SuperLU NATURAL on K pre-permuted by METIS nested dissection of the node graph",
        lambda K: _SuperLU(K, "NATURAL", _metis_order(K, nodal=True)),
    ),
    "cvxopt-cholmod": ("CHOLMOD (supernodal, AMD) inside cvxopt", _CvxoptCholmod),
    "superlu-nd": (
        "SuperLU NATURAL on K pre-permuted by signorini.linalg.ordering.nested_dissection",
        lambda K: _SuperLU(K, "NATURAL", _nd_order(K)),
    ),
    "cvxopt-cholmod-nd": (
        "CHOLMOD inside cvxopt, signorini's nested dissection",
        lambda K: _CvxoptCholmod(K, _nd_order(K)),
    ),
    "cvxopt-cholmod-metis": (
        "CHOLMOD inside cvxopt, METIS nested dissection of the node graph",
        lambda K: _CvxoptCholmod(K, _metis_order(K, nodal=True)),
    ),
    "cholespy": ("CHOLMOD (supernodal, METIS/AMD, reference BLAS) inside cholespy", _Cholespy),
    "mumps": ("MUMPS through python-mumps, SPD mode, METIS ordering", _Mumps),
    "qdldl": ("QDLDL (up-looking LDL^T, AMD)", _QDLDL),
}


def build(method: str, K: sp.csc_matrix):
    if method.startswith("backend:"):
        from signorini.linalg import factorize

        return factorize(K, method.split(":", 1)[1])
    return VARIANTS[method][1](K)


def _best(fn, repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def one(case: str, method: str) -> dict:
    K = operator(case)
    n = K.shape[0]
    rng = np.random.default_rng(1)
    b1, b64 = rng.standard_normal(n), rng.standard_normal((n, 64))
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    rss0 = _rss_now()
    t0 = time.perf_counter()
    F = build(method, K)
    t_factor = time.perf_counter() - t0
    held = _rss_now() - rss0
    x = F.solve(b1)
    res = float(np.linalg.norm(K @ x - b1) / np.linalg.norm(b1))
    X = F.solve(b64)
    res64 = float(np.max(np.linalg.norm(K @ X - b64, axis=0) / np.linalg.norm(b64, axis=0)))
    t1 = _best(lambda: F.solve(b1), 3)
    t64 = _best(lambda: F.solve(b64), 2)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return {
        "case": case,
        "method": method,
        "dofs": n,
        "nnz_K": K.nnz,
        "factor_MB": F.nbytes / 1e6 if F.nbytes else float("nan"),
        "held_MB": held / 1e6,
        "factor_s": t_factor,
        "solve1_ms": 1e3 * t1,
        "solve64_ms": 1e3 * t64,
        "peak_MB": peak / 1e6,
        "peak_over_K_MB": (peak - base) / 1e6,
        "residual": max(res, res64),
    }


def one_schur(case: str, keep: bool) -> dict:
    """MUMPS Schur complement of K on the contact dofs (3 per contact node): time, peak,
    and its error against columns of K^-1 (S (K^-1)_cc = I) on a few unit vectors."""
    K = operator(case)
    c = np.load(CACHE / f"{case}-contact.npy")
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    t0 = time.perf_counter()
    ctx, S = _mumps_context(K, c, keep)
    t = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    S = np.tril(S) + np.tril(S, -1).T if np.allclose(np.triu(S, 1), 0) else np.triu(S) + np.triu(S, 1).T
    ref, _ = _mumps_context(K)
    cols = np.linspace(0, c.size - 1, 8).astype(int)
    E = np.zeros((K.shape[0], cols.size))
    E[c[cols], np.arange(cols.size)] = 1.0
    Y = ref.solve(np.asfortranarray(E))[c]
    err = float(np.abs(S @ Y - np.eye(c.size)[:, cols]).max())
    return {
        "case": case,
        "method": "mumps-schur" + ("-keep" if keep else ""),
        "dofs": K.shape[0],
        "schur_dofs": int(c.size),
        "schur_s": t,
        "factor_MB": 12 * ctx.factor_stats.nonzeros / 1e6,
        "peak_MB": peak / 1e6,
        "peak_over_K_MB": (peak - base) / 1e6,
        "schur_error": err,
    }


def markdown(rows: list[dict]) -> list[str]:
    md = [
        "| case | dofs | method | factor MB | held MB | factor s | solve 1 ms | solve 64 ms | peak MB "
        "| peak - K MB | residual |",
        "|" + "---|" * 11,
    ]
    for r in rows:
        if "schur_s" in r:
            md.append(
                f"| {r['case']} | {r['dofs']} | {r['method']} ({r['schur_dofs']} dofs) | {r['factor_MB']:.0f} | | "
                f"{r['schur_s']:.2f} | | | {r['peak_MB']:.0f} | {r['peak_over_K_MB']:.0f} | {r['schur_error']:.1e} |"
            )
            continue
        if "error" in r:
            md.append(f"| {r['case']} | | {r['method']} | {r['error']} |" + " |" * 7)
            continue
        fmb = "" if np.isnan(r["factor_MB"]) else f"{r['factor_MB']:.0f}"
        md.append(
            f"| {r['case']} | {r['dofs']} | {r['method']} | {fmb} | {r['held_MB']:.0f} | {r['factor_s']:.2f} | "
            f"{r['solve1_ms']:.1f} | {r['solve64_ms']:.0f} | {r['peak_MB']:.0f} | {r['peak_over_K_MB']:.0f} | "
            f"{r['residual']:.1e} |"
        )
    return md


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_factor", description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", nargs="+", default=["bar3d-8", "tet-8", "bar3d-16", "tet-16"])
    ap.add_argument("--methods", nargs="+", default=None, help="default: every registered direct backend")
    ap.add_argument("--out", default="out/bench")
    ap.add_argument("--one", nargs=2, metavar=("CASE", "METHOD"), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.one:
        if a.one[1].startswith("mumps-schur"):
            print(json.dumps(one_schur(a.one[0], keep=a.one[1].endswith("-keep"))))
            return 0
        print(json.dumps(one(*a.one)))
        return 0
    if a.methods is None:
        from signorini.linalg import BACKENDS

        a.methods = [f"backend:{e.name}" for e in BACKENDS if isinstance(e.obj, str)]
    rows = []
    for case in a.cases:
        operator(case)  # build the cache once, outside the timed processes
        for method in a.methods:
            cmd = [sys.executable, "-m", "benchmarks.bench_factor", "--one", case, method]
            proc = subprocess.run(cmd, capture_output=True, text=True)
            if proc.returncode:
                last = (proc.stderr.strip().splitlines() or ["failed"])[-1]
                r = {"case": case, "method": method, "error": last[:120]}
                print(f"{case} {method}: {r['error']}", flush=True)
            else:
                r = json.loads(proc.stdout.strip().splitlines()[-1])
            if "schur_s" in r:
                print(
                    f"{case} {method}: Schur complement on {r['schur_dofs']} dofs {r['schur_s']:.2f} s, "
                    f"factor {r['factor_MB']:.0f} MB, peak {r['peak_MB']:.0f} MB, error {r['schur_error']:.1e}",
                    flush=True,
                )
            elif "error" not in r:
                print(
                    f"{case} {method}: factor {r['factor_s']:.2f} s, {r['factor_MB']:.0f} MB "
                    f"(held {r['held_MB']:.0f} MB), solve {r['solve1_ms']:.1f} ms / 64: {r['solve64_ms']:.0f} ms, "
                    f"peak {r['peak_MB']:.0f} MB, residual {r['residual']:.1e}",
                    flush=True,
                )
            rows.append(r)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "factor.json").write_text(json.dumps(rows, indent=1))
    (out / "factor.md").write_text("\n".join(markdown(rows)) + "\n")
    print("\n".join(markdown(rows)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
