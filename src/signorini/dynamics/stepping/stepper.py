"""The public stepper: a run one time level at a time (in the spirit of scipy's ``OdeSolver``).

``Stepper(problem, scheme, grid, options)``: a problem, a scheme, the time grid ``(dt, T)``
and one :class:`~.run_options.RunOptions`; its set-up (discretization, factorization, level
0) happens in the constructor.  Then ``step()`` computes one time level, and ``t``, ``dt``,
``n``, ``state``, ``status`` (``running``, ``finished``, ``failed``, ``interrupted``),
``message`` and ``counters`` say where the run is; ``finish()`` closes the observers and
returns the :class:`~.history.History` of the levels computed.  :func:`~.simulate.simulate`
is a short loop over it that adds the signal handling and, on several ranks, the agreement
to stop.

A hand-driven loop::

    stepper = Stepper(problem, "crank-nicolson", (1e-3, 1.0), {"mass": "seed"})
    while stepper.status == "running":
        stepper.step()
        if stepper.state.lam.min() < -1e3:   # any condition of the user's
            break
    history = stepper.finish()               # "interrupted" when stopped before T

What the stepper delegates: the energy control's trials and rejections to
:class:`~.step_control.AdaptiveSteps`, the checkpoints to :class:`~.checkpointer.Checkpointer`
(``options.checkpoint``, a :class:`~.run_options.CheckpointPolicy`: every K levels, and the
last level computed when the run ends), what a step changes to the restartable parts of
:mod:`~.restart`.  :meth:`Stepper.resume` continues a run from a checkpoint: the same problem,
scheme, mass and dt (checked), and any final time T at or after the checkpoint; it computes
what the uninterrupted run computes (bit for bit on the same machine, backend and thread
count) and its history holds every level from t = 0.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import ConvergenceError, InputError
from ...linalg.base import clear_kept_analyses, total_memory
from ...linalg.threads import blas_controller, blas_threads
from ..model.problem import Discretization, Problem
from ..observe.events import StopRun, events_list
from ..observe.history import History
from ..observe.observers import grow_observers
from ..observe.rotation_watch import ROTATION_LIMIT, RotationWatch
from ..observe.untagged import UntaggedContact
from ..restart import checkpoint as ckpt
from ..restart.protocol import Pairing, SolverStates, StepParts
from ..schemes import Scheme, State, make_scheme
from .checkpointer import Checkpointer
from .run_options import RunOptions
from .setup import (
    MAX_CONTACT_RESIDUAL,
    finish_history,
    make_observers,
    number_of_steps,
    run_options,
    set_up,
)
from .step_control import AdaptiveSteps, control_spec
from .time_grid import TimeGrid

#: the values of :attr:`Stepper.status`
STATUSES = ("running", "finished", "failed", "interrupted")


class Stepper:
    """A run, one time level at a time (module docstring).

    Parameters
    ----------
    problem : a :class:`~.problem.Problem` or an assembled :class:`~.problem.Discretization`.
    scheme : a name or alias of :data:`~.schemes.SCHEMES`, a :class:`~.schemes.Scheme`
        subclass or an instance.
    grid : ``(dt, T)``: the time step [s] (a number, or a schedule ``[{until, dt}, ...]``,
        :mod:`~.time_grid`) and the final time [s] (None: a schedule's last ``until``).
    options : a :class:`~.run_options.RunOptions` (or a mapping of its names): the mass, the
        solver and scheme options, observers, events, the step control, the checkpoint policy.

    A run continued from a checkpoint is built by :meth:`resume`.

    Attributes
    ----------
    t, dt : the time of the current level and the time step [s].
    n, n_steps : the current level and the last one (T / dt).
    state : the :class:`~.schemes.State` of the current level.
    status, message : ``running`` until the run ends; why it ended early.
    run : the :class:`~.observers.Run` (context, scheme, initial state) observers see.
    solvers, pairing : the solvers' and the rows' restartable data (:class:`~.restart.protocol.SolverStates`,
        :class:`~.restart.protocol.Pairing`).
    step_parts : what a rejected step's rollback puts back (:class:`~.restart.protocol.StepParts`).
    adaptive : the energy control (:class:`~.step_control.AdaptiveSteps`; None: fixed steps).
    checkpointer : the run's checkpoints (:class:`~.checkpointer.Checkpointer`).
    resumed_from : the level and time the run resumed at (None: it started at t = 0).
    """

    def __init__(
        self,
        problem: Problem | Discretization,
        scheme: str | type[Scheme] | Scheme = "crank-nicolson",
        grid: tuple[Any, float | None] = (0.01, 1.0),
        options: RunOptions | Mapping[str, Any] | None = None,
    ) -> None:
        self._build(problem, scheme, grid, options, None)

    @classmethod
    def resume(
        cls,
        checkpoint: str | Path,
        problem: Problem | Discretization,
        scheme: str | type[Scheme] | Scheme = "crank-nicolson",
        grid: tuple[Any, float | None] = (0.01, 1.0),
        options: RunOptions | Mapping[str, Any] | None = None,
    ) -> Stepper:
        """The run of ``checkpoint`` continued: the same problem, scheme, mass and dt (checked:
        a mismatch is an InputError naming what differs) to any final time T at or after the
        checkpoint's.  It computes what the uninterrupted run computes (bit for bit on the same
        machine, backend and thread count) and its history holds every level from t = 0."""
        if not isinstance(checkpoint, (str, Path)):
            raise InputError(f"Stepper.resume needs the path of a checkpoint, got {type(checkpoint).__name__}")
        stepper = cls.__new__(cls)
        stepper._build(problem, scheme, grid, options, Path(checkpoint))
        return stepper

    def _build(
        self,
        problem: Problem | Discretization,
        scheme: str | type[Scheme] | Scheme,
        grid: Any,
        options: RunOptions | Mapping[str, Any] | None,
        resume: Path | None,
    ) -> None:
        dt, T = check_problem_and_grid(problem, grid, resume)
        o = RunOptions.of(options)
        saved = ckpt.read(resume) if resume is not None else None  # a bad file: refused before the set-up
        control_name, control_options = control_spec(o.control)
        if saved is None:
            self.grid = TimeGrid.build(dt, T)
        elif control_name == "energy" and "time_control" in saved["attrs"]:
            self.grid = adaptive_grid(dt, T, saved["attrs"], str(resume))
        else:
            a = saved["attrs"]
            self.grid = TimeGrid.build(dt, T, int(a["level"]), float(a["t"]), a.get("segment"))
            if int(a["level"]) > self.grid.n_steps:
                raise InputError(
                    f"checkpoint {str(resume)!r} is at t = {a['t']:.10g} (level {a['level']}), after "
                    f"this run's T = {self.grid.T:.10g}; give a later T"
                )
        sch = make_scheme(scheme, o.scheme_options)
        self.adaptive: AdaptiveSteps | None = None
        if control_name == "energy":
            mesh = problem.problem.mesh if hasattr(problem, "problem") else problem.mesh
            self.adaptive = AdaptiveSteps.build(self, sch, self.grid, o.energy, control_options, mesh)
        steps = {s.dt for s in self.grid.segments} | ({float(saved["attrs"]["dt"])} if saved is not None else set())
        if len(steps) > 1 and not getattr(sch, "variable_step", True):
            raise InputError(
                f"scheme {sch.name} cannot change its time step ({sch.variable_step_refusal}); give one "
                "dt (and resume with the run's own)"
            )
        opts = run_options(o.snapshot_every, o.backend, o.memory_budget, o.solver_options)
        events = events_list(o.events)
        if events:
            from ..observe.events import parse_stop_at

            parse_stop_at([e for e in events if isinstance(e, str)], "events")  # names checked before the set-up
        t0 = time.perf_counter()
        # a resumed run: factorized for the checkpoint's step (the solvers' warm starts and Delassus
        # columns restored are of that step)
        dt0 = None if saved is None else float(saved["attrs"]["dt"])
        self.run, self.starter = set_up(problem, o.mass, sch, self.grid, opts, dt_initial=dt0)
        self.setup_seconds = time.perf_counter() - t0
        run = self.run
        self.recorder, self.energies, self.snaps, obs = make_observers(
            o.snapshot_every, o.energy, o.progress, o.observers
        )
        if self.energies is not None:
            self.energies.check = run.ctx.solver_options.get("energy_check", "warn")
        self.untagged = UntaggedContact(run.ctx.solver_options.get("untagged_contact", "warn"))
        obs.insert(1, self.untagged)
        self.rotation = RotationWatch(float(run.ctx.solver_options.get("rotation_limit", ROTATION_LIMIT)))
        obs.insert(2, self.rotation)
        self.watch = None
        if events:
            from ..observe.events import EventWatch

            self.watch = EventWatch(events)
            obs.append(self.watch)  # last: the level is recorded before a terminal event ends the run
        self.observers = obs
        self.n, self.state = 0, run.initial
        self._first = 0  # the level the loop starts from (a resumed run: the checkpoint's)
        self.status, self.message = "running", ""
        self.resumed_from: dict[str, Any] | None = None
        self._capacity = run.n_steps + 1  # levels the observers have room for
        #: factor bytes an adaptive control keeps for the steps it left (a quarter of the budget)
        ladder_bytes = 0.25 * float(run.ctx.solver_options.get("memory_budget") or total_memory())
        self.solvers = SolverStates(run.ctx, self.adaptive is not None, ladder_bytes)
        self.pairing = Pairing(run.ctx, lambda: self.t)
        self.step_parts = StepParts(self.solvers, self.pairing)  # a rejected step's rollback
        self.checkpointer = Checkpointer(self, o.checkpoint, o.case_hash)
        self._loop_seconds = 0.0
        #: the BLAS threads of the loop (0: the libraries' own); a driver that holds them already
        #: sets :attr:`in_loop` (:func:`~.simulate.simulate`)
        self.threads = run.ctx.solver_options.get("loop_blas_threads", 1)
        self.in_loop = False
        self._blas: Any = None
        self._history: History | None = None
        self._base_counters = run.ctx.counters()  # the set-up's (a resumed run adds the loop's only)
        self._counters_before: dict[str, int] = {}
        self._started: list[Any] = []
        try:
            for ob in obs:
                ob.start(run)
                self._started.append(ob)
            if saved is not None:
                with blas_threads(self.threads):  # the Delassus blocks solved again as in the loop that solved them
                    where = self.checkpointer.restore(saved, str(resume))
                self.n = self._first = where["level"]
                self._counters_before = where["counters"]
                self.resumed_from = {
                    "level": where["level"],
                    "t": where["t"],
                    "checkpoint": str(resume),
                    "created": where["created"],
                }
                self._base_counters = run.ctx.counters()  # after the operators the restore factorized
        except BaseException:
            self.close_observers()
            raise
        if self.n >= self.n_steps:
            self.status = "finished"

    # -- where the run is ------------------------------------------------------------
    @property
    def n_steps(self) -> int:
        """The index of the last level (an adaptive control's grid changes it as it refines)."""
        return self.grid.n_steps

    @property
    def t(self) -> float:
        return float(self.state.t)

    @property
    def dt(self) -> float:
        """The time step of the last step taken (the first one before any) [s]."""
        return float(self.run.ctx.dt)

    @property
    def counters(self) -> dict[str, int]:
        """The run's counters so far (``summary.json`` ``counters``)."""
        now = self.run.ctx.counters()
        if self.resumed_from is None:
            out = dict(now)
        else:  # the run it continues, plus this run's loop (not its set-up)
            out = dict(self._counters_before)
            for k, v in now.items():
                out[k] = out.get(k, 0) + v - self._base_counters.get(k, 0)
            if "pair_rows_repaired" in now:
                out["pair_rows_repaired"] = now["pair_rows_repaired"]  # restored with the pairing
        out["steps"] = self.n
        return out

    # -- the loop --------------------------------------------------------------------
    def step(self) -> str:
        """Compute the next time level; returns the status (``running`` while levels remain).

        A step that fails (a solver that does not converge, a non-finite state, a contact
        residual above tolerance) ends the run as ``failed`` and keeps the levels before it;
        a terminal event ends it as ``finished`` after its level.
        """
        if self.status != "running":
            raise RuntimeError(f"the stepper is {self.status} at level {self.n} ({self.message or 'no more steps'})")
        if self.in_loop or self.threads <= 0:
            return self._step()
        if self._blas is None:  # the libraries loaded after the set-up: found once, not at every step
            self._blas = blas_controller()
        with blas_threads(self.threads, self._blas):
            return self._step()

    def trial(self, n: int) -> tuple[State | None, str]:
        """Level n computed from the current one, not accepted: (state, "") or (None, why it
        failed).  What it changed is put back by the rollback of the parts marked before it
        (:meth:`~.step_control.AdaptiveSteps.step`, :mod:`~.restart`)."""
        try:
            new = self._advance(n)
        except (ConvergenceError, InputError, np.linalg.LinAlgError, FloatingPointError) as exc:
            return None, f"step {n} (t = {self.grid.time_of(n):.6g}): {exc}"
        if not new.is_finite():
            return None, f"step {n} (t = {self.grid.time_of(n):.6g}): non-finite value in the state"
        if new.info is not None and not new.info.residual <= MAX_CONTACT_RESIDUAL:
            return None, (
                f"step {n} (t = {self.grid.time_of(n):.6g}): the contact solve did not reach complementarity "
                f"(residual {new.info.residual:.3g} > {MAX_CONTACT_RESIDUAL:g})"
            )
        return new, ""

    def _step(self) -> str:
        run, n = self.run, self.n + 1
        t0 = time.perf_counter()
        self.checkpointer.before_step()
        try:
            t_before = self.t
            if self.adaptive is None:
                new, why = self.trial(n)
            else:
                self.adaptive.force_before = self.state.lam
                new, why = self.adaptive.step(n)
            if new is None:
                return self._stop("failed", why)
            if self.adaptive is not None and n + 1 > self._capacity:
                self._capacity = grow_observers(run, self.observers, 2 * self._capacity)  # geometric: not the
                # levels a refined step would take to T
            try:
                for o in self.observers:
                    o.record(run, n, new)
            except ConvergenceError as exc:  # e.g. an energy that overflows
                return self._stop("failed", f"step {n} (t = {self.grid.time_of(n):.6g}): {exc}")
            except StopRun as exc:  # a terminal event after this level (the last observer): it is kept
                self._accept(new, n, t_before)  # and re-paired as after any level: a resume continues from there
                return self._stop("finished", str(exc))
            self._accept(new, n, t_before)
            if self.n >= self.n_steps:
                self.status = "finished"
            else:
                self.checkpointer.level_done()
            return self.status
        finally:
            self._loop_seconds += time.perf_counter() - t0

    def _accept(self, new: State, n: int, t_before: float) -> None:
        """Level n is the run's: small sliding re-pairs after it, the control counts it, and
        what a checkpoint of it holds is taken again before the next step's work."""
        self.state, self.n = new, n
        self.run.ctx.slide(new.U, new.t)  # contact pairs: slave nodes that left their master facet re-paired
        self.checkpointer.accepted()
        if self.adaptive is not None:
            self.adaptive.accepted(t_before)
            self.run.n_steps = self.grid.n_steps  # the levels if the step were kept (a progress bar's "of N")

    def _advance(self, n: int) -> State:
        run = self.run
        self.use_segment(n)
        if n == 1 and self.starter is not None:
            new = run.scheme.start(run.ctx, self.state, self.starter.step(run.ctx, self.state))
        else:
            new = run.scheme.step(run.ctx, self.state)
        r = None if new.info is None else new.info.force_residual
        if r is not None:  # Newton's residual at the level: its work is a term of the energy identity (solver_work)
            new.extra["newton_residual"] = r
        return new

    def use_segment(self, n: int) -> None:
        """The step and time origin of level n's segment in the context (a new step factorized)."""
        run = self.run
        seg = self.grid.segment(n)
        ctx = run.ctx
        if seg.dt != ctx.dt:  # a new step: its factorization (the old one released, or kept by a control)
            ops = [op for op in (run.scheme.step_operator(ctx, seg.dt),) if op is not None]
            if self.adaptive is not None:
                ctx.use_step(seg.dt, seg.start, ops, self.solvers.ladder_bytes)
            else:
                ctx.change_dt(seg.dt, seg.start, ops)
            if ops:
                run.scheme.check_context(ctx, prepared=True)
        elif seg.start != ctx.t0:
            ctx.t0 = seg.start

    def _stop(self, status: str, message: str) -> str:
        self.status, self.message = status, message
        return status

    def interrupt(self, message: str) -> None:
        """End a running run as ``interrupted`` with ``message`` (the levels computed are kept)."""
        if self.status == "running":
            self._stop("interrupted", message)

    def save_checkpoint(self, path: str | Path | None = None) -> Path | None:
        """Write the checkpoint of the current level (to ``path``, else the policy's; only rank
        0 writes on several ranks).  Returns the path written."""
        return self.checkpointer.save(path)

    # -- the end ---------------------------------------------------------------------
    def close_observers(self) -> None:
        """Close every observer started (once)."""
        started, self._started = self._started, []
        for o in started:
            o.close(self.run, self.status, self.n, self.state)

    def finish(self) -> History:
        """Close the observers and return the :class:`History` of levels 0..n (once; later
        calls return the same).  A run still running ends as ``interrupted``.  With
        checkpoints on, the last level computed is checkpointed (whatever the status: a
        finished run can be continued to a later T)."""
        if self._history is not None:
            return self._history
        if self.status == "running":
            self._stop("interrupted", f"finish() called after step {self.n} of {self.n_steps}")
        self.checkpointer.at_exit()
        try:
            self.close_observers()
        finally:
            self._history = self._assemble()
            clear_kept_analyses()  # the analyses released factors left for this run's next tangents
        return self._history

    def _assemble(self) -> History:
        run = self.run
        H = finish_history(
            run,
            self.n,
            self.recorder,
            self.energies,
            self.snaps,
            self.setup_seconds,
            self._loop_seconds,
            counters=self.counters,
            steps=self.n - self._first,
        )
        if self.watch is not None:
            H.meta["events"] = self.watch.met
            H.meta["stop_at"] = [e.name for e in getattr(self.watch, "events", []) if e.terminal]
        H.untagged_penetration = self.untagged.series
        H.master_penetration = self.untagged.master_series
        # every node watched: against the rigid obstacle and against the surfaces of the pairs
        H.meta["untagged_boundary_nodes"] = self.untagged.watched_nodes()
        H.meta["untagged_worst_penetration"] = self.untagged.worst[0]  # the failing level of untagged_contact=fail too
        H.meta.update(self.untagged.master_summary() or {})  # the master nodes through the slave surface (reported)
        if self.untagged.exceeded():
            H.meta["warnings"].append(self.untagged.message())
        self.rotation.summary(H.meta)
        failed = self.status == "failed"
        if self.energies is not None:
            self.energies.report(H.meta, H.lam, H.t, run, failed, self.adaptive is not None)
        self.checkpointer.summary(H.meta)
        if self.resumed_from is not None:
            H.meta["resumed_from"] = dict(self.resumed_from)
        if self.adaptive is not None:
            factorizations = int(self.counters.get("factorizations", 0))
            self.adaptive.summary(H.meta, self.energies.energy_scale, factorizations, failed)
        else:
            steps = [seg.dt for seg in self.grid.segments]
            H.meta["time_control"] = {
                "control": "fixed",
                "dt_smallest_used": min(steps),
                "dt_largest_used": max(steps),
                "steps_accepted": self.n - self._first,
                "steps_rejected": 0,
            }
        steps = schedule_of(H.t)
        if len(steps) > 1:
            H.meta["dt_schedule"] = steps
        H.meta["T"] = float(self.grid.T)
        H.status, H.message = self.status, self.message
        return H


def check_problem_and_grid(problem: Any, grid: Any, resume: Any = None) -> tuple[Any, Any]:
    """The (dt, T) of ``grid``, the problem's type and the step checked first (a one-line InputError before
    anything is built)."""
    if not isinstance(problem, (Problem, Discretization)):
        raise InputError(
            f"simulate's problem must be a signorini Problem or Discretization, got {type(problem).__name__}"
        )
    if not isinstance(grid, (tuple, list)) or len(grid) != 2:
        raise InputError(
            f"the stepper's grid must be a pair (dt, T): Stepper(problem, scheme, (dt, T), options), got {grid!r}"
        )
    dt, T = grid
    if not isinstance(dt, (list, tuple)) and resume is None:
        number_of_steps(dt, T)
    return dt, T


def adaptive_grid(dt: Any, T: float, attrs: dict[str, Any], where: str) -> TimeGrid:
    """The grid of an adaptive run resumed from a checkpoint: the plan of ``dt`` (or its
    schedule) up to T, continued from the checkpoint's level on the segment it was on (its
    step dt_piece / 2^k and its origin: the levels' times are those of the uninterrupted run)."""
    grid = TimeGrid.build(dt, T)
    try:
        level, t = int(attrs["level"]), float(attrs["t"])
        start, step, first = (float(attrs["segment"][0]), float(attrs["segment"][1]), int(attrs["segment"][2]))
    except (KeyError, TypeError, ValueError, IndexError):
        raise InputError(f"checkpoint {where!r}: its level, time or segment is malformed") from None
    if not (np.isfinite([t, start, step]).all() and step > 0 and 0 <= first <= level and 0.0 <= start <= t):
        raise InputError(f"checkpoint {where!r}: its segment {attrs['segment']!r} does not hold level {level}")
    if t >= grid.T * (1 - 1e-12):
        raise InputError(
            f"checkpoint {where!r} is at t = {t:.10g}, at or after this run's T = {grid.T:.10g}; give a later T"
        )
    _, _, dt_piece = grid.piece(t)
    k = np.log2(dt_piece / step)
    if not (0 <= round(k) <= 64 and abs(k - round(k)) < 1e-9):
        raise InputError(
            f"checkpoint {where!r}: its step {step:g} is not dt / 2^k of this run's dt {dt_piece:g}; "
            "resume with the run's own dt"
        )
    grid.continue_with(level, t, step, start=start, first=first)
    return grid


def schedule_of(t: np.ndarray) -> list[dict[str, float]]:
    """[{until, dt}] of the levels t (consecutive steps equal to a relative 1e-9 merged)."""
    out: list[dict[str, float]] = []
    for k in range(1, len(t)):
        step = float(t[k] - t[k - 1])
        if out and abs(step - out[-1]["dt"]) <= 1e-9 * out[-1]["dt"]:
            out[-1]["until"] = float(t[k])
        else:
            out.append({"until": float(t[k]), "dt": float(f"{step:.12g}")})  # the step, not its round-off
    return out
