"""Observers of the time loop: called at every level, closed on every exit.

The loop in :func:`~signorini.dynamics.stepping.simulate.simulate` calls, for every observer,
``start(run)`` once with the initial state (level 0), ``record(run, n, state)`` after
every accepted step n, and ``close(run, status, n_last)`` exactly once on any exit
(finished, interrupted, failed), so files are completed and memory released.

Checkpoints (:mod:`~.checkpoint`): an observer whose series a resumed run must continue
names its part of the checkpoint (``checkpoint_key``), gives its data up to level n
(``saved(n)``: arrays, numbers, strings or lists of them) and takes them back after its
``start`` when a run resumes at level n (``resume(run, n, state, data)``).  An observer
without a key starts afresh at the resumed level (a user's observer sees the levels from
the resume on).

Built in: :class:`HistoryRecorder` (gaps, multipliers and solver data per level),
:class:`EnergyRecorder` (the scheme's energy and its identity; costs a few products per
step, switch it off with ``simulate(..., energy=False)``), :class:`SnapshotRecorder`
(full fields in memory every k steps, for studies) and :class:`ProgressCallback`.
The XDMF field writer that streams to disk is :class:`signorini.io.output.FieldWriter`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import ConvergenceError, InputError, NonFiniteError
from ..rows.current_rows import level_gaps
from ..schemes import Scheme, State
from ..schemes.base import EnergyParts
from ..solve.context import Context
from .history import angular_momentum, empty_series


@dataclass
class Run:
    """What observers can see: the context, the scheme, the time grid, the level-0 state."""

    ctx: Context
    scheme: Scheme
    n_steps: int
    dt: float
    initial: State
    problem: Any = None
    #: a resumed run: the times of the levels 0..n restored from its checkpoint
    level_times: np.ndarray | None = None


def grow_observers(run: Run, observers: list[Any], size: int) -> int:
    """Room for ``size`` levels in every observer that keeps per-level arrays (``grow``);
    returns ``size``."""
    run.n_steps = size - 1
    for o in observers:
        if hasattr(o, "grow"):
            o.grow(size)
    return size


class Observer:
    """Base class: override any of ``start``, ``record``, ``close`` (and, for checkpoints,
    ``checkpoint_key``, ``saved`` and ``resume``)."""

    #: the name of this observer's data in a checkpoint; None: it keeps nothing to restore
    checkpoint_key: str | None = None

    def saved(self, n: int) -> dict[str, Any]:
        """Its data up to level ``n`` (included), for a checkpoint."""
        return {}

    def resume(self, run: Run, n: int, state: State, data: dict[str, Any]) -> None:
        """Continue at level ``n`` (``state``) with ``data`` from :meth:`saved` (after ``start``)."""

    def start(self, run: Run) -> None:
        pass

    def record(self, run: Run, n: int, state: State) -> None:
        pass

    def close(self, run: Run, status: str, n_last: int, state: State) -> None:
        pass


class HistoryRecorder(Observer):
    """Per-level gaps, multipliers, active set size, iterations, fallbacks, residuals, and
    the total contact impulse of each step (``Scheme.impulse``), and the time of each level."""

    checkpoint_key = "history"

    def start(self, run: Run) -> None:
        nc = run.ctx.disc.contact.size
        self.series = empty_series(run.n_steps + 1, nc, run.ctx.disc.space.dim, run.ctx.rows.components - 1)
        for k in ("kinetic_energy", "elastic_energy"):
            del self.series[k]
        self.reactions = None
        if run.ctx.has_fixed and run.ctx.disc.problem.dirichlet:
            from .reactions import Reactions

            self.reactions = Reactions(run.ctx, run.ctx.disc.problem.dirichlet)
            self.series["reaction"] = np.zeros((run.n_steps + 1, len(self.reactions.tags), run.ctx.disc.space.dim))
        self.times = np.full(run.n_steps + 1, np.nan)
        self._prev = run.initial
        self._put(run, 0, run.initial)

    def saved(self, n: int) -> dict[str, Any]:
        return {"series": {"times": self.times[: n + 1], **{k: v[: n + 1] for k, v in self.series.items()}}}

    def resume(self, run: Run, n: int, state: State, data: dict[str, Any]) -> None:
        series = data.get("series", {})
        if "reaction" in self.series and "reaction" not in series:  # a checkpoint of before the reactions
            series = {**series, "reaction": np.full((n + 1,) + self.series["reaction"].shape[1:], np.nan)}
        for k in ("angular_momentum", "nonlinear_iterations"):  # a checkpoint of before these series
            if k not in series:
                v = self.series[k]
                series = {**series, k: np.full((n + 1,) + v.shape[1:], np.nan if v.dtype.kind == "f" else 0, v.dtype)}
        _restore_series(self.series, series, n, "history")
        times = np.asarray(series.get("times", []), dtype=float)
        if (
            times.shape != (n + 1,)
            or not np.all(np.isfinite(times))
            or np.any(np.diff(times) <= 0)
            or (times[-1] != state.t)
        ):
            raise InputError("checkpoint: the levels' times are not increasing up to the checkpoint's t")
        self.times[: n + 1] = times
        self._prev = self.last = state

    def _put(self, run: Run, n: int, s: State) -> None:
        S = self.series
        self.times[n] = s.t
        S["gap"][n] = level_gaps(run.ctx, s.U, s.t)
        # total linear momentum 1_k^T M V per component (the product the energy uses, computed once)
        MV = s.product("MV", lambda: run.ctx.Mop @ s.V)
        S["momentum"][n] = MV.reshape(-1, S["momentum"].shape[1]).sum(axis=0)
        S["angular_momentum"][n] = angular_momentum(run.ctx.disc.problem.mesh.points, s.U, MV)
        self.last = s
        S["lam"][n] = s.lam
        S["active"][n] = int(np.count_nonzero(s.lam))
        S["contact_force"][n] = run.ctx.disc.contact.force_components(s.lam, s.lam_t)
        if self.reactions is not None:
            S["reaction"][n] = self.reactions(run.ctx, s)
        if "lam_t" in S and s.lam_t is not None:
            S["lam_t"][n] = s.lam_t
            if s.info is not None and s.info.slip is not None:
                S["slip"][n] = s.info.slip
                S["contact_status"][n] = s.info.status
        if s.info is not None:
            S["nonlinear_iterations"][n] = s.info.nonlinear_iterations
            S["iterations"][n] = s.info.iterations
            S["fallbacks"][n] = s.info.fallback
            S["residual"][n] = s.info.residual

    def grow(self, size: int) -> None:
        """Room for levels 0 .. size - 1 (an adaptive run's levels are not known in advance)."""
        self.series = _grown({**self.series, "_times": self.times}, size)
        self.times = self.series.pop("_times")

    def record(self, run: Run, n: int, state: State) -> None:
        self._put(run, n, state)
        self.series["impulse"][n] = float(np.sum(run.scheme.impulse(run.ctx, self._prev, state)))
        self._prev = state

    def close(self, run: Run, status: str, n_last: int, state: State) -> None:
        self.series = {k: v[: n_last + 1] for k, v in self.series.items()}
        self.times = self.times[: n_last + 1]
        self._prev = None


def _grown(series: dict[str, np.ndarray], size: int) -> dict[str, np.ndarray]:
    """The arrays of ``series`` with room for ``size`` levels (new levels: nan, or 0 for
    integers), the levels recorded kept."""
    out = {}
    for k, v in series.items():
        if v.shape[0] >= size:
            out[k] = v
            continue
        fill = np.nan if np.issubdtype(v.dtype, np.floating) else 0
        a = np.full((size,) + v.shape[1:], fill, dtype=v.dtype)
        a[: v.shape[0]] = v
        out[k] = a
    return out


def _restore_series(series: dict[str, np.ndarray], data: dict[str, Any], n: int, what: str) -> None:
    """Levels 0..n of every series from a checkpoint's ``data`` (shapes checked)."""
    for k, v in series.items():
        if k not in data:
            raise InputError(f"checkpoint: the {what} series {k!r} is missing")
        a = np.asarray(data[k])
        if a.dtype != v.dtype:
            raise InputError(f"checkpoint: the {what} series {k!r} is {a.dtype}, expected {v.dtype}")
        if a.shape != (n + 1,) + v.shape[1:]:
            raise InputError(
                f"checkpoint: the {what} series {k!r} has shape {a.shape}, expected {(n + 1,) + v.shape[1:]}"
            )
        v[: n + 1] = a


def _restored_rows(value: Any, size: int) -> np.ndarray:
    """A checkpoint's open contact cycles (size,): finite numbers, or refused (InputError)."""
    a = np.asarray(value, dtype=float) if value is not None else np.zeros(size)
    if a.shape != (size,) or not np.all(np.isfinite(a)):
        raise InputError(f"checkpoint: the energy's open contact cycles must be {size} finite numbers")
    return a


def _non_negative(value: Any, key: str) -> float:
    """A checkpoint's cumulative created or destroyed energy: a finite number >= 0, or refused (InputError)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    if not (np.isfinite(v) and v >= 0):
        raise InputError(f"checkpoint: the energy's {key} must be a finite number >= 0, got {value!r}")
    return v


def _finite_energy(parts: tuple[float, float], n: int) -> tuple[float, float]:
    """(kinetic, potential) if both are finite; else :class:`NonFiniteError` (values beyond doubles)."""
    if not (np.isfinite(parts[0]) and np.isfinite(parts[1])):
        raise NonFiniteError(
            f"the energy of level {n} is not finite ({parts[0]:.3g} kinetic, {parts[1]:.3g} potential): "
            "values beyond double precision"
        )
    return parts


#: residual of the energy identity, relative to the run's largest energy, above which a run
#: warns (or fails, solver option energy_check = fail): every scheme closes it to 1e-14..1e-13
#: on the benchmarks and an iterative solve to its tolerance; a unit mismatch (E in Pa with rho
#: in t/mm^3) leaves 1e-4 to 1e-1
ENERGY_IDENTITY_TOLERANCE = 1e-6


#: energy created by the scheme (``spurious_energy``), relative to the run's energy scale, above
#: which a run warns (or fails with energy_check = fail)
SPURIOUS_TOLERANCE = 0.01


class EnergyRecorder(Observer):
    """The scheme's discrete energy per level and the parts of its identity, checked at every
    step: the residual r_n = |E^n - E^{n-1} - predicted_n| / (the largest of the energy's parts
    and of the works so far: kinetic, elastic, load potential, external, contact, numerical,
    friction) above
    :data:`ENERGY_IDENTITY_TOLERANCE` is recorded (:attr:`worst`, a warning at the end) or,
    with ``check = "fail"``, stops the run (ConvergenceError)."""

    #: "warn" or "fail" (solver option energy_check)
    check = "warn"
    #: (residual, level) of the largest relative residual so far
    worst: tuple[float, int] = (0.0, -1)
    #: the energy the scheme created so far [energy]: the largest running sum of (the work of the
    #: contact forces of a fixed obstacle and of the pairs + the numerical part), which the
    #: exact dynamics make zero (an exchange that the next steps give back is not counted
    #: twice); and the level where it first exceeded :data:`SPURIOUS_TOLERANCE` of the scale
    spurious: float = 0.0
    spurious_first: int = -1
    #: the unexplained energy created and destroyed so far (both >= 0) [energy]: the contact rows' cycles (each
    #: row's net work of a fixed obstacle or of a pair, with a penalty's springs, from the step it starts acting
    #: to the step it lets go: positive nets created, negative destroyed, the cycles still open counted as they
    #: stand) plus the numerical part's net (its running maximum created, its running minimum's depth destroyed).
    #: Unlike :attr:`spurious`, energy created after earlier losses shows (a body chattering at rest after its
    #: impact lost energy); a release that gives back what its entry took is not counted as created.
    created: float = 0.0
    destroyed: float = 0.0
    created_first: int = -1
    #: the run's energy scale: max(|E^0|, the largest kinetic energy, |the loads' work|) so far
    energy_scale: float = 0.0
    #: whether the rigid obstacle moves (its contact work is then physical: only the numerical
    #: part counts)
    obstacle_moves = False

    KEYS = (
        "kinetic_energy",
        "elastic_energy",
        "load_potential",
        "predicted_increment",
        "external",
        "contact",
        "numerical",
        "friction",
        "damping",
        "solver",
    )
    PARTS = ("external", "contact", "numerical", "friction", "damping", "solver")
    checkpoint_key = "energy"

    def resume(self, run: Run, n: int, state: State, data: dict[str, Any]) -> None:
        saved = dict(data.get("series", {}))
        if "damping" not in saved and "friction" in saved:  # a checkpoint of a version without damping
            saved["damping"] = np.zeros(n + 1)  # (whose runs were undamped)
        if "solver" not in saved and "friction" in saved:  # a checkpoint of before the solver's work: its levels'
            saved["solver"] = np.zeros(n + 1)  # residuals' work was not counted (nor is it known)
        _restore_series(self.series, saved, n, "energy")
        self._scale, self.worst = 0.0, (0.0, -1)
        self.spurious, self.spurious_first, self.energy_scale, self._net = 0.0, -1, 0.0, 0.0
        self._reset_cycles(run)
        if "cycles_open" in data:  # a checkpoint of before the cycles: they count from the resume
            self._open = _restored_rows(data["cycles_open"], self._open.size)
            self._rows_created = _non_negative(data.get("cycles_created"), "created")
            self._rows_destroyed = _non_negative(data.get("cycles_destroyed"), "destroyed")
            first = data.get("cycles_first", -1)
            if not (isinstance(first, (int, np.integer)) and -1 <= int(first) <= n):
                raise InputError(f"checkpoint: the energy's first level above the tolerance {first!r} is not a level")
            self.created_first = int(first)
        for k in range(n + 1):  # the check's running figures, from the levels restored
            self._check(run, k, check=False)
        self._prev = state
        self._dt = float(data["dt"])  # the step the last level's energy was computed with
        if not self._dt > 0:
            raise InputError(f"checkpoint: the energy's step {self._dt!r} is not a positive number")

    def saved(self, n: int) -> dict[str, Any]:
        return {
            "series": {k: v[: n + 1] for k, v in self.series.items()},
            "dt": float(self._dt),
            "cycles_open": self._open.copy(),
            "cycles_created": float(self._rows_created),
            "cycles_destroyed": float(self._rows_destroyed),
            "cycles_first": int(self.created_first),
        }

    def _reset_cycles(self, run: Run) -> None:
        self._open = np.zeros(run.ctx.disc.contact.size)  # each row's net work of its open cycle
        self._rows_created = self._rows_destroyed = 0.0
        self._num_high = self._num_low = self._num_net = 0.0
        self.created = self.destroyed = 0.0
        self.created_first = -1

    def _cycles(self, run: Run, state: State) -> None:
        """Each contact row's work of the step (kept by the scheme's ``contact_works`` with the level), added to
        its open cycle; the rows that let go at this level close theirs (:attr:`created`)."""
        rows = state.cache.get("contact_rows")
        if rows is None or self.obstacle_moves or rows.size != self._open.size:
            return
        stored = run.scheme.contact_energy(run.ctx, state, by_row=True)
        if stored is not None:  # a penalty's springs: the contact work they keep is not unexplained
            before = run.scheme.contact_energy(run.ctx, self._prev, by_row=True)
            rows = rows + (stored - before)
        self._open += rows
        closed = (state.lam == 0.0) & (self._open != 0.0)
        if closed.any():
            net = self._open[closed]
            self._rows_created += float(net[net > 0].sum())
            self._rows_destroyed -= float(net[net < 0].sum())
            self._open[closed] = 0.0

    def start(self, run: Run) -> None:
        n = run.n_steps + 1
        self.series = {k: np.full(n, np.nan) for k in self.KEYS}
        for k in self.PARTS:
            self.series[k][0] = 0.0
        self._scale, self.worst = 0.0, (0.0, -1)
        self.spurious, self.spurious_first, self.energy_scale, self._net = 0.0, -1, 0.0, 0.0
        obstacle = run.ctx.disc.problem.obstacle
        self.obstacle_moves = bool(getattr(obstacle, "moving", False))
        self._reset_cycles(run)
        rtol = run.ctx.solver_options.get("rtol")
        iterative = any(getattr(solver, "uses_guess", False) for solver in run.ctx.solvers)  # CG solves
        loose = 100.0 * float(rtol) if iterative and isinstance(rtol, (int, float)) else 0.0
        self.tolerance = max(ENERGY_IDENTITY_TOLERANCE, loose)
        self._put(run, 0, run.initial)
        self._check(run, 0)
        self._prev = run.initial
        self._dt = run.ctx.dt  # the step this level's energy is computed with

    def _put(self, run: Run, n: int, state: State) -> None:
        """Level n's kinetic energy, and its potential split into the loads' part and the rest."""
        S = self.series
        S["kinetic_energy"][n], potential = _finite_energy(run.scheme.energy(run.ctx, state), n)
        S["load_potential"][n] = run.scheme.load_potential(run.ctx, state)
        S["elastic_energy"][n] = potential - S["load_potential"][n]

    def step_parts(self, run: Run, n: int, state: State) -> EnergyParts | None:
        """The parts of the energy identity of the step from the last recorded level to
        ``state`` (level n), without recording it (the adaptive control judges a step with
        them, :mod:`~.step_control`)."""
        S = self.series
        parts = run.scheme.energy_increment(run.ctx, self._prev, state)
        if parts is not None and getattr(self, "_dt", run.ctx.dt) != run.ctx.dt:
            # the step changed before this step (a dt schedule, a resume with another dt): a
            # scheme's energy may depend on dt (HHT's dt^2 A.MA term); the previous level's
            # energy under the new dt minus its recorded one is the redefinition, counted in
            # the numerical part so that the identity holds across the change
            kinetic, potential = _finite_energy(run.scheme.energy(run.ctx, self._prev), n - 1)
            recorded = S["kinetic_energy"][n - 1] + S["elastic_energy"][n - 1] + S["load_potential"][n - 1]
            parts.numerical += kinetic + potential - recorded
        return parts

    def indicator(self, run: Run, n: int, state: State) -> tuple[float, float, float]:
        """(delta, E_scale, eta) of the step to ``state`` for the adaptive control: the energy that
        no physical work explains (the contact work when the obstacle is fixed, the numerical
        part: :mod:`~.step_control`), the run's energy scale with this level's kinetic energy,
        and the elastic energy 1/2 e.S e of the scheme's local error estimate e on a step with
        contact forces (0 otherwise, or without an estimate)."""
        parts = self.step_parts(run, n, state)
        kinetic, _ = _finite_energy(run.scheme.energy(run.ctx, state), n)
        scale = max(self.energy_scale, kinetic)
        # the motion's error only where a contact acts (at either level): the waves that carry its
        # force must be resolved; the free vibrations an impact leaves in a body are not judged
        # (CN carries them without energy error; resolving them would take dt_min everywhere)
        touching = bool(np.any(state.lam) or np.any(self._prev.lam))
        # the step that made the level before (the energy's _dt, checkpointed); none at level 0
        dt_before = self._dt if n >= 2 else None
        e = run.scheme.local_error(run.ctx, self._prev, state, dt_before) if touching else None
        if e is not None and run.ctx.has_fixed:  # a prescribed motion has no error of integration (and its
            e = e.copy()  # V and A on the Dirichlet dofs are not the scheme's: a kink there is not a step's)
            e[run.ctx.fixed] = 0.0
        eta = 0.0 if e is None else 0.5 * float(e @ (run.ctx.Sop @ e))
        if parts is None:
            return 0.0, scale, eta
        numerical = parts.numerical if run.scheme.conserving else max(parts.numerical, 0.0)
        R0 = run.initial.extra.get("R0")
        if n == 1 and R0 is not None and np.any(R0):  # the start-up relaxation of an initial state out of
            numerical = 0.0  # equilibrium on the massless dofs: whatever the step (bar1d_compressed: -0.0032)
        # a penalty's springs store what the contact force works (outside E): only the net is spurious
        stored = run.scheme.contact_energy(run.ctx, state) - run.scheme.contact_energy(run.ctx, self._prev)
        contact = 0.0 if self.obstacle_moves else parts.contact + stored
        external = abs(float(self.series["external"][n - 1] + parts.external))
        return contact + numerical, max(scale, external), eta

    def grow(self, size: int) -> None:
        """Room for levels 0 .. size - 1 (an adaptive run's levels are not known in advance)."""
        self.series = _grown(self.series, size)

    def record(self, run: Run, n: int, state: State) -> None:
        S = self.series
        self._put(run, n, state)
        parts = self.step_parts(run, n, state)
        self._dt = run.ctx.dt
        if parts is not None:
            S["predicted_increment"][n] = parts.total
            S["external"][n] = S["external"][n - 1] + parts.external
            S["contact"][n] = S["contact"][n - 1] + parts.contact
            S["numerical"][n] = S["numerical"][n - 1] + parts.numerical
            S["friction"][n] = S["friction"][n - 1] + parts.friction
            S["damping"][n] = S["damping"][n - 1] + parts.damping
            S["solver"][n] = S["solver"][n - 1] + parts.solver
        else:
            for k in self.PARTS:
                S[k][n] = S[k][n - 1]
        if parts is not None:
            self._cycles(run, state)
        self._prev.cache.clear()  # release the old level's products
        self._prev = state
        self._check(run, n)

    def _check(self, run: Run, n: int, check: bool = True) -> None:
        """The identity's residual at level n against the largest energy of levels 0..n."""
        S = self.series
        energy = S["kinetic_energy"][n] + S["elastic_energy"][n] + S["load_potential"][n]
        # the largest of the energy's parts and works so far: a body falling from rest has E = 0
        # (kinetic and load potential cancel), round-off of E is round-off of its parts
        parts = [abs(float(S[k][n])) for k in ("kinetic_energy", "elastic_energy", "load_potential", *self.PARTS)]
        self._scale = max(self._scale, max((p for p in parts if np.isfinite(p)), default=0.0))
        e0 = S["kinetic_energy"][0] + S["elastic_energy"][0] + S["load_potential"][0]
        scale = max(abs(float(e0)), float(S["kinetic_energy"][n]), abs(float(S["external"][n])))
        self.energy_scale = max(self.energy_scale, scale if np.isfinite(scale) else 0.0)
        if n > 0 and np.isfinite(S["predicted_increment"][n]):
            numerical = float(S["numerical"][n] - S["numerical"][n - 1])
            self._net += numerical
            if not self.obstacle_moves:
                self._net += float(S["contact"][n] - S["contact"][n - 1])
            if self._net > self.spurious:
                self.spurious = self._net
                if self.spurious_first < 0 and self.spurious_relative() > SPURIOUS_TOLERANCE:
                    self.spurious_first = n
            self._num_net += numerical
            self._num_high, self._num_low = max(self._num_high, self._num_net), min(self._num_low, self._num_net)
            opened = self._open[self._open > 0].sum() if self._open.size else 0.0
            closing = self._open[self._open < 0].sum() if self._open.size else 0.0
            self.created = self._rows_created + float(opened) + self._num_high
            self.destroyed = self._rows_destroyed - float(closing) - self._num_low
            if self.created_first < 0 and self.spurious_exceeded():
                self.created_first = n
            if check and self.check == "fail" and self.spurious_exceeded():
                raise ConvergenceError(self.spurious_message())
        if n == 0 or not np.isfinite(S["predicted_increment"][n]) or self._scale == 0.0:
            return
        before = S["kinetic_energy"][n - 1] + S["elastic_energy"][n - 1] + S["load_potential"][n - 1]
        r = abs(float(energy - before - S["predicted_increment"][n])) / self._scale
        if r > self.worst[0]:
            self.worst = (r, n)
        if check and self.check == "fail" and r > self.tolerance:
            raise ConvergenceError(self.message())

    #: the identity's tolerance of this run: :data:`ENERGY_IDENTITY_TOLERANCE`, or 100 x an
    #: iterative solve's relative tolerance when that is looser (``start`` sets it)
    tolerance = ENERGY_IDENTITY_TOLERANCE

    def exceeded(self) -> bool:
        return self.worst[0] > self.tolerance

    def spurious_relative(self) -> float:
        return self.spurious / self.energy_scale if self.energy_scale > 0 else 0.0

    def created_relative(self) -> float:
        return self.created / self.energy_scale if self.energy_scale > 0 else 0.0

    def spurious_exceeded(self) -> bool:
        """Whether the energy created (:attr:`created`) exceeds :data:`SPURIOUS_TOLERANCE` of the scale."""
        return self.created_relative() > SPURIOUS_TOLERANCE

    def spurious_message(
        self,
        single_level: int = 0,
        t_first: float | None = None,
        duration: float | None = None,
        dt: float | None = None,
        controlled: bool = False,
        mass: str = "",
    ) -> str:
        """The warning of a run whose scheme created more than :data:`SPURIOUS_TOLERANCE` of its
        energy scale: how much, from which level, the contact episodes a single level long, and the fix."""
        where = ""
        if self.created_first >= 0:
            at = f", t = {t_first:.6g}" if t_first is not None else ""
            where = f"; above {100 * SPURIOUS_TOLERANCE:g}% from level {self.created_first}{at} on"
        single = (
            (f"; {single_level} contact episode(s) lasted a single level: the step does not resolve the contact")
            if single_level
            else ""
        )
        fix = "a smaller time step"
        if duration is not None and dt is not None:
            fix = (
                f"a time step well below the contact duration (about {duration:.3g} s for this body: 2 x its size "
                f"along the obstacle's normal / its wave speed; dt = {dt:.3g} s)"
            )
        if mass in ("standard", "lumped"):  # its contact chatters whatever the step
            fix = (
                f"a mass without contact inertia (the default, moment-preserving; the {mass!r} mass's contact chatters)"
            )
        elif controlled:
            fix = "a smaller tolerance or dt_min of the energy control"
        else:
            fix = f'the energy control ([time] control = "energy", --dt-control energy) or {fix}'
        return (
            f"the scheme created {self.created:.4g} of energy, {100 * self.created_relative():.3g}% of the run's "
            f"energy scale {self.energy_scale:.4g}{where} (work that a fixed obstacle and the contact between bodies "
            f"cannot do, and the scheme's numerical part){single}: the result gains energy that is not physics; "
            f"use {fix}"
        )

    def message(self) -> str:
        r, n = self.worst
        return (
            f"the energy identity does not close: at level {n} the energy's change differs from the work and "
            f"dissipation the scheme predicts by {r:.3g} of the largest energy (tolerance {self.tolerance:g}; every "
            "scheme closes it to about 1e-14 with a direct solver): the operators are too ill-conditioned for "
            "double precision, or an iterative solver's tolerance (solver option rtol) is too loose; check the "
            "units (E in Pa with rho in kg/m^3, or MPa with t/mm^3) and materials whose stiffnesses differ by "
            "many orders of magnitude"
        )

    def close(self, run: Run, status: str, n_last: int, state: State) -> None:
        self.series = {k: v[: n_last + 1] for k, v in self.series.items()}

    def report(
        self, meta: dict[str, Any], lam: np.ndarray, t: np.ndarray, run: Run, failed: bool, adaptive: bool
    ) -> None:
        """What the recorder found, in a run's ``meta``: the warning of an identity that did not
        close; ``spurious_energy`` and ``single_level_contacts`` (``lam``: the multipliers per
        level; ``t``: the levels' times), and the warning of a run whose scheme created more
        than 1% of its energy scale (a run that failed too: the energy it gained before its failure is
        often the cause, as Crank-Nicolson's growth under large rotations before Newton fails)."""
        from .diagnostics import contact_duration_estimate, single_level_contacts

        if self.exceeded() and not failed:
            meta["warnings"].append(self.message())
        single = single_level_contacts(lam)
        meta["single_level_contacts"] = single
        meta["spurious_energy"] = {
            "absolute": self.spurious,
            "relative": self.spurious_relative(),
            "scale": self.energy_scale,
            "first_level": self.spurious_first,
            "created": self.created,
            "destroyed": self.destroyed,
            "created_relative": self.created_relative(),
            "created_first_level": self.created_first,
        }
        if self.spurious_exceeded() and not (failed and self.check == "fail"):  # energy_check=fail: its message
            first = self.created_first
            t_first = float(t[first]) if 0 <= first < t.size else None
            duration = contact_duration_estimate(run.ctx.disc.problem)
            meta["warnings"].append(
                self.spurious_message(single, t_first, duration, run.dt, adaptive, run.ctx.disc.mass_name)
            )


class SnapshotRecorder(Observer):
    """Full displacement and velocity fields in memory every ``every`` steps and at the
    last level (for convergence studies; use the XDMF writer for large runs)."""

    def __init__(self, every: int):
        self.every = every
        self.t: list[float] = []
        self.u: list[np.ndarray] = []
        self.v: list[np.ndarray] = []
        self._last = -1

    def _take(self, n: int, s: State) -> None:
        self.t.append(s.t)
        self.u.append(s.U.copy())
        self.v.append(s.V.copy())
        self._last = n

    checkpoint_key = "snapshots"

    def start(self, run: Run) -> None:
        self._take(0, run.initial)

    def saved(self, n: int) -> dict[str, Any]:
        return {"t": np.array(self.t), "u": np.array(self.u), "v": np.array(self.v), "last": self._last}

    def resume(self, run: Run, n: int, state: State, data: dict[str, Any]) -> None:
        self.t = [float(x) for x in data["t"]]
        self.u, self.v = list(np.asarray(data["u"])), list(np.asarray(data["v"]))
        self._last = int(data["last"])

    def record(self, run: Run, n: int, state: State) -> None:
        if n % self.every == 0:
            self._take(n, state)

    def close(self, run: Run, status: str, n_last: int, state: State) -> None:
        if self._last != n_last:
            self._take(n_last, state)

    def snapshots(self) -> dict[str, np.ndarray]:
        return {"t": np.array(self.t), "u": np.array(self.u), "v": np.array(self.v)}


class ProgressCallback(Observer):
    """Calls ``callback(step, n_steps)`` after every step."""

    def __init__(self, callback: Callable[[int, int], None]):
        self.callback = callback

    def record(self, run: Run, n: int, state: State) -> None:
        self.callback(n, run.n_steps)


class CentreOfMassRecorder(Observer):
    """Position and velocity of the centre of mass along a direction, per level.

    With E the rigid translation along the unit vector ``direction`` (E_{d i + k} =
    direction_k) and M the run's mass matrix, x_G = (E^T M U)/(E^T M E) and v_G =
    (E^T M V)/(E^T M E) [length, length/time]: the mean displacement weighted by the
    discrete mass, whose motion obeys m x_G'' = E^T (forces) exactly when the mass
    matrix is the one the scheme integrates.  One dot product per level.  ``region``: the
    centre of the nodes of that region's cells only (a body of several: E is zero elsewhere;
    M is block diagonal over the bodies, so it is that body's centre of mass).
    """

    def __init__(self, direction, region: str | None = None):
        self.direction = np.asarray(direction, dtype=float)
        self.region = region

    def start(self, run: Run) -> None:
        n_nodes = run.ctx.M.shape[0] // self.direction.size
        E = np.tile(self.direction, n_nodes)
        if self.region is not None:
            keep = np.zeros(n_nodes, dtype=bool)
            keep[run.ctx.disc.problem.mesh.region_nodes(self.region)] = True
            E = E * np.repeat(keep, self.direction.size)
        w = run.ctx.M @ E
        self.weights = w / float(w @ E)
        self.position = np.full(run.n_steps + 1, np.nan)
        self.velocity = np.full(run.n_steps + 1, np.nan)
        self._put(0, run.initial)

    def grow(self, size: int) -> None:
        grown = _grown({"position": self.position, "velocity": self.velocity}, size)
        self.position, self.velocity = grown["position"], grown["velocity"]

    def _put(self, n: int, s: State) -> None:
        self.position[n] = self.weights @ s.U
        self.velocity[n] = self.weights @ s.V

    def record(self, run: Run, n: int, state: State) -> None:
        self._put(n, state)

    def close(self, run: Run, status: str, n_last: int, state: State) -> None:
        self.position, self.velocity = self.position[: n_last + 1], self.velocity[: n_last + 1]
