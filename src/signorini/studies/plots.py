"""Figures of the report (matplotlib, no display needed); each writes the CSV it plots."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..fem.assembly import von_mises


def _fig(rows: int, cols: int, size=(10, 6)):
    import matplotlib.pyplot as plt

    return plt.subplots(rows, cols, figsize=size, squeeze=False)


def _save(fig, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _write_csv(path: Path, header: list[str], columns: list[np.ndarray]) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(zip(*[np.asarray(c).tolist() for c in columns], strict=True))


def contact_histories(runs: dict, png: Path, csv_path: Path) -> None:
    """Fig. 1/6: mean normal displacement of the contact nodes and total multiplier."""
    fig, ax = _fig(2, 2)
    header, cols = [], []
    for j, scheme in enumerate(("crank-nicolson", "backward-euler")):
        for mass in ("standard", "seed"):
            H = runs[(scheme, mass)]
            disp = H.gap.mean(axis=1)
            ax[0, j].plot(H.t, disp, label=mass)
            ax[1, j].plot(H.t, H.lambda_sum, label=mass)
            header += [f"t_{scheme}_{mass}", f"gap_mean_{scheme}_{mass}", f"lambda_sum_{scheme}_{mass}"]
            cols += [H.t, disp, H.lambda_sum]
        ax[0, j].set_title(f"{scheme}: contact displacement (gap)")
        ax[1, j].set_title(f"{scheme}: total multiplier sum lambda")
        for a in ax[:, j]:
            a.set_xlabel("t")
            a.legend()
    _save(fig, png)
    _write_csv(csv_path, header, cols)


def energies(runs: dict, png: Path, csv_path: Path) -> None:
    """Fig. 2/7: total energy against time for the four scheme/mass pairs."""
    fig, ax = _fig(1, 1, (8, 4.5))
    header, cols = [], []
    for (scheme, mass), H in runs.items():
        ax[0, 0].plot(H.t, H.energy, label=f"{scheme} / {mass}")
        header += [f"t_{scheme}_{mass}", f"energy_{scheme}_{mass}"]
        cols += [H.t, H.energy]
    ax[0, 0].set_xlabel("t")
    ax[0, 0].set_ylabel("E")
    ax[0, 0].set_yscale("log")
    ax[0, 0].legend()
    _save(fig, png)
    _write_csv(csv_path, header, cols)


def convergence(conv: dict, png: Path, csv_path: Path) -> None:
    """Fig. 3/8: log-log relative errors against n with reference slopes 1/2 and 1."""
    keys = ("u_H1", "v_L2", "force", "energy_L2")
    fig, ax = _fig(1, len(keys), (14, 4))
    rows = []
    for j, k in enumerate(keys):
        for name, c in conv.items():
            n = np.array([r["n"] for r in c["rows"]])
            e = np.array([r[k] for r in c["rows"]])
            ax[0, j].loglog(n, e, "o-", label=name)
            rows += [(name, k, int(a), float(b)) for a, b in zip(n, e, strict=True)]
        ax[0, j].loglog(n, e[0] * (n / n[0]) ** -0.5, "k:", label="slope 1/2")
        ax[0, j].loglog(n, e[0] * (n / n[0]) ** -1.0, "k--", label="slope 1")
        ax[0, j].set_title(k)
        ax[0, j].set_xlabel("n")
    ax[0, 0].legend(fontsize=7)
    _save(fig, png)
    with open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["pair", "norm", "n", "relative_error"])
        w.writerows(rows)


def von_mises_3d(runs: dict, png: Path, csv_path: Path) -> dict:
    """Fig. 4/5: von Mises stress on the face x = 0 of the 3D bar at snapshot times."""
    fig, ax = None, None
    stats = {}
    rows = []
    for i, (mass, (p, H)) in enumerate(runs.items()):
        mesh = p.mesh
        on_face = np.isclose(mesh.points[:, 0], 0.0)
        y, z = mesh.points[on_face, 1], mesh.points[on_face, 2]
        times = H.snapshots["t"]
        if fig is None:
            fig, ax = _fig(len(runs), len(times), (1.3 * len(times) + 2, 8))
        vmax_near, rough = 0.0, []
        fields = [von_mises(mesh, p.material, u)[on_face] for u in H.snapshots["u"]]
        levels = np.linspace(0.0, max(max(float(f.max()) for f in fields), 1e-12), 21)  # one scale per row
        for j, t in enumerate(times):
            vm = fields[j]
            tc = ax[i, j].tricontourf(y, z, vm, levels=levels, cmap="viridis")
            ax[i, j].set_title(f"{mass}\nt={t:.2f}", fontsize=7)
            ax[i, j].set_xticks([])
            if j == len(times) - 1:
                fig.colorbar(tc, ax=ax[i, j])
            rows += [(mass, float(t), float(a), float(b), float(c)) for a, b, c in zip(y, z, vm, strict=True)]
            if t > 0.4:
                vmax_near = max(vmax_near, float(vm[z < 0.2].max()))
                order = np.lexsort((y, z))
                col = vm[order].reshape(-1, np.unique(y).size).mean(axis=1)
                rough.append(float(np.mean(np.abs(np.diff(col)))))
        stats[mass] = {"max_near_contact": vmax_near, "roughness": float(np.mean(rough)) if rough else 0.0}
    _save(fig, png)
    with open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["mass", "t", "y", "z", "von_mises"])
        w.writerows(rows)
    return stats
