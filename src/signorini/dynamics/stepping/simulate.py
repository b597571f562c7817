"""The time loop: ``simulate(problem, scheme, dt, T, mass=...) -> History``.

:func:`simulate` builds a :class:`~.stepper.Stepper` (set-up: :mod:`~.setup`) and steps it
to the final time, turning SIGINT and SIGTERM into a stop after the step in progress (and,
on several ranks, agreeing on it).  Every exit returns a :class:`~.history.History` with a
status:

``finished``     the final time was reached, or a terminal event occurred;
``interrupted``  SIGINT (Ctrl-C) or SIGTERM arrived: the loop stops after the step in
                 progress (a second Ctrl-C aborts that step);
``failed``       a non-finite value appeared in the state, or a solver did not
                 converge; the message names the step and the time.

The levels computed before the stop are kept; observers are closed in every case.  With
checkpoints on, a run that ends early can be continued (``resume=``): interruption is a
pause.
"""

from __future__ import annotations

import signal
from collections.abc import Callable, Iterable, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ...linalg.threads import blas_threads
from ...parallel import agree_deferred
from ...signals import handled, interrupts_must_raise
from ..model.mass import DEFAULT_MASS
from ..model.problem import Discretization, Problem
from ..observe.history import History
from ..observe.observers import Observer
from ..schemes import Scheme
from .run_options import CheckpointPolicy, RunOptions
from .setup import (  # noqa: F401 - the names users and older code import from here
    MAX_CONTACT_RESIDUAL,
    check_history_fits,
    initial_state,
    number_of_steps,
    set_up,
)
from .stepper import STATUSES, Stepper, check_problem_and_grid  # noqa: F401 - exported where users find simulate


class _Interrupts:
    """SIGINT/SIGTERM set a flag (the loop stops after the step); a second SIGINT raises."""

    def __init__(self) -> None:
        self.signal_name: str | None = None
        self.signum = 0
        #: a second SIGINT aborts the step in progress; never on several ranks, where one rank
        #: leaving a collective solve would leave the others waiting in it
        self.abort_on_second = True
        #: a step is in progress (only a step can be aborted: between steps, in the observers
        #: and while the history is assembled a second SIGINT must not lose the levels computed)
        self.in_step = False

    def handler(self, signum, frame) -> None:
        if self.signal_name is not None and signum == signal.SIGINT and self.abort_on_second and self.in_step:
            raise KeyboardInterrupt
        self.signal_name = signal.Signals(signum).name
        self.signum = int(signum)

    def agree(self, comm) -> str | None:
        """The signal to stop for (None: go on).  On several ranks: every rank stops when a
        signal reached any of them (one reduction per step), with the name of the highest
        signal number received; the decision is the reduction's, never this rank's flag (its
        handler may set it after the reduction: this rank alone would stop, the others wait)."""
        if comm.size == 1:
            return self.signal_name
        signum = comm.max(self.signum)
        if signum and not self.signum:
            self.signum, self.signal_name = signum, signal.Signals(signum).name
        return signal.Signals(signum).name if signum else None


@contextmanager
def _catch_signals(enabled: bool):
    flag = _Interrupts()
    with handled(flag.handler, enabled):
        yield flag


def simulate(
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
    observers: Iterable[Observer] = (),
    energy: bool = True,
    handle_signals: bool = True,
    events: Iterable[Any] = (),
    checkpoint: str | Path | Callable[[], Path] | None = None,
    checkpoint_every: int = 0,
    checkpoint_meta: Mapping[str, Any] | None = None,
    case_hash: str | None = None,
    resume: str | Path | None = None,
    on_checkpoint: Callable[[dict], None] | None = None,
    control: str | Mapping[str, Any] | None = None,
) -> History:
    """Integrate ``problem`` in time with exact nodal contact at every step.

    Parameters
    ----------
    problem : a :class:`Problem` or an already assembled :class:`Discretization`.
    scheme : a name or alias of :data:`~signorini.dynamics.schemes.SCHEMES`
        (``crank-nicolson``/``cn``, ``backward-euler``/``be``, ``newmark``, ``theta``,
        ``paoli-schatzman``/``ps``), a :class:`Scheme` subclass, or an instance.
    dt, T : time step and final time [s]; N = T/dt steps (T must be >= dt).
    mass : mass variant (ignored when a Discretization is given).
    snapshot_every : keep full displacement/velocity fields in memory every k steps
        and at the last level (0 = never); for large runs stream them with
        :class:`signorini.io.output.FieldWriter` instead.
    backend, memory_budget : shortcuts for ``solver_options['backend']`` and
        ``solver_options['memory_budget']`` [bytes].
    progress : callback(step, n_steps) called after every step.
    scheme_options : the scheme's parameters, e.g. ``{"beta": 0.3, "gamma": 0.6}``.
    solver_options : backend, preconditioner, rtol, max_iter, max_newton, memory_budget,
        lcp_max_iter, condense_budget (see :data:`signorini.linalg.SOLVER_OPTIONS`).
    observers : extra :class:`~.observers.Observer` objects (e.g. a field writer).
    energy : record the scheme's energy and its identity (a few products per step).
    handle_signals : turn SIGINT/SIGTERM into ``status = "interrupted"``.
    events : :class:`~.events.Event` s (a function g(t, state), ``terminal``, ``direction``) or
        names of built-in events (``"separation"``, ``"first-contact"``, ``"rest:0.01"``: each
        terminal) watched after every level (:mod:`~.events`); a terminal one ends the run
        after its level, status ``finished``; ``meta['events']`` lists every event met.
    checkpoint, checkpoint_every : write a checkpoint (:mod:`~.checkpoint`) to this path every
        K levels (0: only when the run ends early: interrupted or failed); ``meta['checkpoints']``
        counts them.  ``checkpoint_meta`` and ``case_hash``: see :class:`~.stepper.Stepper`.
    resume : a checkpoint to continue from: the same problem, scheme, mass and dt (checked;
        a mismatch is an InputError naming what differs); the History holds every level
        from t = 0, ``meta['resumed_from']`` says where it resumed.
    control : the time-step control (:mod:`~.step_control`): ``"fixed"`` (None, the default
        here: the steps asked for) or ``"energy"`` (dt as the largest step; steps rejected and
        halved where the energy identity shows energy no physical work explains, down to
        dt_min), or ``{"control": "energy", "tolerance": ..., "dt_min": ..., "grow_after": 4}`` (the
        tolerance made from the mesh when absent or 0: min(1e-3, 0.025 (h/L)^2)); ``meta['time_control']``
        says what ran.

    Returns
    -------
    History with ``status``, ``message``, ``counters`` and the levels computed.
    """
    check_problem_and_grid(problem, (dt, T), resume)  # these first, as the stepper would
    policy = CheckpointPolicy.of(checkpoint, checkpoint_every, checkpoint_meta, on_checkpoint)
    options = RunOptions(mass, snapshot_every, backend, memory_budget, progress, scheme_options, solver_options,
                         observers, energy, events, control, policy, case_hash)  # fmt: skip
    if resume is None:
        stepper = Stepper(problem, scheme, (dt, T), options)
    else:
        stepper = Stepper.resume(resume, problem, scheme, (dt, T), options)
    comm = stepper.run.ctx.comm
    with _catch_signals(handle_signals) as interrupts:
        interrupts.abort_on_second = comm.size == 1
        try:
            agree_deferred(comm)  # several ranks: a signal of the set-up stops every rank here
        except KeyboardInterrupt:
            stepper.status = "interrupted"
            stepper.close_observers()
            raise
        try:
            with blas_threads(stepper.threads):
                stepper.in_loop = True
                while stepper.status == "running":
                    name = interrupts.agree(comm)
                    if name:
                        stepper.interrupt(f"{name} after step {stepper.n} of {stepper.n_steps}")
                        break
                    try:
                        interrupts.in_step = True
                        stepper.step()
                    except KeyboardInterrupt:
                        stepper.interrupt(f"SIGINT during step {stepper.n + 1} of {stepper.n_steps}")
                    finally:
                        interrupts.in_step = False
        finally:
            stepper.in_loop = False
            H = stepper.finish()  # observers closed on every exit
        name = interrupts.agree(comm)
        if name and H.status == "finished":  # after the last step: every step kept
            H.status = "interrupted"
            H.message = f"{name} after the time loop (all {stepper.n} steps kept)"
    if H.status == "interrupted" and interrupts_must_raise():  # a study of many runs: not a truncated one
        raise KeyboardInterrupt(H.message)
    return H
