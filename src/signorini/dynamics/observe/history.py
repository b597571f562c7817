"""The result of a simulation: status, counters, per-step scalars, per-contact-node series."""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...fem.mesh import Mesh
from ...fem.node_order import to_user_dofs, user_order_of
from ..schemes.momentum_projection import moment
from .diagnostics import impact_impulses, oscillation_index, oscillation_indices, penetration

HISTORY_COLUMNS = (
    "t",
    "energy",
    "kinetic_energy",
    "elastic_energy",
    "energy_increment",
    "predicted_increment",
    "lambda_sum",
    "gap_mean",
    "gap_min",
    "active_contacts",
    "newton_iterations",
    "complementarity_residual",
    "external_work",
    "contact_work",
    "numerical_dissipation",
    "penetration",
    "impulse",
    "untagged_penetration",
)
#: columns added after HISTORY_COLUMNS: the global components of the total contact force
#: (one per space dimension: x; x, y; x, y, z), then the friction columns
FORCE_COLUMNS = ("contact_force_x", "contact_force_y", "contact_force_z")
FRICTION_COLUMNS = ("stick_nodes", "slip_nodes", "friction_dissipation")
#: columns added after the friction ones (newer columns go last: a reader of an older
#: file finds every column it knew where it was)
LATER_COLUMNS = ("load_potential",)
#: the total linear momentum 1^T M V of all bodies per component, after those
MOMENTUM_COLUMNS = ("momentum_x", "momentum_y", "momentum_z")
#: after the momentum: the step that ended at each level (nan at level 0; an adaptive control's
#: levels are not evenly spaced)
STEP_COLUMNS = ("dt",)
#: after the step: minus the cumulative work of the damping forces (0 undamped)
DAMPING_COLUMNS = ("damping_dissipation",)
#: after the damping: the angular momentum sum_a x_a x (M V)_a about the origin, x = X + U (3D: x, y, z;
#: 2D: z only; none in 1D), then the Newton iterations of the step (finite strain; 0 when linear) and the
#: cumulative work of the residual Newton left (a term of the energy identity; 0 when linear), then the reactions
ANGULAR_COLUMNS = ("angular_momentum_x", "angular_momentum_y", "angular_momentum_z")
NONLINEAR_COLUMNS = ("nonlinear_iterations", "solver_work")
#: after those: the largest penetration of a contact pair's master nodes into its slave surface at each level
#: (node-to-facet's known limit: reported, not constrained; 0 without pairs)
PAIR_COLUMNS = ("master_penetration",)


def angular_columns(dim: int) -> tuple[str, ...]:
    """The angular momentum's columns in ``dim`` space dimensions."""
    return {1: (), 2: ANGULAR_COLUMNS[2:]}.get(dim, ANGULAR_COLUMNS)


def history_columns(dim: int) -> tuple[str, ...]:
    """The header of ``history.csv`` for a run in ``dim`` space dimensions (then the reactions)."""
    return (
        HISTORY_COLUMNS
        + FORCE_COLUMNS[:dim]
        + FRICTION_COLUMNS
        + LATER_COLUMNS
        + MOMENTUM_COLUMNS[:dim]
        + STEP_COLUMNS
        + DAMPING_COLUMNS
        + angular_columns(dim)
        + NONLINEAR_COLUMNS
        + PAIR_COLUMNS
    )


def angular_momentum(points: np.ndarray, U: np.ndarray, MV: np.ndarray) -> np.ndarray:
    """sum_a x_a x p_a with x = X + U, p = M V per node (:func:`moment`) [mass x length^2 / time]."""
    return moment(points + U.reshape(-1, points.shape[1]), MV)


#: the counters every summary.json has (a run may add more, e.g. krylov_iterations)
COUNTER_KEYS = ("steps", "factorizations", "linear_solves", "contact_iterations", "fallbacks")


@dataclass
class History:
    """Time series of a run, one entry per time level t_0 .. t_N.

    Attributes
    ----------
    t : (N+1,) times [s].
    gap : (N+1, nc) g_i - nu_i.u_i (>= 0) [length].
    lam : (N+1, nc) nodal multipliers lambda_i (<= 0, force).
    kinetic_energy, elastic_energy, load_potential, energy : (N+1,) the scheme's discrete
        energy (``meta['energy_definition']``; for CN and BE E = 1/2 V.MV + 1/2 U.SU - U.F,
        spec eq. 6) and its three parts: kinetic, elastic (1/2 U.SU; the scheme's strain
        energy) and the loads' potential (-U.F(t); ``Scheme.load_potential``) [energy].
    predicted_increment : (N+1,) right-hand side of the scheme's energy identity for the
        step ending at t_n (nan at n = 0 or when the scheme has none for that step).
    external_work, contact_work, numerical_dissipation : (N+1,) cumulative sums of the
        three parts of ``predicted_increment`` (0 at n = 0): work of time-dependent
        loads and prescribed motion, contact term, the scheme's own dissipation.
    untagged_penetration : (N+1,) largest penetration into the obstacle of the boundary
        nodes that are not contact nodes (:mod:`signorini.dynamics.observe.untagged`) [length];
        its maximum is ``untagged_penetration_max`` in the summary.
    impulse : (N+1,) total contact impulse sum_i P_i (<= 0) of the step ending at t_n,
        the P of the scheme's momentum balance M (V^{n+1} - V^n) = ... + B^T P
        (``Scheme.impulse``; nan at n = 0) [force x time].
    active, iterations, fallbacks, residual : per step active-set size, active-set
        (semismooth Newton) iterations, whether the robust fallback ran, and the
        relative complementarity residual.
    coordinates : (nc, d) contact node coordinates; weights : (nc,) contact area weights.
    contact_force : (N+1, d) global components of the total contact force
        sum_i lambda_i nu_i + lambda_t,i . t_i [force] (every run).
    lam_t, slip : (N+1, nc, d - 1) tangential multipliers in the nodal frames [force] and
        slip of the step ending at t_n (relative to the obstacle; a slip rate for
        velocity-level schemes) [length]; None without friction.
    contact_status : (N+1, nc) int8, 0 separated, 1 stick, 2 slip (None without friction).
    momentum : (N+1, d) total linear momentum 1_k^T M V of all bodies per component
        [mass x length / time]; no contact force changes it (the pairs' forces balance).
    friction_work : (N+1,) cumulative work of the tangential forces in the scheme's
        energy identity (<= 0 when friction dissipates); ``friction_dissipation`` = minus it.
    tangents : (nc, d - 1, d) the tangent vectors of the nodal frames (None without friction).
    snapshots : optional dict with ``t`` (k,), ``u`` and ``v`` (k, n_dofs) full fields.
    meta : inputs, sizes and timings (dofs, backend, ...).
    status : ``finished``, ``interrupted`` (SIGINT/SIGTERM) or ``failed`` (non-finite
        state or a solver that did not converge); the arrays hold the levels computed.
    message : why the run stopped early ('' when finished).
    counters : steps, factorizations, linear_solves, contact_iterations, fallbacks, ...
    """

    t: np.ndarray
    gap: np.ndarray
    lam: np.ndarray
    kinetic_energy: np.ndarray
    elastic_energy: np.ndarray
    predicted_increment: np.ndarray
    active: np.ndarray
    iterations: np.ndarray
    fallbacks: np.ndarray
    residual: np.ndarray
    coordinates: np.ndarray
    weights: np.ndarray
    snapshots: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)
    external_work: np.ndarray | None = None
    contact_work: np.ndarray | None = None
    numerical_dissipation: np.ndarray | None = None
    impulse: np.ndarray | None = None
    untagged_penetration: np.ndarray | None = None
    #: (N+1,) the largest penetration of the pairs' master nodes into the slave surfaces (``master_penetration``)
    master_penetration: np.ndarray | None = None
    contact_force: np.ndarray | None = None
    lam_t: np.ndarray | None = None
    slip: np.ndarray | None = None
    contact_status: np.ndarray | None = None
    friction_work: np.ndarray | None = None
    #: (N+1,) cumulative work of the damping forces C V (<= 0); ``damping_dissipation`` = minus it
    damping_work: np.ndarray | None = None
    #: (N+1,) cumulative work of the force residual a finite-strain step's Newton left at its solution, a term of
    #: the energy identity (0 when linear; ``solver_work``)
    solver_work: np.ndarray | None = None
    load_potential: np.ndarray | None = None
    momentum: np.ndarray | None = None
    #: (N+1, 3 | 1 | 0) the angular momentum about the origin (:func:`angular_momentum`)
    angular_momentum: np.ndarray | None = None
    #: (N+1,) the Newton iterations of each step (finite strain; 0 when linear)
    nonlinear_iterations: np.ndarray | None = None
    #: (N+1, m, d) the reaction of each Dirichlet tag (:mod:`~signorini.dynamics.observe.reactions`)
    reaction: np.ndarray | None = None
    #: the names of its history.csv columns, ``reaction_<tag>_<axis>`` (m x d of them)
    reaction_columns: tuple[str, ...] = ()
    tangents: np.ndarray | None = None
    #: (nc,) the mesh's number of each contact node (the user's, whatever the run's order)
    nodes: np.ndarray | None = None
    #: (nc,) the contact pair of each row (its index in the problem's pairs; -1: the rigid obstacle)
    pair: np.ndarray | None = None
    #: (nc,) the master facet each pair row faces at the last level (index in the master tag's facets; -1: obstacle)
    master_facet: np.ndarray | None = None
    status: str = "finished"
    message: str = ""
    counters: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """True when the run reached its final time."""
        return self.status == "finished"

    @property
    def energy(self) -> np.ndarray:
        """kinetic + elastic + load potential: the scheme's energy (``energy_definition``)."""
        if self.load_potential is None:
            return self.kinetic_energy + self.elastic_energy
        return self.kinetic_energy + self.elastic_energy + self.load_potential

    @property
    def steps(self) -> int:
        return self.t.size - 1

    @property
    def lambda_sum(self) -> np.ndarray:
        """Total contact force sum_i lambda_i (<= 0)."""
        return self.lam.sum(axis=1)

    @property
    def pressure(self) -> np.ndarray:
        """Contact pressure -lambda_i / w_i (>= 0 in compression) [force/length^(d-1)]."""
        return -self.lam / self.weights[None, :]

    @property
    def energy_increment(self) -> np.ndarray:
        return np.concatenate([[np.nan], np.diff(self.energy)])

    @property
    def impacts(self) -> int:
        """Number of steps where contact starts (no active node before, some after)."""
        on = self.active > 0
        return int(np.sum(on[1:] & ~on[:-1]))

    @property
    def dim(self) -> int:
        return int(self.coordinates.shape[1]) if self.coordinates.ndim == 2 else 1

    def friction_counts(self) -> tuple[np.ndarray, np.ndarray]:
        """(stick, slip) node counts per level; without friction no node sticks and every
        node in contact slips (nothing holds it tangentially)."""
        if self.contact_status is None:
            return np.zeros(self.t.size, dtype=np.int64), np.asarray(self.active, dtype=np.int64)
        return (self.contact_status == 1).sum(axis=1), (self.contact_status == 2).sum(axis=1)

    def columns(self) -> dict[str, np.ndarray]:
        """The per-step table written to ``history.csv``."""
        force = self.contact_force if self.contact_force is not None else np.full((self.t.size, self.dim), np.nan)
        stick, slip = self.friction_counts()
        fw = _or_nan(self.friction_work, self.t.size)
        return {
            **self._base_columns(),
            **{name: force[:, k] for k, name in enumerate(FORCE_COLUMNS[: self.dim])},
            "stick_nodes": stick,
            "slip_nodes": slip,
            "friction_dissipation": -fw,
            "load_potential": _or_nan(self.load_potential, self.t.size),
            **{
                name: (self.momentum[:, k] if self.momentum is not None else np.full(self.t.size, np.nan))
                for k, name in enumerate(MOMENTUM_COLUMNS[: self.dim])
            },
            "dt": np.concatenate([[np.nan], np.diff(self.t)]) if self.t.size else self.t,
            "damping_dissipation": 0.0 - _or_nan(self.damping_work, self.t.size),  # 0.0 - x: no "-0" when undamped
            **{
                name: (
                    self.angular_momentum[:, k] if self.angular_momentum is not None else np.full(self.t.size, np.nan)
                )
                for k, name in enumerate(angular_columns(self.dim))
            },
            "nonlinear_iterations": (
                self.nonlinear_iterations
                if self.nonlinear_iterations is not None
                else np.zeros(self.t.size, dtype=np.int64)
            ),
            "solver_work": _or_nan(self.solver_work, self.t.size),
            "master_penetration": _or_nan(self.master_penetration, self.t.size),
            **self._reaction_columns(),
        }

    def _reaction_columns(self) -> dict[str, np.ndarray]:
        """``reaction_<tag>_<axis>`` (one per Dirichlet tag and component), after every other column."""
        if self.reaction is None or not self.reaction_columns:
            return {}
        flat = self.reaction.reshape(self.reaction.shape[0], -1)
        return {name: flat[:, k] for k, name in enumerate(self.reaction_columns)}

    def _base_columns(self) -> dict[str, np.ndarray]:
        return {
            "t": self.t,
            "energy": self.energy,
            "kinetic_energy": self.kinetic_energy,
            "elastic_energy": self.elastic_energy,
            "energy_increment": self.energy_increment,
            "predicted_increment": self.predicted_increment,
            "lambda_sum": self.lambda_sum,
            "gap_mean": _facing(self.gap, "mean"),
            "gap_min": _facing(self.gap, "min"),
            "active_contacts": self.active,
            "newton_iterations": self.iterations,
            "complementarity_residual": self.residual,
            "external_work": _or_nan(self.external_work, self.t.size),
            "contact_work": _or_nan(self.contact_work, self.t.size),
            "numerical_dissipation": _or_nan(self.numerical_dissipation, self.t.size),
            "penetration": penetration(self.gap),
            "impulse": _or_nan(self.impulse, self.t.size),
            "untagged_penetration": _or_nan(self.untagged_penetration, self.t.size),
        }

    def to_user_order(self, mesh: Mesh, contact_nodes: np.ndarray) -> None:
        """Put the per-contact-node arrays (nc axis) and the snapshots of a run on a
        renumbered ``mesh`` (:mod:`~signorini.fem.node_order`) in the user's node order,
        the order of a run on the user's mesh; nothing to do otherwise."""
        if mesh.node_ids is None:
            return
        p = user_order_of(mesh, contact_nodes)
        for name in ("gap", "lam", "lam_t", "slip", "contact_status"):
            a = getattr(self, name)
            if a is not None:
                setattr(self, name, a[:, p])
        for name in ("coordinates", "weights", "tangents", "pair", "master_facet"):
            a = getattr(self, name)
            if a is not None:
                setattr(self, name, a[p])
        if self.nodes is not None:
            self.nodes = mesh.node_ids[self.nodes][p]
        for name in ("u", "v"):
            if name in self.snapshots:
                self.snapshots[name] = to_user_dofs(mesh, self.snapshots[name])

    def write_csv(self, path: str | Path) -> None:
        cols = self.columns()
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            names = history_columns(self.dim) + tuple(self.reaction_columns if self.reaction is not None else ())
            w.writerow(names)
            for row in zip(*(cols[c] for c in names), strict=True):
                w.writerow([repr(float(v)) if isinstance(v, (float, np.floating)) else int(v) for v in row])

    def write_contact_npz(self, path: str | Path) -> None:
        """``t``, ``gap``, ``lam`` (= ``lambda_n``), ``coordinates``, ``weights``, ``nodes`` (the mesh's
        number of each contact node, when known); with friction also
        ``lambda_t`` (N+1, nc, d - 1), ``slip`` (N+1, nc, d - 1), ``status`` (N+1, nc: 0 separated,
        1 stick, 2 slip) and ``tangents`` (nc, d - 1, d), the nodal frames' tangent vectors; ``pair``
        (nc,): the contact pair of each row (-1: the rigid obstacle) and ``master_facet`` (nc,): the
        facet of the pair's master tag it faces at the last level (small sliding re-pairs; -1 on
        obstacle rows)."""
        extra = {} if self.nodes is None else {"nodes": self.nodes}
        nc = self.gap.shape[1] if self.gap.ndim == 2 else 0
        extra["pair"] = self.pair if self.pair is not None else np.full(nc, -1, dtype=np.int64)
        extra["master_facet"] = self.master_facet if self.master_facet is not None else np.full(nc, -1, np.int64)
        if self.master_facet is not None and self.gap.ndim == 2 and self.gap.shape[0]:
            # a slave node beyond the master surface's rim at the last level (gap +inf) faces no facet
            extra["master_facet"] = np.where(np.isposinf(self.gap[-1]), -1, self.master_facet)
        if self.lam_t is not None:
            extra.update(lambda_t=self.lam_t, slip=self.slip, status=self.contact_status)
            if self.tangents is not None:
                extra["tangents"] = self.tangents
        np.savez_compressed(
            path,
            t=self.t,
            gap=self.gap,
            lam=self.lam,
            lambda_n=self.lam,
            coordinates=self.coordinates,
            weights=self.weights,
            **extra,
        )

    def save(self, out: str | Path) -> None:
        """Write ``history.csv``, ``contact.npz`` and ``summary.json`` into ``out``."""
        out = Path(out)
        text = json.dumps(finite_json(self.summary()), indent=2, default=_json_default)
        for name, write in (
            ("history.csv", self.write_csv),
            ("contact.npz", self.write_contact_npz),
            ("summary.json", lambda p: p.write_text(text)),
        ):
            try:
                write(out / name)
            except OSError as exc:  # a full disk, a file-size limit: the error names the file
                if exc.filename is None:
                    exc.filename = str(out / name)
                raise

    def summary(self) -> dict:
        E = self.energy
        finite = E[np.isfinite(E)]
        drift = float(np.max(np.abs(finite - E[0])) / abs(E[0])) if E[0] and finite.size else None
        undamped = drift  # the drift less the damping's work: Rayleigh damping's dissipation is physics, not drift
        if drift is not None and self.damping_work is not None:
            net = E - self.damping_work
            net = net[np.isfinite(net)]
            undamped = float(np.max(np.abs(net - E[0])) / abs(E[0])) if net.size else None
        return {
            **self.meta,
            "status": self.status,
            "success": self.success,
            "message": self.message,
            "counters": dict(self.counters),
            "steps": self.steps,
            "impacts": self.impacts,
            "energy_initial": float(E[0]),
            "energy_final": float(E[-1]),
            "energy_max_relative_drift": drift,
            # max |E^n - E^0 - W_damping^n| / |E^0|: the drift without the damping's (physical) work; = the drift
            # when undamped (compare ranks by it)
            "energy_max_relative_drift_undamped": undamped,
            "max_complementarity_residual": float(np.max(self.residual)),
            "fallbacks": int(np.sum(self.fallbacks)),
            "min_gap": float(self.gap[np.isfinite(self.gap)].min()) if np.isfinite(self.gap).any() else None,
            "max_lambda": float(self.lam.max()) if self.lam.size else None,
            # the worst (scaled) residual of the contact law of the steps: the Alart-Curnier
            # residual with friction, the complementarity residual of Signorini without
            "cone_residual_max": float(np.max(self.residual)),
            **self._pairs_at_end(),
            **self.diagnostics(),
        }

    def _pairs_at_end(self) -> dict:
        """``pairs`` with each pair's ``slave_nodes_facing_nothing_at_end`` when its rows are in the current
        configuration (finite strain: every slave node has a row, and one beyond the master's rim has the gap
        +inf); ``inactive_slave_nodes`` is the count at t = 0."""
        pairs = self.meta.get("pairs")
        if not pairs or not self.meta.get("finite_strain") or self.pair is None or self.gap.ndim != 2:
            return {}
        off = np.isposinf(self.gap[-1])
        return {
            "pairs": [
                dict(p, slave_nodes_facing_nothing_at_end=int(np.sum(off & (self.pair == k))))
                for k, p in enumerate(pairs)
            ]
        }

    def _untagged_max(self) -> float | None:
        """Largest untagged penetration of the levels kept, or of the level a failure stopped at."""
        if self.untagged_penetration is None:
            return None
        kept = float(np.max(self.untagged_penetration, initial=0.0))
        return max(kept, float(self.meta.get("untagged_worst_penetration", 0.0)))

    def diagnostics(self) -> dict:
        """Scheme-comparison figures: penetration, oscillation per impact, identity residual.

        ``impulse`` [force x time]: the total contact impulse of the run (sum of the
        ``impulse`` column, <= 0), and ``impact_impulses`` that of every impact (the
        same windows as the oscillation indices; for an elastic rebound of a free body
        about -2 x its momentum); ``penetration_max`` [length] and ``penetration_time_integral`` [length x time]
        (rectangle rule over the levels) of max_i max(0, -gap_i); ``oscillation_index`` of
        the first impact and ``impact_oscillation_indices`` of every impact
        (:mod:`signorini.dynamics.observe.diagnostics`); ``energy_identity_residual`` =
        max_n |E^{n+1} - E^n - predicted| / max_n |E^n| over the steps that have an
        identity (None when none has).
        """
        pen = penetration(self.gap)
        dt = float(self.t[1] - self.t[0]) if self.t.size > 1 else 0.0
        dE = self.energy_increment - self.predicted_increment
        ok = np.isfinite(dE)
        scale = float(np.max(np.abs(self.energy))) if self.energy.size else 0.0
        imp = _or_nan(self.impulse, self.t.size)
        return {
            "impulse": float(np.nansum(imp)) if np.isfinite(imp).any() else None,
            "impact_impulses": impact_impulses(self.lambda_sum, imp),
            "penetration_max": float(pen.max(initial=0.0)),
            "untagged_penetration_max": self._untagged_max(),
            "penetration_time_integral": float(pen[1:].sum() * dt),
            "oscillation_index": oscillation_index(self.t, self.lambda_sum),
            "impact_oscillation_indices": oscillation_indices(self.lambda_sum),
            "energy_identity_residual": float(np.max(np.abs(dE[ok])) / scale) if ok.any() and scale > 0 else None,
        }


def _facing(gap: np.ndarray, how: str) -> np.ndarray:
    """The ``how`` ("mean" or "min") of each level's gaps (levels, nc) over the rows that face something (a finite
    gap; a pair's slave node beyond the master's rim has +inf: no gap), NaN at a level where none does (levels,)."""
    gap = np.asarray(gap, dtype=float)
    if gap.ndim != 2:
        return np.zeros(0)
    facing = np.isfinite(gap)
    count = facing.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        if how == "mean":
            out = np.where(facing, gap, 0.0).sum(axis=1) / count
        else:
            out = np.where(facing, gap, np.inf).min(axis=1, initial=np.inf)
    return np.where(count > 0, out, np.nan)


def _or_nan(a: np.ndarray | None, n: int) -> np.ndarray:
    return np.full(n, np.nan) if a is None else a


def empty_series(levels: int, n_contact: int, dim: int = 1, tangential: int = 0) -> dict[str, np.ndarray]:
    """Pre-allocated per-level arrays of a run, keyed like the :class:`History` fields
    (``tangential``: d - 1 with friction, else 0: no friction arrays)."""
    friction = {}
    if tangential:
        friction = {
            "lam_t": np.zeros((levels, n_contact, tangential)),
            "slip": np.zeros((levels, n_contact, tangential)),
            "contact_status": np.zeros((levels, n_contact), dtype=np.int8),
        }
    return {
        **friction,
        "contact_force": np.zeros((levels, dim)),
        "momentum": np.zeros((levels, dim)),
        "angular_momentum": np.zeros((levels, len(angular_columns(dim)))),
        "nonlinear_iterations": np.zeros(levels, dtype=np.int64),
        "gap": np.empty((levels, n_contact)),
        "lam": np.zeros((levels, n_contact)),
        "kinetic_energy": np.empty(levels),
        "elastic_energy": np.empty(levels),
        "predicted_increment": np.full(levels, np.nan),
        "active": np.zeros(levels, dtype=np.int64),
        "iterations": np.zeros(levels, dtype=np.int64),
        "fallbacks": np.zeros(levels, dtype=bool),
        "residual": np.zeros(levels),
        "impulse": np.full(levels, np.nan),
    }


def finite_json(o):
    """``o`` with every non-finite float replaced by None (strict JSON has no NaN)."""
    if isinstance(o, dict):
        return {k: finite_json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [finite_json(v) for v in o]
    if isinstance(o, (float, np.floating)) and not np.isfinite(o):
        return None
    return o


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(type(o))
