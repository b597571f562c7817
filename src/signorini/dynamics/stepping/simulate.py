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

import dataclasses
import signal
from collections.abc import Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ...errors import InputError
from ...linalg.threads import blas_threads
from ...parallel import agree_deferred
from ...signals import handled, interrupts_must_raise
from ..model.problem import Discretization, Problem
from ..observe.history import History
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


#: simulate's keywords of the checkpoint policy (the rest of its keywords are RunOptions' fields)
POLICY_KEYWORDS = ("checkpoint", "checkpoint_every", "checkpoint_meta", "on_checkpoint")


def run_options(options: RunOptions | Mapping[str, Any] | None, keywords: Mapping[str, Any]) -> RunOptions:
    """:func:`simulate`'s options: ``options``, or its keywords (:class:`RunOptions`' fields and
    :data:`POLICY_KEYWORDS`); an InputError for both, or for a name that is neither."""
    if options is not None:
        if keywords:
            raise InputError(
                f"simulate takes its run options either as options=... or as keywords, not both "
                f"(got options and {', '.join(sorted(keywords))})"
            )
        return RunOptions.of(options)
    fields = [f.name for f in dataclasses.fields(RunOptions) if f.name != "checkpoint"]
    unknown = sorted(set(keywords) - set(fields) - set(POLICY_KEYWORDS))
    if unknown:
        allowed = ", ".join([*fields, *POLICY_KEYWORDS, "options", "resume", "handle_signals"])
        raise InputError(f"simulate: unknown keyword(s) {', '.join(map(repr, unknown))}; allowed: {allowed}")
    policy = CheckpointPolicy.of(
        keywords.get("checkpoint"),
        keywords.get("checkpoint_every", 0),
        keywords.get("checkpoint_meta"),
        keywords.get("on_checkpoint"),
    )
    return RunOptions(**{k: v for k, v in keywords.items() if k in fields}, checkpoint=policy)


def simulate(
    problem: Problem | Discretization,
    scheme: str | type[Scheme] | Scheme = "crank-nicolson",
    dt: float = 0.01,
    T: float = 1.0,
    *,
    options: RunOptions | Mapping[str, Any] | None = None,
    resume: str | Path | None = None,
    handle_signals: bool = True,
    **keywords: Any,
) -> History:
    """Integrate ``problem`` in time with exact nodal contact at every step.

    Parameters
    ----------
    problem : a :class:`Problem` or an already assembled :class:`Discretization`.
    scheme : a name or alias of :data:`~signorini.dynamics.schemes.SCHEMES`
        (``crank-nicolson``/``cn``, ``backward-euler``/``be``, ``newmark``, ``theta``,
        ``paoli-schatzman``/``ps``), a :class:`Scheme` subclass, or an instance.
    dt, T : time step and final time [s]; N = T/dt steps (T must be >= dt).
    options : the run's options, a :class:`~.run_options.RunOptions` (or a mapping of its field names);
        or give them as keywords (not both):
    mass, snapshot_every, backend, memory_budget, progress, scheme_options, solver_options, observers,
        energy, events, control, case_hash : :class:`~.run_options.RunOptions`'s fields, keyword-only
        (``mass``: the mass variant, ignored when a Discretization is given; ``snapshot_every``: keep full
        fields in memory every k steps and at the last level, 0 = never; ``progress``: callback(step,
        n_steps); ``energy``: record the energy and its identity; ``events``: :class:`~.events.Event` s or
        built-in event names, ``"separation"``, ``"first-contact"``, ``"rest:0.01"``, each terminal;
        ``control``: ``"fixed"`` (None, the default here), ``"energy"`` (dt as the largest step; steps
        rejected and halved where the energy identity shows energy no physical work explains, down to
        dt_min) or ``{"control": "energy", "tolerance": ..., "dt_min": ..., "grow_after": 4}``;
        ``meta['time_control']`` says what ran).
    checkpoint, checkpoint_every, checkpoint_meta, on_checkpoint : keywords of the checkpoint policy
        (:class:`~.run_options.CheckpointPolicy`): write a checkpoint (:mod:`~.checkpoint`) to this path every
        K levels (0: only when the run ends); ``meta['checkpoints']`` counts them.
    resume : a checkpoint to continue from: the same problem, scheme, mass and dt (checked;
        a mismatch is an InputError naming what differs); the History holds every level
        from t = 0, ``meta['resumed_from']`` says where it resumed.
    handle_signals : turn SIGINT/SIGTERM into ``status = "interrupted"``.

    An unknown keyword is an :class:`~signorini.errors.InputError` listing the allowed ones.

    Returns
    -------
    History with ``status``, ``message``, ``counters`` and the levels computed.
    """
    check_problem_and_grid(problem, (dt, T), resume)  # these first, as the stepper would
    options = run_options(options, keywords)
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
