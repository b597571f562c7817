"""Per-run diagnostics computed from a history: penetration and contact-force oscillation.

``penetration(gap)``  per level, max_i max(0, -gap_i) >= 0 [length], where
                      gap_i = g_i(t) - nu_i . u_i (>= 0 when admissible); exact-contact
                      schemes give round-off, velocity-level and penalty schemes do not.
``oscillation_index`` total variation of the total contact force over an impact divided by
                      twice its peak |force|: one monotone rise from 0 to the peak and fall
                      back to 0 has index **1**; every extra swing adds its amplitude
                      relative to the peak (a dip of depth a x peak gives 1 + a); 0 when
                      there is no contact; 0.5 for a monotone rise cut by the end of the run.
``impact_impulses``   the total contact impulse of every impact (sum of the per-step
                      impulses over its window) [force x time].

An impact is a cluster of levels with a non-zero force; gaps of at most ``separation``
force-free levels (the standard mass chatters) belong to the cluster.  The window
includes one level before and after, so the rise from 0 and the fall to 0 count.
"""

from __future__ import annotations

import numpy as np


def penetration(gap: np.ndarray) -> np.ndarray:
    """max(0, -min_i gap_i) per level, shape (levels,) [length]; gap has shape (levels, nc)."""
    gap = np.asarray(gap, dtype=float)
    if gap.ndim != 2 or gap.shape[1] == 0:
        return np.zeros(gap.shape[0] if gap.ndim else 0)
    return np.maximum(0.0, -gap.min(axis=1))


def impact_windows(force: np.ndarray, separation: int = 20) -> list[tuple[int, int]]:
    """(first, last) level of every impact: clusters of non-zero force (see the module)."""
    on = np.flatnonzero(np.asarray(force) != 0)
    if on.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(on) > separation)
    starts = np.concatenate([[on[0]], on[breaks + 1]])
    ends = np.concatenate([on[breaks], [on[-1]]])
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def _index(force: np.ndarray, first: int, last: int) -> float:
    seg = force[max(first - 1, 0) : last + 2]
    if first == 0:  # in contact at t = 0: the rise starts from 0
        seg = np.concatenate([[0.0], seg])
    return float(np.sum(np.abs(np.diff(seg))) / (2 * np.max(np.abs(seg))))


def oscillation_indices(force: np.ndarray, separation: int = 20) -> list[float]:
    """The oscillation index of every impact (empty without contact)."""
    force = np.asarray(force, dtype=float)
    return [_index(force, a, b) for a, b in impact_windows(force, separation)]


def oscillation_index(t: np.ndarray | None, force: np.ndarray, separation: int = 20) -> float:
    """The oscillation index of the first impact (0 without contact); ``t`` is unused."""
    values = oscillation_indices(force, separation)
    return values[0] if values else 0.0


def impact_impulses(force: np.ndarray, impulse: np.ndarray, separation: int = 20) -> list[float]:
    """Sum of the per-step ``impulse`` (levels, nan allowed) over every impact of ``force``.

    The step ending at level k carries ``impulse[k]``; an impact spanning the levels
    first..last of non-zero force owns the steps ending at first..last+1 (a trapezoidal
    scheme's step after the last force still carries half of it).
    """
    impulse = np.asarray(impulse, dtype=float)
    if not np.isfinite(impulse).any():
        return []
    return [float(np.nansum(impulse[a : b + 2])) for a, b in impact_windows(np.asarray(force, dtype=float), separation)]


def single_level_contacts(lam: np.ndarray) -> int:
    """The contact episodes that last a single level: levels n where some contact row is active
    (lambda < 0) while none is at n - 1 and n + 1 (an episode at the last level is not counted:
    it may go on).  A step longer than the contact itself shows this way."""
    active = (np.asarray(lam) < 0).reshape(len(lam), -1).any(axis=1) if np.size(lam) else np.zeros(0, bool)
    if active.size < 3:
        return 0
    inner = active[1:-1] & ~active[:-2] & ~active[2:]
    return int(np.count_nonzero(inner))


def contact_duration_estimate(problem) -> float | None:
    """About how long a contact lasts [time]: 2 H / c_p, the time a compression wave takes to
    cross the body (extent H along a plane obstacle's normal, else its smallest extent) and back,
    c_p = sqrt((lam + 2 mu) / rho) of the default material (the elastic bar's impact duration;
    a Hertzian contact lasts longer).  None without a material to tell."""
    mat = getattr(problem, "material", None)
    mesh = getattr(problem, "mesh", None)
    if mat is None or mesh is None:
        return None
    c = float(np.sqrt((mat.lam + 2.0 * mat.mu) / mat.rho))
    normal = getattr(problem.obstacle, "normal", None)
    pts = mesh.points
    if normal is not None and np.size(normal) == mesh.dim and not callable(normal):
        n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
        extent = float(np.ptp(pts @ n))
    else:
        extent = float(np.ptp(pts, axis=0).min()) if mesh.dim > 1 else float(np.ptp(pts))
    return 2.0 * extent / c if c > 0 and extent > 0 else None
