"""The options of a run, declared once: :class:`RunOptions` and its :class:`CheckpointPolicy`.

:class:`~.stepper.Stepper` takes a problem, a scheme, a time grid ``(dt, T)`` and one
:class:`RunOptions`; :func:`~.simulate.simulate` builds that object from its keywords.  A
mapping of the same names is accepted wherever a :class:`RunOptions` is
(:meth:`RunOptions.of`): an unknown name is an :class:`~signorini.errors.InputError` that
lists the allowed ones.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ...errors import InputError
from ..model.mass import DEFAULT_MASS


def _check_every(every: Any) -> None:
    if not isinstance(every, int) or isinstance(every, bool) or every < 0:
        raise InputError(f"checkpoint_every must be a non-negative integer, got {every!r}")


@dataclass(frozen=True)
class CheckpointPolicy:
    """When and where a run writes its checkpoint (:mod:`~.checkpoint`).

    Parameters
    ----------
    path : the checkpoint file, or a function returning it (called at the first write: a
        result directory made only when needed).
    every : write it every K levels; 0: only when the run ends (finished, interrupted or
        failed: the last level computed is always written).
    meta : JSON-able data stored with every checkpoint (the command line keeps there how to
        rebuild the run).
    on_checkpoint : called with ``{level, t, counters, scheme, mass}`` after each checkpoint
        is complete (the command line tells its watchdog).
    """

    path: str | Path | Callable[[], Path]
    every: int = 0
    meta: Mapping[str, Any] | None = field(default_factory=dict)
    on_checkpoint: Callable[[dict[str, Any]], None] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.path, (str, Path)) and not callable(self.path):
            raise InputError(
                f"the checkpoint's path must be a path or a function returning one, got {type(self.path).__name__}"
            )
        _check_every(self.every)
        if self.meta is None:
            object.__setattr__(self, "meta", {})
        if not isinstance(self.meta, Mapping):
            raise InputError(f"checkpoint_meta must be a mapping (JSON-able), got {type(self.meta).__name__}")
        if self.on_checkpoint is not None and not callable(self.on_checkpoint):
            raise InputError(f"on_checkpoint must be a function, got {type(self.on_checkpoint).__name__}")

    @classmethod
    def of(
        cls,
        path: str | Path | Callable[[], Path] | None,
        every: int = 0,
        meta: Mapping[str, Any] | None = None,
        on_checkpoint: Callable[[dict[str, Any]], None] | None = None,
    ) -> CheckpointPolicy | None:
        """The policy of :func:`~.simulate.simulate`'s keywords (None: no checkpoint)."""
        _check_every(every)
        if path is None:
            if every:
                raise InputError("checkpoint_every needs a checkpoint path (checkpoint=...)")
            return None
        return cls(path, every, meta, on_checkpoint)


@dataclass(frozen=True)
class RunOptions:
    """Everything of a run but its problem, scheme and time grid.

    Parameters
    ----------
    mass : the mass variant (:data:`~.mass.MASS_VARIANTS`; ignored for a Discretization).
    snapshot_every : keep full fields in memory every k levels and at the last (0: never).
    backend, memory_budget : shortcuts for ``solver_options['backend']`` and
        ``solver_options['memory_budget']`` [bytes].
    progress : callback(step, n_steps) after every step.
    scheme_options : the scheme's parameters, e.g. ``{"beta": 0.3, "gamma": 0.6}``.
    solver_options : see :data:`signorini.linalg.SOLVER_OPTIONS`.
    observers : extra :class:`~.observers.Observer` objects.
    energy : record the scheme's energy and check its identity at every level.
    events : :class:`~.events.Event` objects or built-in event names (:mod:`~.events`).
    control : the time-step control: ``"fixed"``/None, ``"energy"`` or a table
        (:mod:`~.step_control`).
    case_hash : the hash of the case file the problem was read from (part of the run's identity:
        a checkpoint of another case file is refused on resume).
    checkpoint : a :class:`CheckpointPolicy`, or a path (the policy that writes it when the run
        ends), or None (no checkpoint).
    """

    mass: str = DEFAULT_MASS
    snapshot_every: int = 0
    backend: str | None = None
    memory_budget: float | None = None
    progress: Callable[[int, int], None] | None = None
    scheme_options: Mapping[str, Any] | None = None
    solver_options: Mapping[str, Any] | None = None
    observers: Iterable[Any] = ()
    energy: bool = True
    events: Iterable[Any] = ()
    control: str | Mapping[str, Any] | None = None
    checkpoint: CheckpointPolicy | str | Path | None = None
    case_hash: str | None = None

    def __post_init__(self) -> None:
        c = self.checkpoint
        if isinstance(c, (str, Path)):  # a path: written when the run ends (CheckpointPolicy(path, every=K) for more)
            object.__setattr__(self, "checkpoint", CheckpointPolicy(c))
        elif c is not None and not isinstance(c, CheckpointPolicy):
            raise InputError(
                f"the run option 'checkpoint' must be a CheckpointPolicy or a path, got {type(c).__name__}"
            )

    @classmethod
    def of(cls, options: RunOptions | Mapping[str, Any] | None) -> RunOptions:
        """``options`` as a RunOptions (a mapping of its field names; None: the defaults)."""
        if options is None:
            return cls()
        if isinstance(options, cls):
            return options
        if not isinstance(options, Mapping):
            raise InputError(f"the run's options must be a RunOptions or a mapping, got {type(options).__name__}")
        names = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(map(repr, set(options) - set(names)))
        if unknown:
            raise InputError(f"unknown run option(s) {', '.join(unknown)}; allowed: {', '.join(names)}")
        return cls(**options)
