"""Convergence of the 2D/3D bars against a fine reference run (spec 0.6 and 7).

Nested structured meshes n0 2^k with dt = ratio h; the reference is a finer level.
Coarse solutions are prolonged to the reference mesh by Q1 interpolation (nodes of a
nested structured grid) and to the reference time levels by linear interpolation.
Relative norms (time integrals as rectangle sums over the reference levels):

``u_H1``     |e_u|_{L2(0,T; H1)} with the energy norm sqrt(e^T S e) of the reference mesh
``v_L2``     |e_v|_{L2(0,T; L2)} with sqrt(e^T M e), standard reference mass
``v_Linf``   max_t |e_v|_{L2} / max_t |v|_{L2}
``force``    |sum lambda_h - sum lambda|_{L2(0,T)} (total contact force)
``energy_L2``, ``energy_Linf``  relative to the reference's initial energy
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from ..dynamics.history import History
from ..dynamics.simulate import simulate
from ..fem.assembly import mass_matrix, stiffness_matrix
from ..studies.benchmarks import get_benchmark


def prolong(coarse_grid, fine_grid, field: np.ndarray, dim: int) -> np.ndarray:
    """Q1 interpolation of nodal vectors ``field`` (k, n_coarse*dim) to a nested fine grid."""
    shape = tuple(g.size for g in coarse_grid)[::-1]
    fine_pts = np.stack(np.meshgrid(*fine_grid[::-1], indexing="ij"), -1).reshape(-1, dim)
    k = field.shape[0]
    vals = field.reshape(k, *shape, dim)
    vals = np.moveaxis(vals, 0, -2).reshape(*shape, k * dim)
    interp = RegularGridInterpolator(tuple(coarse_grid[::-1]), vals)
    out = interp(fine_pts).reshape(-1, k, dim)
    return np.moveaxis(out, 1, 0).reshape(k, -1)


def time_interpolate(t_c: np.ndarray, field: np.ndarray, t_f: np.ndarray) -> np.ndarray:
    """Linear interpolation in time of rows of ``field`` (levels t_c) at times t_f."""
    dt = t_c[1] - t_c[0]
    s = np.clip(t_f / dt, 0, t_c.size - 1)
    i = np.minimum(np.floor(s + 1e-9).astype(int), t_c.size - 2)
    w = (s - i)[:, None] if field.ndim == 2 else s - i
    return field[i] * (1 - w) + field[i + 1] * w


def relative_errors(H: History, ref: History, mesh_c, mesh_f, S, M) -> dict[str, float]:
    tf = ref.t
    dim = mesh_f.dim
    u = prolong(mesh_c.grid, mesh_f.grid, H.snapshots["u"], dim)
    v = prolong(mesh_c.grid, mesh_f.grid, H.snapshots["v"], dim)
    u = time_interpolate(H.snapshots["t"], u, tf)
    v = time_interpolate(H.snapshots["t"], v, tf)
    eu = u - ref.snapshots["u"]
    ev = v - ref.snapshots["v"]

    def sq(A, e):
        return np.einsum("ij,ij->i", e, (A @ e.T).T)

    out = {
        "u_H1": float(np.sqrt(sq(S, eu).sum() / sq(S, ref.snapshots["u"]).sum())),
        "v_L2": float(np.sqrt(sq(M, ev).sum() / sq(M, ref.snapshots["v"]).sum())),
        "v_Linf": float(np.sqrt(sq(M, ev).max() / sq(M, ref.snapshots["v"]).max())),
    }
    f_c = time_interpolate(H.t, H.lambda_sum, tf)
    f_r = ref.lambda_sum
    out["force"] = float(np.sqrt(np.sum((f_c - f_r) ** 2) / np.sum(f_r**2)))
    E_c = time_interpolate(H.t, H.energy, tf)
    dE = E_c - ref.energy
    E0 = ref.energy[0]
    out["energy_L2"] = float(np.sqrt(np.mean(dE**2)) / E0)
    out["energy_Linf"] = float(np.max(np.abs(dE)) / E0)
    return out


def convergence_study(
    bench: str,
    scheme: str,
    mass: str,
    levels: list[int],
    ref_level: int,
    T: float = 1.0,
    ratio: float = 0.5,
    params: dict | None = None,
    reference: History | None = None,
) -> dict:
    """Errors of ``levels`` against a reference run at ``ref_level`` (all nested), with rates.

    The reference defaults to the same scheme and mass at ``ref_level``; pass
    ``reference`` (e.g. one CN + ``seed`` run shared by all pairs, the project's
    default in ``signorini reproduce``) to compare every scheme with the same solution.
    """
    b = get_benchmark(bench)
    pf = b.problem(ref_level, params)
    ref = reference or simulate(pf, scheme, ratio * b.h(ref_level, params), T, mass=mass, snapshot_every=1)
    S = stiffness_matrix(pf.mesh, pf.material)
    M = mass_matrix(pf.mesh, pf.material.rho)
    rows = []
    for n in levels:
        if ref_level % n:
            raise ValueError(f"level {n} is not nested in the reference level {ref_level}")
        pc = b.problem(n, params)
        H = simulate(pc, scheme, ratio * b.h(n, params), T, mass=mass, snapshot_every=1)
        rows.append({"n": n, "h": b.h(n, params), **relative_errors(H, ref, pc.mesh, pf.mesh, S, M)})
    return {
        "benchmark": bench,
        "scheme": scheme,
        "mass": mass,
        "ref_level": ref_level,
        "T": T,
        "rows": rows,
        "rates": level_rates(rows),
    }


def level_rates(rows: list[dict]) -> dict[str, list[float]]:
    """Observed rates between successive rows for every error column."""
    from ..studies.study import observed_rates

    keys = [k for k in rows[0] if k not in ("n", "h")]
    return {k: [float(r) for r in observed_rates([r[k] for r in rows], [r["h"] for r in rows])] for k in keys}


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
) -> dict:
    """Convergence study on nested levels n0 2^k, k = 0..levels-1, with dt = ratio h.

    1D benchmarks are compared with their exact solution (:func:`signorini.study.errors_1d`);
    2D/3D ones with a reference run at ``ref_level`` (default n0 2^levels), same scheme
    and mass.
    """
    from ..studies.study import errors_1d

    b = get_benchmark(bench)
    ns = [n0 * 2**k for k in range(levels)]
    if b.dim == 1:
        rows = []
        for n in ns:
            p = b.problem(n, params)
            H = simulate(p, scheme, ratio * b.h(n, params), T, mass=mass, snapshot_every=1)
            rows.append({"n": n, "h": b.h(n, params), **errors_1d(H, p, b.exact(b.params(params), T))})
        return {
            "benchmark": bench,
            "scheme": scheme,
            "mass": mass,
            "reference": "exact",
            "T": T,
            "rows": rows,
            "rates": level_rates(rows),
        }
    ref_level = ref_level or n0 * 2**levels
    out = convergence_study(bench, scheme, mass, ns, ref_level, T=T, ratio=ratio, params=params)
    out["reference"] = f"n={ref_level}"
    return out


def table_markdown(result: dict) -> str:
    """Markdown table of a study: errors per level and rates between levels."""
    rows = result["rows"]
    keys = [k for k in rows[0] if k not in ("n", "h")]
    lines = [
        f"{result['benchmark']}: {result['scheme']} / {result['mass']} mass, T = {result['T']}, "
        f"reference {result['reference']}",
        "",
        "| n | h | " + " | ".join(keys) + " |",
        "|---" * (len(keys) + 2) + "|",
    ]
    for r in rows:
        lines.append(f"| {r['n']} | {r['h']:.4g} | " + " | ".join(f"{r[k]:.4e}" for k in keys) + " |")
    for i in range(len(rows) - 1):
        lines.append(
            f"| rate {rows[i]['n']}->{rows[i + 1]['n']} | | "
            + " | ".join(f"{result['rates'][k][i]:.2f}" for k in keys)
            + " |"
        )
    return "\n".join(lines) + "\n"


def table_csv(result: dict, path) -> None:
    import csv

    rows = result["rows"]
    keys = list(rows[0])
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(keys)
        for r in rows:
            w.writerow([r[k] for k in keys])
