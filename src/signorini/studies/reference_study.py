"""Convergence of the 2D/3D bars against a fine reference run (spec 0.6 and 7).

Nested structured meshes n0 2^k with dt = ratio h.  No exact solution is known, so the
errors are measured against a *reference run* on a finer nested mesh with the same
dt/h ratio.  The reference's own error biases the observed rates: with errors that
decay like h^p and point the same way at every level, the measured error of level n
is roughly C (h_n^p - h_ref^p), which flattens the error curve near the reference and
inflates the rate of the finest pairs.  The default reference is therefore
``DEFAULT_REFERENCE_FACTOR`` = 4 times finer in h and dt than the finest level
reported (``n_ref = 4 n_finest``), every result states its reference and how much
finer it is, and :func:`convergence_study` can repeat the measurement against further
references (``check_references``) so that the rates can be compared
(:func:`rate_comparison`).

Coarse solutions are interpolated linearly in time to the reference time levels
t <= T and prolonged to the reference mesh by interpolation with the levels' own cells, Q1 or (``--set
order=2``: ``quad9``, ``hexahedron27``) Q2: a sparse tensor product of 1D interpolation matrices on the
:class:`Lattice` of the nodes.  Relative norms, time integrals as rectangle
sums over the reference levels in [0, T]:

``u_H1``     |e_u|_{L2(0,T; H1)} with the energy norm sqrt(e^T S e) of the reference mesh
``v_L2``     |e_v|_{L2(0,T; L2)} with sqrt(e^T M e), standard reference mass
``v_Linf``   max_t |e_v|_{L2} / max_t |v|_{L2}
``force``    |sum lambda_h - sum lambda|_{L2(0,T)} (total contact force)
``energy_L2``, ``energy_Linf``  relative to the reference's initial energy
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..dynamics.observe.history import History
from ..dynamics.stepping.simulate import simulate
from ..errors import InputError
from ..fem.assembly import mass_matrix, stiffness_matrix
from .benchmarks import get_benchmark

DEFAULT_REFERENCE_FACTOR = 4
_CHUNK_VALUES = 4_000_000  # floats per block of (dofs x time levels) in the error sums
_TOL = 1e-9


# ----------------------------------------------------------------------------- transfer
def _interp_1d(xc: np.ndarray, xf: np.ndarray) -> sp.csr_matrix:
    """Linear interpolation from the 1D grid ``xc`` to the points ``xf`` (inside it)."""
    j = np.clip(np.searchsorted(xc, xf, side="right") - 1, 0, xc.size - 2)
    w = np.clip((xf - xc[j]) / (xc[j + 1] - xc[j]), 0.0, 1.0)
    rows = np.repeat(np.arange(xf.size), 2)
    cols = np.stack([j, j + 1], 1).ravel()
    vals = np.stack([1 - w, w], 1).ravel()
    P = sp.csr_matrix((vals, (rows, cols)), shape=(xf.size, xc.size))
    P.eliminate_zeros()
    return P


def prolongation_matrix(coarse_grid, fine_grid, dim: int) -> sp.csr_matrix:
    """Q1 interpolation of nodal vectors from a structured grid to a nested finer one.

    Nodes are numbered with the first axis fastest (``rectangle``, ``box``,
    ``interval``) and dofs node by node (``node * dim + component``).
    """
    P = None
    for xc, xf in zip(coarse_grid, fine_grid, strict=True):
        Pk = _interp_1d(np.asarray(xc, float), np.asarray(xf, float))
        P = Pk if P is None else sp.kron(Pk, P, format="csr")
    return sp.kron(P, sp.identity(dim, format="csr"), format="csr")


def prolong(coarse_grid, fine_grid, field: np.ndarray, dim: int) -> np.ndarray:
    """Q1 interpolation of nodal vectors ``field`` (k, n_coarse*dim) to a nested fine grid."""
    P = prolongation_matrix(coarse_grid, fine_grid, dim)
    return np.asarray((P @ np.asarray(field).T).T)


def time_interpolate(t_c: np.ndarray, field: np.ndarray, t_f: np.ndarray) -> np.ndarray:
    """Linear interpolation in time of rows of ``field`` (levels t_c) at times t_f."""
    t_c = np.asarray(t_c, float)
    i = np.clip(np.searchsorted(t_c, t_f, side="right") - 1, 0, t_c.size - 2)
    w = np.clip((t_f - t_c[i]) / (t_c[i + 1] - t_c[i]), 0.0, 1.0)
    if field.ndim == 2:
        w = w[:, None]
    return field[i] * (1 - w) + field[i + 1] * w


def _interp_1d_quadratic(xc: np.ndarray, xf: np.ndarray) -> sp.csr_matrix:
    """Quadratic interpolation from the 1D nodes ``xc`` of P2 cells (2m + 1 points: vertices at the even
    indices, the cells' midpoints between) to the points ``xf`` (inside them)."""
    vertices = xc[::2]
    m = vertices.size - 1
    j = np.clip(np.searchsorted(vertices, xf, side="right") - 1, 0, m - 1)
    xi = (xf - vertices[j]) / (vertices[j + 1] - vertices[j])
    vals = np.stack([2.0 * (xi - 0.5) * (xi - 1.0), 4.0 * xi * (1.0 - xi), 2.0 * xi * (xi - 0.5)], 1)
    cols = np.stack([2 * j, 2 * j + 1, 2 * j + 2], 1)
    P = sp.csr_matrix((vals.ravel(), (np.repeat(np.arange(xf.size), 3), cols.ravel())), shape=(xf.size, xc.size))
    P.eliminate_zeros()
    return P


@dataclass(frozen=True)
class Lattice:
    """The tensor grid the nodes of a structured level lie on: its axes (coordinates per direction), the order
    of its cells, and each node's index in the grid (first axis fastest; None: the nodes are in that order, as
    the linear generators number them).  ``key`` names the level in the reference's caches."""

    axes: tuple[np.ndarray, ...]
    order: int = 1
    index: np.ndarray | None = None

    @property
    def key(self) -> tuple[int, ...]:
        return (self.order, *(a.size for a in self.axes))


#: quadratic cells whose structured meshes' nodes fill a tensor grid (Q2: each cell's 3^dim nodes)
TENSOR_QUADRATIC = ("line3", "quad9", "hexahedron27")


def lattice(mesh) -> Lattice:
    """The :class:`Lattice` of a structured level: the generators' grid (linear cells), or the tensor grid of the
    nodes of Q2 cells (``quad9``, ``hexahedron27``, ``line3``); an InputError for a mesh that has neither."""
    if mesh.grid is not None:
        return Lattice(tuple(np.asarray(g, dtype=float) for g in mesh.grid))
    if mesh.order == 2 and mesh.cell_type in TENSOR_QUADRATIC:
        axes, where = [], []
        for k in range(mesh.dim):
            x = mesh.points[:, k]
            span = max(float(np.ptp(x)), 1.0)
            s = np.sort(x)
            axis = s[np.concatenate([[True], np.diff(s) > _TOL * span])]
            i = np.clip(np.searchsorted(axis, x - _TOL * span), 0, axis.size - 1)
            if np.abs(axis[i] - x).max(initial=0.0) > _TOL * span:
                break
            axes.append(axis)
            where.append(i)
        else:
            sizes = [a.size for a in axes]
            index = np.ravel_multi_index(tuple(where[::-1]), sizes[::-1])  # the first axis fastest
            if np.unique(index).size == mesh.n_nodes == int(np.prod(sizes)):
                return Lattice(tuple(axes), 2, index)
    raise InputError(
        f"a convergence study needs structured levels whose nodes fill a tensor grid (the generators' linear cells, "
        f"or {', '.join(TENSOR_QUADRATIC)}); this mesh of {mesh.cell_type} cells has none"
    )


def lattice_prolongation(coarse: Lattice, fine: Lattice, dim: int) -> sp.csr_matrix:
    """Interpolation of nodal vectors (``node * dim + component``) from a level to a nested finer one of the same
    order, with the coarse cells' shape functions (Q1: :func:`prolongation_matrix`; Q2: quadratic per axis)."""
    if coarse.order != fine.order:
        raise InputError(f"levels of order {coarse.order} and {fine.order} cannot be compared (one order per study)")
    if coarse.order == 1 and coarse.index is None and fine.index is None:
        return prolongation_matrix(coarse.axes, fine.axes, dim)
    one_d = _interp_1d if coarse.order == 1 else _interp_1d_quadratic
    P = None
    for xc, xf in zip(coarse.axes, fine.axes, strict=True):
        Pk = one_d(xc, xf)
        P = Pk if P is None else sp.kron(Pk, P, format="csr")
    rows = np.arange(P.shape[0]) if fine.index is None else fine.index
    cols = np.arange(P.shape[1]) if coarse.index is None else coarse.index
    P = P[rows][:, cols].tocsr()
    return sp.kron(P, sp.identity(dim, format="csr"), format="csr")


def _is_nested(coarse_grid, fine_grid) -> bool:
    for xc, xf in zip(coarse_grid, fine_grid, strict=True):
        d = np.abs(np.asarray(xf)[None, :] - np.asarray(xc)[:, None]).min(axis=1)
        if d.max() > _TOL * max(1.0, float(np.ptp(xf))):
            return False
    return True


# ----------------------------------------------------------------------------- reference
@dataclass
class Reference:
    """A fine run (snapshots at every step) that plays the exact solution's role."""

    benchmark: str
    level: int
    scheme: str
    mass: str
    history: History
    problem: object
    h: float
    params: dict | None = None
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def dt(self) -> float:
        return float(self.history.t[1] - self.history.t[0])

    @property
    def t_end(self) -> float:
        return float(self.history.t[-1])

    @property
    def mesh(self):
        return self.problem.mesh

    @property
    def lattice(self) -> Lattice:
        if "lattice" not in self._cache:
            self._cache["lattice"] = lattice(self.mesh)
        return self._cache["lattice"]

    def matrices(self):
        if "S" not in self._cache:
            self._cache["S"] = stiffness_matrix(self.mesh, self.problem.material)
            self._cache["M"] = mass_matrix(self.mesh, self.problem.material.rho)
        return self._cache["S"], self._cache["M"]

    def window(self, T: float) -> int:
        """Number of reference time levels in [0, T]."""
        return int(np.searchsorted(self.history.t, T * (1 + _TOL) + _TOL, side="right"))

    def prepare(self, lattices, T: float) -> None:
        """One pass over the reference levels in [0, T]: the squared norms |u|_S^2 and
        |v|_M^2, and for every coarse level's :class:`Lattice` the projections P^T S u_ref, P^T M v_ref and the
        Galerkin matrices P^T S P, P^T M P (cached; see :func:`relative_errors`)."""
        k = self.window(T)
        if self._cache.get("k") != k:
            self._cache.update(k=k, proj={}, norms=None)
        proj = self._cache["proj"]
        todo = {}
        for g in lattices:
            key = g.key
            if key not in proj and key not in todo:
                if not _is_nested(g.axes, self.lattice.axes):
                    raise InputError(f"a mesh ({key[1:]}) is not nested in the reference mesh (n = {self.level})")
                todo[key] = lattice_prolongation(g, self.lattice, self.mesh.dim)
        need_norms = self._cache["norms"] is None
        if not todo and not need_norms:
            return
        S, M = self.matrices()
        snaps = self.history.snapshots
        n_f = snaps["u"].shape[1]
        out = {key: (np.empty((k, P.shape[1])), np.empty((k, P.shape[1]))) for key, P in todo.items()}
        norms = (np.empty(k), np.empty(k))
        step = max(1, _CHUNK_VALUES // max(n_f, 1))
        for a in range(0, k, step):
            b = min(k, a + step)
            for i, (name, A) in enumerate((("u", S), ("v", M))):
                R = np.ascontiguousarray(snaps[name][a:b].T)
                AR = A @ R
                if need_norms:
                    norms[i][a:b] = np.einsum("ij,ij->j", R, AR)
                for key, P in todo.items():
                    out[key][i][a:b] = (P.T @ AR).T
        if need_norms:
            self._cache["norms"] = norms
        for key, P in todo.items():
            PT = P.T.tocsr()
            proj[key] = (*out[key], (PT @ S @ P).tocsr(), (PT @ M @ P).tocsr())

    def norms(self, T: float) -> tuple[np.ndarray, np.ndarray]:
        """Squared |u|_S and |v|_M at the reference levels in [0, T]."""
        self.prepare((), T)
        return self._cache["norms"]

    def projection(self, coarse: Lattice, T: float):
        """(P^T S u_ref, P^T M v_ref, P^T S P, P^T M P) for the coarse level's :class:`Lattice`."""
        self.prepare([coarse], T)
        return self._cache["proj"][coarse.key]

    def info(self, finest: int | None = None, finest_dt: float | None = None) -> dict:
        """What the reference is, and how much finer it is than level ``finest``."""
        out = {
            "kind": "run",
            "level": self.level,
            "scheme": self.scheme,
            "mass": self.mass,
            "h": self.h,
            "dt": self.dt,
            "t_end": self.t_end,
        }
        if finest is not None:
            out["finest_level"] = finest
            out["factor_h"] = self.level / finest
        if finest_dt is not None:
            out["factor_dt"] = finest_dt / self.dt
        out["description"] = describe_reference(out)
        return out


def describe_reference(info: dict) -> str:
    """One line: 'CN + seed at n = 32 (h = ..., dt = ...), 4x finer in h and 4x in dt than n = 8'."""
    if info.get("kind") == "exact":
        return "exact solution"
    text = f"{info['scheme']} + {info['mass']} at n = {info['level']} (h = {info['h']:.4g}, dt = {info['dt']:.4g})"
    if "factor_h" in info:
        text += f", {info['factor_h']:g}x finer in h"
        if "factor_dt" in info:
            text += f" and {info['factor_dt']:.3g}x in dt"
        text += f" than the finest level n = {info['finest_level']}"
    return text


def reference_run(
    bench: str,
    level: int,
    scheme: str,
    mass: str,
    T: float,
    ratio: float = 0.5,
    params: dict | None = None,
) -> Reference:
    """Run ``scheme`` + ``mass`` at ``level`` with dt = ratio h, snapshots at every step."""
    b = get_benchmark(bench)
    p = b.problem(level, params)
    h = b.h(level, params)
    H = simulate(p, scheme, ratio * h, T, mass=mass, snapshot_every=1)
    if not H.success:
        raise InputError(f"the reference run at n = {level} did not finish: {H.status} ({H.message})")
    return Reference(bench, level, scheme, mass, H, p, h, params)


def as_reference(bench: str, level: int, history: History, params: dict | None = None) -> Reference:
    """Wrap an existing run at ``level`` (it must hold snapshots at every step)."""
    b = get_benchmark(bench)
    scheme, mass = history.meta.get("scheme", "unknown scheme"), history.meta.get("mass", "unknown mass")
    snaps = history.snapshots
    if not snaps or snaps["t"].size != history.t.size:
        raise InputError("a reference run needs snapshots at every step (simulate(..., snapshot_every=1))")
    p = b.problem(level, params)
    if snaps["u"].shape[1] != p.mesh.n_nodes * p.mesh.dim:
        raise InputError(f"the reference history does not belong to level n = {level} of {bench!r}")
    return Reference(bench, level, scheme, mass, history, p, b.h(level, params), params)


def check_reference(ref: Reference, levels: list[int], T: float, dt_finest: float | None = None) -> None:
    """Raise :class:`InputError` unless ``ref`` can serve as the reference of ``levels`` up to T."""
    if ref.t_end < T * (1 - _TOL) - _TOL:
        raise InputError(f"the reference (n = {ref.level}) ends at t = {ref.t_end:.6g}, before the study's T = {T:.6g}")
    check_levels(levels, ref.level)
    if dt_finest is not None and ref.dt > dt_finest * (1 + _TOL):
        raise InputError(f"the reference time step {ref.dt:.6g} is larger than the finest level's {dt_finest:.6g}")


def check_levels(levels: list[int], ref_level: int) -> None:
    """The level checks of :func:`check_reference` before anything runs."""
    finest = max(levels)
    if ref_level <= finest:
        raise InputError(
            f"the reference level n = {ref_level} is not finer than the finest level n = {finest}; use "
            f"n >= {DEFAULT_REFERENCE_FACTOR * finest} (the default is {DEFAULT_REFERENCE_FACTOR}x the finest level)"
        )
    bad = [n for n in levels if ref_level % n]
    if bad:
        raise InputError(
            f"level(s) {', '.join(map(str, bad))} not nested in the reference level n = {ref_level} "
            f"(the reference level must be a multiple of every level)"
        )


# ----------------------------------------------------------------------------- errors
def relative_errors(H: History, mesh_c, ref: Reference, T: float) -> dict[str, float]:
    """Relative errors of the coarse run ``H`` (on ``mesh_c``) against ``ref`` over [0, T].

    With P the prolongation and u_c the coarse field interpolated to a reference time,
    |P u_c - u_ref|_S^2 = u_c.(P^T S P) u_c - 2 u_c.(P^T S u_ref) + |u_ref|_S^2: the
    fine-mesh terms are computed once per reference and coarse mesh
    (:meth:`Reference.prepare`) and shared by every run on that mesh.  (Round-off:
    about 1e-16 of |u_ref|^2, i.e. relative errors below ~1e-7 are not resolved; a
    negative result of the cancellation is set to 0.)
    """
    coarse = lattice(mesh_c)
    if not _is_nested(coarse.axes, ref.lattice.axes):
        raise InputError(f"the mesh of this level is not nested in the reference mesh (n = {ref.level})")
    if H.t[-1] < T * (1 - _TOL) - _TOL:
        raise InputError(f"the run ends at t = {H.t[-1]:.6g} before T = {T:.6g}")
    snaps = H.snapshots
    if not snaps or snaps["t"].size != H.t.size:
        raise InputError("the convergence study needs snapshots at every step (simulate(..., snapshot_every=1))")
    k = ref.window(T)
    tf = ref.history.t[:k]
    Qu, Qv, Sc, Mc = ref.projection(coarse, T)
    u2, v2 = ref.norms(T)
    uc = time_interpolate(snaps["t"], snaps["u"], tf)
    vc = time_interpolate(snaps["t"], snaps["v"], tf)

    def err2(A, x, Q, r2):
        xAx = np.einsum("ij,ji->i", x, A @ x.T)
        return np.maximum(xAx - 2 * np.einsum("ij,ij->i", x, Q) + r2, 0.0)

    eu2, ev2 = err2(Sc, uc, Qu, u2), err2(Mc, vc, Qv, v2)
    out = {
        "u_H1": float(np.sqrt(eu2.sum() / u2.sum())),
        "v_L2": float(np.sqrt(ev2.sum() / v2.sum())),
        "v_Linf": float(np.sqrt(ev2.max() / v2.max())),
    }
    f_c = time_interpolate(H.t, H.lambda_sum, tf)
    f_r = ref.history.lambda_sum[:k]
    out["force"] = float(np.sqrt(np.sum((f_c - f_r) ** 2) / np.sum(f_r**2))) if np.any(f_r) else float("nan")
    E_c = time_interpolate(H.t, H.energy, tf)
    dE = E_c - ref.history.energy[:k]
    E0 = ref.history.energy[0]
    out["energy_L2"] = float(np.sqrt(np.mean(dE**2)) / E0)
    out["energy_Linf"] = float(np.max(np.abs(dE)) / E0)
    return out


def level_rates(rows: list[dict]) -> dict[str, list[float]]:
    """Observed rates between successive rows for every error column (nan if undefined)."""
    from .study import observed_rates

    keys = [k for k in rows[0] if k not in ("n", "h")]
    if len(rows) < 2:
        return {k: [] for k in keys}
    return {k: [float(r) for r in observed_rates([r[k] for r in rows], [r["h"] for r in rows])] for k in keys}


def run_levels(bench, scheme, mass, levels, T, ratio=0.5, params=None) -> dict[int, tuple]:
    """The coarse runs of a study: {n: (problem, history)} with snapshots at every step."""
    b = get_benchmark(bench)
    runs = {}
    for n in levels:
        p = b.problem(n, params)
        runs[n] = (p, simulate(p, scheme, ratio * b.h(n, params), T, mass=mass, snapshot_every=1))
    return runs


def _rows_against(runs: dict, ref: Reference, T: float, bench: str, params) -> list[dict]:
    b = get_benchmark(bench)
    rows = []
    use = [n for n in sorted(runs) if n < ref.level and not ref.level % n]
    ref.prepare([lattice(runs[n][0].mesh) for n in use], T)
    for n in use:
        p, H = runs[n]
        rows.append({"n": n, "h": b.h(n, params), **relative_errors(H, p.mesh, ref, T)})
    return rows


def convergence_study(
    bench: str,
    scheme: str,
    mass: str,
    levels: list[int],
    ref_level: int | None = None,
    T: float = 1.0,
    ratio: float = 0.5,
    params: dict | None = None,
    reference: Reference | History | None = None,
    check_references: tuple = (),
    runs: dict | None = None,
) -> dict:
    """Errors of ``levels`` against a nested reference, with rates.

    ``ref_level`` defaults to ``DEFAULT_REFERENCE_FACTOR`` x the finest level; the
    reference defaults to the same scheme and mass at ``ref_level`` and dt = ratio h.
    Pass ``reference`` (a :class:`Reference`, or a History at ``ref_level``) to compare
    every scheme with one solution (``signorini reproduce`` shares one CN + ``seed``
    run).  ``check_references`` (References or levels) repeat the measurement for the
    levels coarser than each of them (``result["checks"]``), to see whether the rates
    depend on the reference (:func:`rate_comparison`).  ``runs`` reuses coarse runs
    ({n: (problem, history)}, e.g. from :func:`run_levels`).

    Raises :class:`InputError` if the reference ends before T, is not finer than the
    finest level (in h or dt), or if a level does not divide the reference level.
    """
    b = get_benchmark(bench)
    levels = sorted(int(n) for n in levels)
    finest = levels[-1]
    dt_finest = ratio * b.h(finest, params)
    if isinstance(reference, Reference):
        ref = reference
    else:
        ref_level = ref_level or DEFAULT_REFERENCE_FACTOR * finest
        check_levels(levels, ref_level)
        if reference is None:
            ref = reference_run(bench, ref_level, scheme, mass, T, ratio, params)
        else:
            ref = as_reference(bench, ref_level, reference, params=params)
    check_reference(ref, levels, T, dt_finest)
    runs = runs if runs is not None else run_levels(bench, scheme, mass, levels, T, ratio, params)
    rows = _rows_against(runs, ref, T, bench, params)
    checks = []
    for c in check_references:
        cref = c if isinstance(c, Reference) else reference_run(bench, int(c), scheme, mass, T, ratio, params)
        if cref.t_end < T * (1 - _TOL) - _TOL:
            check_reference(cref, levels, T)  # raises the horizon error
        crows = _rows_against(runs, cref, T, bench, params)
        checks.append({"reference": cref.info(), "rows": crows, "rates": level_rates(crows) if crows else {}})
    return {
        "benchmark": bench,
        "scheme": scheme,
        "mass": mass,
        "T": T,
        "ratio": ratio,
        "ref_level": ref.level,
        "reference": ref.info(finest, dt_finest),
        "rows": rows,
        "rates": level_rates(rows),
        "checks": checks,
    }


# ----------------------------------------------------------------------------- rate checks
def pair_rates(result: dict) -> list[dict]:
    """Every observed rate of ``result`` and its checks, one entry per (reference, level pair, norm).

    ``factor`` is how much finer the reference is than the finer level of the pair.
    """
    out = []
    for block in [result, *result.get("checks", [])]:
        ref = block["reference"]
        rows = block["rows"]
        for i in range(len(rows) - 1):
            n0, n1 = rows[i]["n"], rows[i + 1]["n"]
            for k, rates in block["rates"].items():
                factor = ref["level"] / n1
                out.append({"ref_level": ref["level"], "pair": (n0, n1), "norm": k, "factor": factor, "rate": rates[i]})
    return out


def rate_comparison(result: dict, norms=None) -> list[dict]:
    """Differences of the rates of one level pair against references f and 2f times finer.

    One entry per factor f present: ``{"factors": (f, 2f), "count", "max_diff",
    "mean_diff", "worst": (pair, norm, rate_f, rate_2f)}``; non-finite rates are skipped.
    """
    rates = [r for r in pair_rates(result) if norms is None or r["norm"] in norms]
    by_key = {}
    for r in rates:
        by_key.setdefault((r["pair"], r["norm"]), {})[r["factor"]] = r["rate"]
    out = {}
    for (pair, norm), byf in by_key.items():
        for f, rate in byf.items():
            g = 2 * f
            if g in byf and np.isfinite(rate) and np.isfinite(byf[g]):
                d = abs(byf[g] - rate)
                e = out.setdefault(f, {"factors": (f, g), "diffs": [], "worst": None, "worst_diff": -1.0})
                e["diffs"].append(d)
                if d > e["worst_diff"]:
                    e["worst_diff"], e["worst"] = d, (pair, norm, rate, byf[g])
    result_list = []
    for f in sorted(out):
        e = out[f]
        result_list.append(
            {
                "factors": e["factors"],
                "count": len(e["diffs"]),
                "max_diff": float(max(e["diffs"])),
                "mean_diff": float(np.mean(e["diffs"])),
                "worst": e["worst"],
            }
        )
    return result_list


def rate_trend(result: dict, norms=None) -> dict[str, int]:
    """How the rate of each (level pair, norm) moves as the reference gets finer.

    Counts the (pair, norm) entries measured against at least two references whose
    rates fall monotonically (``falls``), rise monotonically (``rises``) or neither
    (``mixed``) with the reference factor.
    """
    by_key = {}
    for r in pair_rates(result):
        if (norms is None or r["norm"] in norms) and np.isfinite(r["rate"]):
            by_key.setdefault((r["pair"], r["norm"]), []).append((r["factor"], r["rate"]))
    out = {"falls": 0, "rises": 0, "mixed": 0}
    for vals in by_key.values():
        if len(vals) < 2:
            continue
        d = np.diff([v for _, v in sorted(vals)])
        out["falls" if np.all(d < 0) else "rises" if np.all(d > 0) else "mixed"] += 1
    return out


# ----------------------------------------------------------------------------- 1D + CLI
def study(
    bench: str,
    scheme: str,
    mass: str,
    n0: int,
    levels: int,
    T: float,
    ratio: float = 0.5,
    ref_level: int | None = None,
    params: dict | None = None,
    check_ref_levels: tuple = (),
) -> dict:
    """Convergence study on nested levels n0 2^k, k = 0..levels-1, with dt = ratio h.

    1D benchmarks are compared with their exact solution (:func:`signorini.study.errors_1d`);
    2D/3D ones with a reference run at ``ref_level`` (default
    ``DEFAULT_REFERENCE_FACTOR`` x the finest level, i.e. n0 2^(levels+1)), same scheme
    and mass, and optionally with the further references ``check_ref_levels``.
    """
    from .study import errors_1d

    b = get_benchmark(bench)
    ns = [n0 * 2**k for k in range(levels)]
    if b.dim == 1:
        if ref_level is not None or check_ref_levels:
            raise InputError(f"{bench!r} is compared with its exact solution: a reference level does not apply")
        rows = []
        for n in ns:
            p = b.problem(n, params)
            H = simulate(p, scheme, ratio * b.h(n, params), T, mass=mass, snapshot_every=1)
            rows.append({"n": n, "h": b.h(n, params), **errors_1d(H, p, b.exact(b.params(params), T))})
        return {
            "benchmark": bench,
            "scheme": scheme,
            "mass": mass,
            "reference": {"kind": "exact", "description": "exact solution"},
            "T": T,
            "ratio": ratio,
            "rows": rows,
            "rates": level_rates(rows),
            "checks": [],
        }
    ref_level = ref_level or DEFAULT_REFERENCE_FACTOR * ns[-1]
    check_levels(ns, ref_level)
    for c in check_ref_levels:
        if len(ns) < 2 or c <= ns[1] or any(c % n for n in ns if n < c):
            raise InputError(
                f"check reference n = {c} must be finer than at least two levels (> {ns[1] if len(ns) > 1 else ns[0]}) "
                "and a multiple of every level below it"
            )
    return convergence_study(
        bench, scheme, mass, ns, ref_level, T=T, ratio=ratio, params=params, check_references=tuple(check_ref_levels)
    )


def _fmt(x: float, spec: str) -> str:
    return format(x, spec) if x is not None and np.isfinite(x) else "n/a"


def table_markdown(result: dict) -> str:
    """Markdown table of a study: errors per level, rates between levels, the reference."""
    rows = result["rows"]
    keys = [k for k in rows[0] if k not in ("n", "h")]
    ref = result["reference"]
    lines = [
        f"{result['benchmark']}: {result['scheme']} / {result['mass']} mass, T = {result['T']:g}, "
        f"dt = {result.get('ratio', 0.5):g} h (fixed steps at every level: a convergence study is on its grids, not "
        "under the energy control of `signorini run`)",
        "",
        f"Reference: {ref['description']}.",
        "",
    ]
    if ref.get("kind") == "run" and ref.get("factor_h", DEFAULT_REFERENCE_FACTOR) < DEFAULT_REFERENCE_FACTOR:
        lines += [
            f"Warning: the reference is only {ref['factor_h']:g}x finer than the finest level; "
            "the rates of the finest pairs are biased upwards.",
            "",
        ]
    lines += ["| n | h | " + " | ".join(keys) + " |", "|---" * (len(keys) + 2) + "|"]
    for r in rows:
        lines.append(f"| {r['n']} | {r['h']:.4g} | " + " | ".join(_fmt(r[k], ".4e") for k in keys) + " |")
    for i in range(len(rows) - 1):
        lines.append(
            f"| rate {rows[i]['n']}->{rows[i + 1]['n']} | | "
            + " | ".join(_fmt(result["rates"][k][i], ".2f") for k in keys)
            + " |"
        )
    if result.get("checks"):
        lines += ["", rate_table_markdown(result, keys)]
    return "\n".join(lines) + "\n"


def reference_levels(results) -> list[int]:
    """Sorted levels of the references of ``results`` and of their checks."""
    return sorted({blk["reference"]["level"] for r in results for blk in [r, *r.get("checks", [])]})


def rate_rows(result: dict, norms, refs, na: str = "n/a") -> list[str]:
    """Table cells ``norm | n0->n1 | rate (factor x) | ...`` (one per reference in ``refs``)
    for every norm and level pair of ``result`` and its checks; ``na`` where the
    reference is not finer than the pair's finer level."""
    table = {(r["norm"], r["pair"], r["ref_level"]): r for r in pair_rates(result) if r["norm"] in norms}
    pairs = sorted({k[1] for k in table})
    rows = []
    for k in norms:
        for pr in pairs:
            cells = [
                na if (x := table.get((k, pr, r))) is None else f"{_fmt(x['rate'], '.2f')} ({x['factor']:g}x)"
                for r in refs
            ]
            rows.append(f"{k} | {pr[0]}->{pr[1]} | " + " | ".join(cells))
    return rows


def rate_table_markdown(result: dict, norms) -> str:
    """Rates of every level pair against each reference (factor = reference / finer level)."""
    refs = reference_levels([result])
    lines = [
        "Rates against references of different fineness (in brackets: how many times finer the "
        "reference is than the finer level of the pair; n/a: the reference is not finer than that level):",
        "",
        "| norm | pair | " + " | ".join(f"ref n = {r}" for r in refs) + " |",
        "|---" * (len(refs) + 2) + "|",
    ]
    lines += [f"| {row} |" for row in rate_rows(result, norms, refs)]
    comp = rate_comparison(result, norms)
    if comp:
        lines.append("")
        for c in comp:
            f, g = c["factors"]
            pr, k, a, bb = c["worst"]
            lines.append(
                f"- references {f:g}x vs {g:g}x finer: max |rate difference| {c['max_diff']:.2f} "
                f"(mean {c['mean_diff']:.2f}, {c['count']} rates; largest for {k} {pr[0]}->{pr[1]}: "
                f"{a:.2f} vs {bb:.2f})"
            )
    return "\n".join(lines)


def table_csv(result: dict, path) -> None:
    """The main rows (errors against the main reference) with the reference level as last column."""
    import csv

    rows = result["rows"]
    keys = list(rows[0])
    ref = result["reference"].get("level", "exact")
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([*keys, "reference_level"])
        for r in rows:
            w.writerow([*[r[k] for k in keys], ref])
