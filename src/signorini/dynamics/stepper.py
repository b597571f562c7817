"""The public stepper: a run one time level at a time (in the spirit of scipy's ``OdeSolver``).

:class:`Stepper` is built from the arguments of :func:`~.simulate.simulate`; its set-up
(discretization, factorization, level 0) happens in the constructor.  Then
``step()`` computes one time level, and ``t``, ``dt``, ``n``, ``state``, ``status``
(``running``, ``finished``, ``failed``, ``interrupted``), ``message`` and ``counters`` say
where the run is; ``finish()`` closes the observers and returns the
:class:`~.history.History` of the levels computed.  :func:`~.simulate.simulate` is a short
loop over it that adds the signal handling and, on several ranks, the agreement to stop.

A hand-driven loop::

    stepper = Stepper(problem, "crank-nicolson", dt=1e-3, T=1.0)
    while stepper.status == "running":
        stepper.step()
        if stepper.state.lam.min() < -1e3:   # any condition of the user's
            break
    history = stepper.finish()               # "interrupted" when stopped before T

Checkpoints (:mod:`~.checkpoint`): ``checkpoint=PATH`` with ``checkpoint_every=K`` writes
the state of every K-th level to PATH, and of the last level computed when the run ends
(finished, interrupted or failed); ``resume=PATH`` continues a run from such a file: the same
problem, scheme, mass and dt (checked), and any final time T at or after the checkpoint.
The resumed run computes what the uninterrupted run computes (bit for bit on the same
machine, backend and thread count) and its history holds every level from t = 0.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConvergenceError, InputError
from ..linalg import total_memory
from ..linalg.threads import blas_threads
from . import checkpoint as ckpt
from .events import StopRun, events_list
from .history import History
from .mass import DEFAULT_MASS
from .problem import Discretization, Problem
from .schemes import Scheme, State, make_scheme
from .setup import (
    MAX_CONTACT_RESIDUAL,
    finish_history,
    make_observers,
    number_of_steps,
    run_options,
    set_up,
)
from .step_control import MAX_LEVELS, EnergyControl, control_spec
from .time_grid import TimeGrid
from .untagged import UntaggedContact

#: the values of :attr:`Stepper.status`
STATUSES = ("running", "finished", "failed", "interrupted")


class Stepper:
    """A run, one time level at a time (module docstring).

    Parameters
    ----------
    problem, scheme, dt, T, mass, snapshot_every, backend, memory_budget, progress,
    scheme_options, solver_options, observers, energy, events :
        as :func:`~.simulate.simulate`.
    checkpoint : path of the checkpoint file to write (None: none), or a function
        returning it (called at the first write: a result directory made when needed).
    checkpoint_every : write it every K levels (0: only when the run ends early).
    checkpoint_meta : JSON-able data stored with every checkpoint (the command line keeps
        there how to rebuild the run) and ``case_hash`` its case file's hash (identity).
    resume : path of a checkpoint to continue from (its level must be before T).
    on_checkpoint : called with (level, t, counters, scheme, mass) after each checkpoint
        of the run is complete (the command line tells its watchdog).

    Attributes
    ----------
    t, dt : the time of the current level and the time step [s].
    n, n_steps : the current level and the last one (T / dt).
    state : the :class:`~.schemes.State` of the current level.
    status, message : ``running`` until the run ends; why it ended early.
    run : the :class:`~.observers.Run` (context, scheme, initial state) observers see.
    resumed_from : the level and time the run resumed at (None: it started at t = 0).
    """

    def __init__(
        self,
        problem: Problem | Discretization,
        scheme: str | type[Scheme] | Scheme = "crank-nicolson",
        dt: float = 0.01,
        T: float = 1.0,
        mass: str = DEFAULT_MASS,
        snapshot_every: int = 0,
        backend: str | None = None,
        memory_budget: float | None = None,
        progress: Callable[[int, int], None] | None = None,
        *,
        scheme_options: Mapping[str, Any] | None = None,
        solver_options: Mapping[str, Any] | None = None,
        observers: Iterable[Any] = (),
        energy: bool = True,
        events: Iterable[Any] = (),
        checkpoint: str | Path | Callable[[], Path] | None = None,
        checkpoint_every: int = 0,
        checkpoint_meta: Mapping[str, Any] | None = None,
        case_hash: str | None = None,
        resume: str | Path | None = None,
        on_checkpoint: Callable[[dict[str, Any]], None] | None = None,
        control: str | Mapping[str, Any] | None = None,
    ) -> None:
        if not isinstance(problem, (Problem, Discretization)):
            raise InputError(f"simulate's problem must be a signorini Problem or Discretization, got "
                             f"{type(problem).__name__}")  # fmt: skip
        if not isinstance(dt, (list, tuple)) and resume is None:
            number_of_steps(dt, T)  # dt and T first: a one-line error before anything is built
        if not isinstance(checkpoint_every, int) or isinstance(checkpoint_every, bool) or checkpoint_every < 0:
            raise InputError(f"checkpoint_every must be a non-negative integer, got {checkpoint_every!r}")
        if checkpoint_every and checkpoint is None:
            raise InputError("checkpoint_every needs a checkpoint path (checkpoint=...)")
        saved = ckpt.read(Path(resume)) if resume is not None else None  # a bad file: refused before the set-up
        control_name, control_options = control_spec(control)
        if saved is None:
            grid = TimeGrid.build(dt, T)
        elif control_name == "energy" and "time_control" in saved["attrs"]:
            grid = adaptive_grid(dt, T, saved["attrs"], str(resume))
        else:
            a = saved["attrs"]
            grid = TimeGrid.build(dt, T, int(a["level"]), float(a["t"]), a.get("segment"))
            if int(a["level"]) > grid.n_steps:
                raise InputError(f"checkpoint {str(resume)!r} is at t = {a['t']:.10g} (level {a['level']}), after "
                                 f"this run's T = {grid.T:.10g}; give a later T")  # fmt: skip
        self.grid = grid
        sch = make_scheme(scheme, scheme_options)
        self.control: EnergyControl | None = None
        if control_name == "energy":
            why = sch.step_control_refusal() if hasattr(sch, "step_control_refusal") else ""
            if why:
                raise InputError(f"control 'energy' cannot run scheme {sch.label}: {why}; use control 'fixed'")
            if not energy:
                raise InputError("control 'energy' judges each step by the energy identity: it needs energy=True")
            self.control = EnergyControl(**control_options)
            smallest = min(piece[2] for piece in grid.plan)
            self.control.dt_min_used = self.control.dt_min or smallest / 2 ** self.control.k_max(smallest)
            if self.control.dt_min > smallest:
                raise InputError(f"control 'energy': dt_min = {self.control.dt_min:g} is above the step "
                                 f"{smallest:g}; give dt_min <= dt")  # fmt: skip
            if 0 < self.control.dt_min < smallest / 2**MAX_LEVELS:
                raise InputError(f"control 'energy': dt_min = {self.control.dt_min:g} is below dt / 2^{MAX_LEVELS} = "
                                 f"{smallest / 2**MAX_LEVELS:.4g} (the energy identity is lost to round-off at such "
                                 "steps); give a larger dt_min")  # fmt: skip
        steps = {s.dt for s in grid.segments} | ({float(saved["attrs"]["dt"])} if saved is not None else set())
        if len(steps) > 1 and not getattr(sch, "variable_step", True):
            raise InputError(f"scheme {sch.name} cannot change its time step ({sch.variable_step_refusal}); give one "
                             "dt (and resume with the run's own)")  # fmt: skip
        opts = run_options(snapshot_every, backend, memory_budget, solver_options)
        events = events_list(events)
        if events:
            from .events import parse_stop_at

            parse_stop_at([e for e in events if isinstance(e, str)], "events")  # names checked before the set-up
        t0 = time.perf_counter()
        # a resumed run: factorized for the checkpoint's step (the solvers' warm starts and Delassus
        # columns restored are of that step)
        dt0 = None if saved is None else float(saved["attrs"]["dt"])
        self.run, self.starter = set_up(problem, mass, sch, grid, opts, dt_initial=dt0)
        self.setup_seconds = time.perf_counter() - t0
        run = self.run
        self.recorder, self.energies, self.snaps, obs = make_observers(snapshot_every, energy, progress, observers)
        if self.energies is not None:
            self.energies.check = run.ctx.solver_options.get("energy_check", "warn")
        self.untagged = UntaggedContact(run.ctx.solver_options.get("untagged_contact", "warn"))
        obs.insert(1, self.untagged)
        self.watch = None
        if events:
            from .events import EventWatch

            self.watch = EventWatch(events)
            obs.append(self.watch)  # last: the level is recorded before a terminal event ends the run
        self.observers = obs
        self.n, self.state = 0, run.initial
        self._first = 0  # the level the loop starts from (a resumed run: the checkpoint's)
        self.status, self.message = "running", ""
        self.resumed_from: dict[str, Any] | None = None
        self._checkpoint = checkpoint
        self._on_checkpoint = on_checkpoint
        self._series = ckpt.SeriesLog()  # the levels' series written beside the checkpoint
        self._meta = dict(checkpoint_meta or {})
        self.log = ckpt.CheckpointLog(checkpoint_every, checkpoint) if checkpoint is not None else None
        self._identity = ckpt.identity(run, case_hash)
        self._capacity = run.n_steps + 1  # levels the observers have room for
        #: factor bytes an adaptive control keeps for the steps it left (a quarter of the budget)
        self._ladder_bytes = 0.25 * float(run.ctx.solver_options.get("memory_budget") or total_memory())
        self._verdict: tuple = ()
        self._next_segment: list | None = None  # an adaptive run's step grown at T (:meth:`_grow_step`)
        self._loop_seconds = 0.0
        self._threads = run.ctx.solver_options.get("loop_blas_threads", 1)
        self._in_loop = False
        self._history: History | None = None
        self._base_counters = run.ctx.counters()  # the set-up's (a resumed run adds the loop's only)
        self._counters_before: dict[str, int] = {}
        self._started: list[Any] = []
        #: the counters at the current level, taken before the next step works (a step that fails
        #: or is interrupted has solved already: its checkpoint is of the level before it)
        self._level_counters: dict[str, int] | None = None
        self._level_warm: list[tuple] | None = None  # the warm starts at the current level
        try:
            for o in obs:
                o.start(run)
                self._started.append(o)
            if saved is not None:
                with blas_threads(self._threads):  # the Delassus blocks solved again as in the loop that solved them
                    self._resume(saved, str(resume))
                self._base_counters = run.ctx.counters()  # after the operators the restore factorized
        except BaseException:
            self._close_observers()
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
        if self._in_loop or self._threads <= 0:
            return self._step()
        with blas_threads(self._threads):
            return self._step()

    def _trial(self, n: int) -> tuple[State | None, str]:
        """Level n computed from the current one: (state, "") or (None, why it failed)."""
        try:
            new = self._advance(n)
        except (ConvergenceError, InputError, np.linalg.LinAlgError, FloatingPointError) as exc:
            return None, f"step {n} (t = {self._time_of(n):.6g}): {exc}"
        if not new.is_finite():
            return None, f"step {n} (t = {self._time_of(n):.6g}): non-finite value in the state"
        if new.info is not None and not new.info.residual <= MAX_CONTACT_RESIDUAL:
            return None, (f"step {n} (t = {self._time_of(n):.6g}): the contact solve did not reach complementarity "
                          f"(residual {new.info.residual:.3g} > {MAX_CONTACT_RESIDUAL:g})")  # fmt: skip
        return new, ""

    def _controlled(self, n: int) -> tuple[State | None, str]:
        """Level n under the energy control (:mod:`~.step_control`): a step judged above its
        allowance, or failed, is rejected (the solvers' warm starts put back) and tried again
        at half the step, down to dt_min."""
        ctl, grid, run = self.control, self.grid, self.run
        comm = run.ctx.comm
        while True:
            begin, _, dt_piece = grid.piece(self.t)
            h = grid.segment(n).dt
            self._use_segment(n)  # the systems of h first: theirs are the warm starts a rejection puts back
            saved = self._save_point()
            new, why = self._trial(n)
            if comm.any(new is None):  # every rank takes the same decision
                new, why = None, why or f"step {n} failed on another rank"
            if new is None:
                verdict = "reject" if ctl.k < ctl.k_max(dt_piece) else "failed"
                if verdict == "failed":
                    return None, why
                ctl.failed_trials += 1
            else:
                delta, scale, eta = self.energies.indicator(run, n, new)
                verdict = ctl.judge(delta, run.scheme.conserving, scale, h, dt_piece, eta)
                if comm.any(verdict == "reject"):
                    verdict = "reject"
            if verdict == "accept" and self.watch is not None and ctl.k < ctl.k_max(dt_piece) and comm.any(
                    self.watch.would_stop(new)):  # a terminal event inside the step: located within dt_min  # fmt: skip
                verdict = "reject"
                ctl.event_refinements += 1
            if verdict == "unresolved" and self.energies.check == "fail":  # energy_check=fail: levels kept
                allowed = ctl.allowed(scale, h, dt_piece)
                return None, (f"step {n} (t = {self._time_of(n):.6g}): at the smallest step {h:.3g} s the step still "
                              f"creates or destroys {abs(delta):.3g} of energy (its error estimate: {eta:.3g}), above "
                              f"the allowance {allowed:.3g} (energy_check=fail); give a smaller dt_min")  # fmt: skip
            if verdict in ("accept", "unresolved"):
                self._verdict = (verdict, delta, scale, h, dt_piece, eta)
                return new, ""
            self._restore_point(saved)
            if verdict == "retry":  # the test hook: the same step again
                continue
            ctl.rejected += 1
            ctl.k += 1
            ctl.calm = 0
            grid.continue_with(self.n, self.t, dt_piece / 2**ctl.k)

    def _after_accepted(self, t0: float) -> None:
        """The control's count of the level just accepted; the step grows by 2 after
        ``grow_after`` calm steps when the level is on the grid of the doubled step."""
        ctl, grid = self.control, self.grid
        verdict, delta, scale, h, dt_piece, eta = self._verdict
        excess = max(abs(delta) if self.run.scheme.conserving else delta, eta)
        ctl.note_accepted(t0, self.t, h, dt_piece, verdict, self.n, excess)
        self._grow_step(delta, scale, h, dt_piece, eta)
        self.run.n_steps = grid.n_steps  # the levels if the step were kept (a progress bar's "of N")

    def _grow_step(self, delta: float, scale: float, h: float, dt_piece: float, eta: float) -> None:
        """The step of the next levels: the piece's own at a piece's start; twice h after
        ``grow_after`` calm steps with a steady contact force, on the grid of 2h."""
        ctl, grid = self.control, self.grid
        at_T = self.n >= grid.n_steps
        begin, end, dt_piece_next = grid.piece(self.t)
        if not at_T and (dt_piece_next != dt_piece or begin >= self.t - 1e-12 * max(abs(self.t), h)):  # a new piece
            ctl.k, ctl.calm = 0, 0  # its own dt
            return
        calm = ctl.calm_step(delta, self.run.scheme.conserving, scale, h, dt_piece, eta)
        ctl.calm = ctl.calm + 1 if calm and ctl.steady_force(self._force_before, self.state.lam) else 0
        if ctl.k == 0 or ctl.calm < ctl.grow_after:
            return
        r = (self.t - begin) / (2.0 * h)
        if abs(r - round(r)) > 1e-6 * max(1.0, abs(r)):  # not on the grid of 2h yet
            return
        ctl.k -= 1
        ctl.calm = 0
        if at_T:  # T reached: the grown step is where a resume to a later T goes on (:meth:`_grid_attrs`)
            self._next_segment = [float(self.t), dt_piece / 2**ctl.k, self.n]
            return
        grid.continue_with(self.n, self.t, dt_piece / 2**ctl.k)

    def _save_point(self) -> list[tuple[Any, dict[str, np.ndarray]]]:
        """What a rejected step must put back: the warm starts of the solvers of the current step
        (the state, the pairing and the observers change only when a level is accepted; the
        Delassus columns a rejected step solved stay valid for its operator)."""
        out = []
        for sys in self.run.ctx.factors.current:
            names = getattr(sys.solver, "warm_state", ())
            out.append((sys, {name: np.array(getattr(sys.solver, name), copy=True) for name in names}))
        return out

    @staticmethod
    def _restore_point(saved: list[tuple[Any, dict[str, np.ndarray]]]) -> None:
        for sys, arrays in saved:
            for name, a in arrays.items():
                setattr(sys.solver, name, a.copy())

    def _step(self) -> str:
        run, n = self.run, self.n + 1
        t0 = time.perf_counter()
        if self.log is not None and self._level_warm is None:  # what a checkpoint of this level holds, if
            self._level_warm = self._warm_starts()  # this step fails or is interrupted midway
            self._level_grid = self._grid_attrs()
        if self.log is not None and self._level_counters is None:  # the counters at this level (before a
            self._level_counters = self.counters  # step's work): what a checkpoint of it holds
        try:
            t_before, self._force_before = self.t, self.state.lam
            new, why = self._trial(n) if self.control is None else self._controlled(n)
            if new is None:
                return self._stop("failed", why)
            if self.control is not None and n + 1 > self._capacity:
                self._grow_observers(2 * self._capacity)  # geometric: not the levels a refined step would take to T
            try:
                for o in self.observers:
                    o.record(run, n, new)
            except ConvergenceError as exc:  # e.g. an energy that overflows
                return self._stop("failed", f"step {n} (t = {self._time_of(n):.6g}): {exc}")
            except StopRun as exc:  # a terminal event after this level (the last observer): it is kept
                self._accept(new, n)  # and re-paired as after any level: a resume continues from there
                if self.control is not None:
                    self._after_accepted(t_before)
                return self._stop("finished", str(exc))
            self._accept(new, n)
            if self.control is not None:
                self._after_accepted(t_before)
            self._level_counters = None  # the counters of this level: taken when a checkpoint needs them
            if self.n >= self.n_steps:
                self.status = "finished"
            elif self.log is not None and self.log.every and self.n % self.log.every == 0:
                self._periodic_checkpoint()
            return self.status
        finally:
            self._loop_seconds += time.perf_counter() - t0

    def _grow_observers(self, size: int) -> None:
        """Room for ``size`` levels in every observer that keeps per-level arrays (``grow``)."""
        self.run.n_steps = size - 1
        for o in self.observers:
            if hasattr(o, "grow"):
                o.grow(size)
        self._capacity = size

    def _report_energy(self, H: History) -> None:
        """What the energy recorder found (:class:`~.observers.EnergyRecorder`): the warning of an
        identity that did not close; ``summary.json`` ``spurious_energy`` and ``single_level_contacts``,
        and the warning of a run whose scheme created more than 1% of its energy scale."""
        from .diagnostics import contact_duration_estimate, single_level_contacts

        e = self.energies
        if e.exceeded() and self.status != "failed":
            H.meta["warnings"].append(e.message())
        single = single_level_contacts(H.lam)
        H.meta["single_level_contacts"] = single
        H.meta["spurious_energy"] = {"absolute": e.spurious, "relative": e.spurious_relative(),
                                     "scale": e.energy_scale, "first_level": e.spurious_first}  # fmt: skip
        if e.spurious_exceeded() and self.status != "failed":
            first = e.spurious_first
            t_first = float(H.t[first]) if 0 <= first < H.t.size else None
            duration = contact_duration_estimate(self.run.ctx.disc.problem)
            H.meta["warnings"].append(
                e.spurious_message(
                    single, t_first, duration, self.run.dt, self.control is not None, self.run.ctx.disc.mass_name
                )
            )

    def _time_of(self, n: int) -> float:
        """The time of level n on the run's grid (for messages)."""
        seg = self.grid.segment(n)
        return seg.start + (n - seg.first) * seg.dt

    def _accept(self, new: State, n: int) -> None:
        """Level n is the run's: small sliding re-pairs after it, its counters and warm starts
        are what a checkpoint of it holds (taken again before the next step's work)."""
        self.state, self.n = new, n
        self.run.ctx.slide(new.U, new.t)  # contact pairs: slave nodes that left their master facet re-paired
        self._level_counters = None
        self._level_warm = None

    def _periodic_checkpoint(self) -> None:
        """A checkpoint every K levels; one that cannot be written (a full disk, a file-size
        limit) is said in the summary and the run goes on (the previous one is intact)."""
        try:
            self.save_checkpoint()
        except (OSError, RuntimeError, ValueError) as exc:
            self.log.error = f"level {self.n}: {type(exc).__name__}: {exc}"
            self.log.failed += 1

    def _warm_starts(self) -> list[tuple]:
        """The solvers' warm starts (copies: a few vectors) and the lengths of their Delassus
        logs now, per factorized operator: what a checkpoint of this level holds of them."""
        ctx = self.run.ctx
        # a rank's are its own rows; an adaptive control's kept steps too (least recently used first)
        systems = []
        if ctx.comm.size == 1:
            systems = ctx.factors.by_step() if self.control is not None else [(ctx.dt, s) for s in ctx.factors.current]
        out = []
        for dt, sys in systems:  # each factorized operator's solver, in order of creation
            warm = {
                name: np.array(getattr(sys.solver, name), copy=True) for name in getattr(sys.solver, "warm_state", ())
            }
            delassus = getattr(sys.solver, "delassus", None)
            out.append((sys, warm, len(delassus._log) if hasattr(delassus, "_log") else None, dt))
        return out

    @staticmethod
    def _warm_arrays(warm: list[tuple]) -> dict[str, np.ndarray]:
        """``solvers/k/...`` arrays of :meth:`_warm_starts`."""
        out: dict[str, np.ndarray] = {}
        for k, (sys, arrays, blocks, dt) in enumerate(warm):
            out[f"solvers/{k}/operator"] = np.array(sys.op.coefficients())
            out[f"solvers/{k}/dt"] = np.array(dt)
            out.update({f"solvers/{k}/{name}": a for name, a in arrays.items()})
            log = sys.solver.delassus.history(blocks) if blocks is not None else None
            if log is not None:  # the Delassus columns solved, to solve them again alike on resume
                out.update({f"solvers/{k}/delassus/{name}": a for name, a in log.items()})
        return out

    def _advance(self, n: int) -> State:
        run = self.run
        self._use_segment(n)
        if n == 1 and self.starter is not None:
            return run.scheme.start(run.ctx, self.state, self.starter.step(run.ctx, self.state))
        return run.scheme.step(run.ctx, self.state)

    def _use_segment(self, n: int) -> None:
        """The step and time origin of level n's segment in the context (a new step factorized)."""
        run = self.run
        seg = self.grid.segment(n)
        ctx = run.ctx
        if seg.dt != ctx.dt:  # a new step: its factorization (the old one released, or kept by a control)
            ops = [op for op in (run.scheme.step_operator(ctx, seg.dt),) if op is not None]
            if self.control is not None:
                ctx.use_step(seg.dt, seg.start, ops, self._ladder_bytes)
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

    # -- checkpoints -----------------------------------------------------------------
    def _grid_attrs(self) -> dict[str, Any]:
        """Where the grid goes on from the current level: the segment of the next level and the
        step of the operators factorized now (a checkpoint's ``segment`` and ``dt``), and an adaptive
        control's state (``time_control``): taken before a step works, so that a checkpoint of a
        step interrupted midway (after a rejection) resumes as from the start of the step."""
        n = self.n
        if self.control is not None:  # the segment of the next level (a growth or rejection may have changed it)
            if n < self.grid.n_steps:
                seg = self.grid.segment(n + 1)
                segment = [seg.start, seg.dt, seg.first]
            else:  # at T: the segment a resume to a later T goes on with (grown at T, or the last one)
                seg = self.grid.segment(n)
                segment = self._next_segment or [seg.start, seg.dt, seg.first]
            state = {**self.control.state(), "plan_dt": self.grid.piece(self.t)[2]}  # the largest step (a resume's dt)
            return {"segment": segment, "dt": self.dt, "time_control": state}
        seg = self.grid.segment(max(n, self.grid.segments[0].first + 1))
        segment = [seg.start, seg.dt, seg.first] if seg.dt == self.dt else [float(self.state.t), self.dt, n]
        return {"segment": segment, "dt": self.dt}

    def checkpoint_contents(self) -> dict[str, Any]:
        """Everything the next step needs, at the current level (:mod:`~.checkpoint`)."""
        run, n = self.run, self.n
        arrays, attrs = {}, {}
        state_arrays, flags = ckpt.state_arrays(run, self.state)
        arrays.update({f"state/{k}": v for k, v in state_arrays.items()})
        attrs["state_flags"] = flags
        warm = self._warm_arrays(self._level_warm if self._level_warm is not None else self._warm_starts())
        arrays.update(warm)
        ckpt._flatten("pairing", run.ctx.pairing_state(self.state.t), arrays, attrs)
        series: dict[str, np.ndarray] = {}
        for o in self.observers:
            key = getattr(o, "checkpoint_key", None)
            if key:
                data = dict(o.saved(n))
                series.update({f"{key}/{k}": v for k, v in data.pop("series", {}).items()})
                ckpt._flatten(f"observers/{key}", data, arrays, attrs)
        counters = self._level_counters if self._level_counters is not None else self.counters
        grid_attrs = self._level_grid if self._level_warm is not None else self._grid_attrs()
        attrs.update(grid_attrs)
        attrs.update(level=n, t=float(self.state.t),
                     identity=self._identity, counters=counters,
                     n_solvers=sum(1 for k in warm if k.endswith("/operator")), meta=self._meta,
                     scheme=run.scheme.name, created=time.strftime("%Y-%m-%dT%H:%M:%S"))  # fmt: skip
        return {"arrays": arrays, "attrs": attrs, "series": series}

    def save_checkpoint(self, path: str | Path | None = None) -> Path | None:
        """Write the checkpoint of the current level (to ``path``, else the stepper's own;
        only rank 0 writes on several ranks).  Returns the path written."""
        target = path if path is not None else self._checkpoint
        if target is None:
            raise InputError("save_checkpoint needs a path (the stepper was built without checkpoint=...)")
        contents = self.checkpoint_contents()
        if self.run.ctx.comm.rank != 0:
            return None
        target = Path(target() if callable(target) else target)

        def write() -> int:  # the levels' series appended beside it, then the checkpoint that counts them
            layout, records, digest = self._series.append(ckpt.series_path(target), contents.pop("series"), self.n)
            contents["attrs"]["series"] = {"layout": layout, "records": records, "digest": digest}
            return ckpt.write(target, contents)

        if self.log is not None and path is None:
            self.log.timed(write)
            self.log.level = self.n
            if self._on_checkpoint is not None:
                a = contents["attrs"]
                self._on_checkpoint({"level": a["level"], "t": a["t"], "counters": a["counters"],
                                     "scheme": self.run.scheme.label, "mass": self.run.ctx.disc.mass_name})  # fmt: skip
        else:
            write()
        return target

    def _resume(self, saved: dict[str, Any], where: str) -> None:
        try:
            self._restore(saved, where)
        except InputError:
            raise
        except (TypeError, ValueError, KeyError, IndexError, AttributeError) as exc:  # a forged file, in one line
            raise InputError(f"checkpoint {where!r}: malformed ({type(exc).__name__}: {exc})") from None

    def _restore(self, saved: dict[str, Any], where: str) -> None:
        attrs, run = saved["attrs"], self.run
        ckpt.compare_identity(attrs["identity"], self._identity, f"checkpoint {where!r}")
        n, t = int(attrs["level"]), float(attrs["t"])
        state_arrays = ckpt.unflatten("state", saved)
        self.state = ckpt.restore_state(run, state_arrays, attrs.get("state_flags", {}), t)
        from .context import Operator, Viscous

        current, restored = run.ctx.dt, {}
        for k in range(int(attrs.get("n_solvers", 0)) if run.ctx.comm.size == 1 else 0):
            op = saved["arrays"].get(f"solvers/{k}/operator")
            if op is None or op.shape not in ((2,), (3,)) or not np.all(np.isfinite(op)):
                raise InputError(f"checkpoint {where!r}: solver {k} has no valid operator")
            step = saved["arrays"].get(f"solvers/{k}/dt")
            if self.control is not None and step is not None:  # a step an adaptive control kept: its own systems
                if step.shape != () or not np.isfinite(step) or not step > 0:
                    raise InputError(f"checkpoint {where!r}: solver {k} has no valid step")
                run.ctx.use_step(float(step), run.ctx.t0, [], self._ladder_bytes)
            viscous = None
            if op.shape == (3,):  # damping per region: c C, the third term
                if run.ctx.damping_matrix is None:
                    raise InputError(f"checkpoint {where!r}: solver {k} holds a damping matrix this run does not have")
                viscous = Viscous(float(op[2]), run.ctx.damping_matrix)
            # made now if the loop made it
            sys, _ = run.ctx.factors.system(Operator(float(op[0]), float(op[1]), None, viscous))
            for name in getattr(sys.solver, "warm_state", ()):
                a = saved["arrays"].get(f"solvers/{k}/{name}")
                old = np.asarray(getattr(sys.solver, name))
                if a is None or a.shape != old.shape:
                    raise InputError(f"checkpoint {where!r}: the warm start {name!r} of solver {k} is missing or "
                                     f"has another shape (another backend?)")  # fmt: skip
                setattr(sys.solver, name, a.astype(old.dtype, copy=True))
                restored.setdefault(id(sys), {})[name] = getattr(sys.solver, name).copy()
            prefix = f"solvers/{k}/delassus/"
            log = {name[len(prefix) :]: a for name, a in saved["arrays"].items() if name.startswith(prefix)}
            delassus = getattr(sys.solver, "delassus", None)
            if all(name in log for name in ("nodes", "slots", "sizes")) and hasattr(delassus, "replay"):
                try:
                    delassus.replay(log)
                except ValueError as exc:
                    raise InputError(f"checkpoint {where!r}: solver {k}: {exc}") from None
        if self.control is not None:
            run.ctx.use_step(current, run.ctx.t0, [], self._ladder_bytes)  # back to the checkpoint's step
            for sys in run.ctx.factors.current:  # its warm starts, not those use_step passed from the last restored
                for name, a in restored.get(id(sys), {}).items():
                    setattr(sys.solver, name, a.copy())
            if "time_control" in attrs:
                self.control.restore(dict(attrs["time_control"]))
        run.ctx.restore_pairing(ckpt.unflatten("pairing", saved), t)
        info = attrs.get("series", {})
        series = ckpt.read_series(Path(where), info.get("layout", []), info.get("records", -1), info.get("digest", ""),
                                  f"checkpoint {where!r}")  # fmt: skip
        if any(len(v) != n + 1 for v in series.values()):
            raise InputError(f"checkpoint {where!r}: its series hold {info.get('records')} levels, not {n + 1}")
        times = series.get("history/times")
        run.level_times = None if times is None else np.asarray(times)
        for o in self.observers:  # each with its data; those without a key with none (e.g. to copy files)
            key = getattr(o, "checkpoint_key", None)
            if not hasattr(o, "resume"):
                continue
            data = ckpt.unflatten(f"observers/{key}", saved) if key else {}
            if key:
                data["series"] = {k[len(key) + 1 :]: v for k, v in series.items() if k.startswith(f"{key}/")}
            o.resume(run, n, self.state, data)
        self.n = self._first = n
        self._counters_before = {k: int(v) for k, v in attrs["counters"].items() if k != "steps"}
        self.resumed_from = {"level": n, "t": t, "checkpoint": where, "created": attrs.get("created", "")}

    # -- the end ---------------------------------------------------------------------
    def _close_observers(self) -> None:
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
        # level 0 too: a run interrupted (or failed) before its first step is resumable
        if self.log is not None and self.log.level != self.n:
            try:
                self.save_checkpoint()
            except (OSError, InputError, RuntimeError, ValueError) as exc:  # the levels computed matter more
                self.log.error = f"level {self.n}: {type(exc).__name__}: {exc}"
                self.log.failed += 1
        try:
            self._close_observers()
        finally:
            self._history = self._assemble()
        return self._history

    def _assemble(self) -> History:
        run = self.run
        H = finish_history(run, self.n, self.recorder, self.energies, self.snaps, self.setup_seconds,
                           self._loop_seconds, counters=self.counters, steps=self.n - self._first)  # fmt: skip
        if self.watch is not None:
            H.meta["events"] = self.watch.met
            H.meta["stop_at"] = [e.name for e in getattr(self.watch, "events", []) if e.terminal]
        H.untagged_penetration = self.untagged.series
        # every node watched: against the rigid obstacle and against the surfaces of the pairs
        H.meta["untagged_boundary_nodes"] = self.untagged.watched_nodes()
        H.meta["untagged_worst_penetration"] = self.untagged.worst[0]  # the failing level of untagged_contact=fail too
        if self.untagged.exceeded():
            H.meta["warnings"].append(self.untagged.message())
        if self.energies is not None:
            self._report_energy(H)
        if self.log is not None:
            H.meta["checkpoints"] = self.log.summary()
            if self.log.error:
                last = f"the last written is of level {self.log.level}" if self.log.level >= 0 else "none was written"
                H.meta["warnings"].append(f"{self.log.failed} checkpoint(s) could not be written (the last: "
                                          f"{self.log.error}); {last}")  # fmt: skip
        if self.resumed_from is not None:
            H.meta["resumed_from"] = dict(self.resumed_from)
        if self.control is not None:
            self.control.settle(self.energies.energy_scale)
            H.meta["time_control"] = self.control.summary(int(self.counters.get("factorizations", 0)))
            if self.control.unresolved and self.status != "failed":
                H.meta["warnings"].append(self.control.unresolved_message())
        else:
            steps = [seg.dt for seg in self.grid.segments]
            H.meta["time_control"] = {"control": "fixed", "dt_smallest_used": min(steps), "dt_largest_used": max(steps),
                                      "steps_accepted": self.n - self._first, "steps_rejected": 0}  # fmt: skip
        steps = schedule_of(H.t)
        if len(steps) > 1:
            H.meta["dt_schedule"] = steps
        H.meta["T"] = float(self.grid.T)
        H.status, H.message = self.status, self.message
        return H


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
        raise InputError(f"checkpoint {where!r} is at t = {t:.10g}, at or after this run's T = {grid.T:.10g}; give a "
                         "later T")  # fmt: skip
    _, _, dt_piece = grid.piece(t)
    k = np.log2(dt_piece / step)
    if not (0 <= round(k) <= 64 and abs(k - round(k)) < 1e-9):
        raise InputError(f"checkpoint {where!r}: its step {step:g} is not dt / 2^k of this run's dt {dt_piece:g}; "
                         "resume with the run's own dt")  # fmt: skip
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
