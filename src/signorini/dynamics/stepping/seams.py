"""What the step control and the checkpointer may see of the stepper: two small interfaces, named.

:class:`~.step_control.AdaptiveSteps` and :class:`~.checkpointer.Checkpointer` are given the
:class:`~.stepper.Stepper` but are typed, and tested (tests/dynamics/stepping/test_seams.py: every attribute
they read of it is a member here), against these protocols only.  What each may change is said per member:
the control refines the grid (``TimeGrid.continue_with``) and puts back what a rejected trial changed
(``step_parts``); the checkpointer's state part sets ``state`` on resume.  Neither writes anything else into
the stepper: the levels' count an observer's progress line shows follows the grid in the stepper itself.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from ..observe.events import EventWatch
    from ..observe.observers import EnergyRecorder, Observer, Run
    from ..restart.protocol import Pairing, SolverStates, StepParts
    from ..schemes.base import State
    from .step_control import AdaptiveSteps
    from .time_grid import TimeGrid


class ControlledStepper(Protocol):
    """What :class:`~.step_control.AdaptiveSteps` reads of the stepper (it changes the grid and, through
    ``step_parts``, puts back a rejected trial's changes)."""

    #: the current level, its time and the step of the systems factorized now [s]
    n: int
    t: float
    dt: float
    #: the current level's state (read: the force before the step)
    state: State
    #: the observers' view of the run (the scheme, the context), the grid the control refines
    run: Run
    grid: TimeGrid
    #: the energy recorder (its indicator judges a trial), the terminal events' watch (None: none)
    energies: EnergyRecorder | None
    watch: EventWatch | None
    #: the parts a trial changes: marked before it, rolled back after a rejection, released after acceptance
    step_parts: StepParts

    def use_segment(self, n: int) -> None:
        """The systems of level n's step made current."""

    def trial(self, n: int) -> tuple[State | None, str]:
        """Level n computed, not accepted."""


class CheckpointedStepper(Protocol):
    """What :class:`~.checkpointer.Checkpointer` reads of the stepper (``state`` is set by the state part on
    resume; nothing else is written)."""

    n: int
    n_steps: int
    dt: float
    state: State
    run: Run
    grid: TimeGrid
    #: the energy control (None: fixed steps): its grid attributes and its state in the header
    adaptive: AdaptiveSteps | None
    observers: Sequence[Observer]
    #: the restartable parts the stepper owns (the rollback walks them too)
    solvers: SolverStates
    pairing: Pairing

    @property
    def counters(self) -> dict[str, Any]:
        """The run's counters so far."""
