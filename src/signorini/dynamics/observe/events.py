"""Events of a run: functions of (t, state) watched after every level, as solve_ivp's.

An :class:`Event` has a function g(t, state) -> float, ``terminal`` and ``direction``: it
occurs at the first level where g changes sign from the previous level (g_{n-1} g_n < 0, or
g_n = 0 after a nonzero g_{n-1}) in the given direction (+1: rising, -1: falling, 0:
either).  Its time is that level's t_n (the event lies in (t_{n-1}, t_n]: within one step).
A terminal event ends the run after that level with status ``finished``; every event met
is listed in ``summary.json`` ``events`` (name, t, level, terminal).

Built-in events (:data:`EVENTS`, by name on the command line ``--stop-at NAME`` and in the
case file ``[time] stop_at = "NAME"``, each then terminal):

``first-contact``  the first level with a contact force (some lambda_i < 0);
``separation``     every contact node free again (no lambda_i < 0) after a contact;
``rest``           the kinetic energy 1/2 V.MV below a fraction of its largest value so far
                   (``rest:0.001``; default 0.01; the largest includes t = 0: a body
                   released from rest comes to rest when its motion has died down).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import InputError
from ...registry import Parameter, Registry
from ..schemes import State
from .observers import Observer, Run


@dataclass
class Event:
    """g(t, state) watched after every level (module docstring)."""

    name: str
    function: Callable[[float, State], float]
    terminal: bool = False
    direction: float = 0.0


class StopRun(Exception):
    """Raised by a terminal event after its level: the loop ends the run as finished."""


def _first_contact(run: Run, _: dict) -> Callable[[float, State], float]:
    return lambda t, s: -1.0 if s.lam.size and np.any(s.lam < 0) else 1.0


def _separation(run: Run, _: dict) -> Callable[[float, State], float]:
    return lambda t, s: 1.0 if s.lam.size and np.any(s.lam < 0) else -1.0


def _rest(run: Run, options: dict) -> Callable[[float, State], float]:
    frac = options["fraction"]
    M = run.ctx.M
    peak = [0.0]

    def g(t: float, s: State) -> float:
        kinetic = 0.5 * float(s.V @ (M @ s.V))
        peak[0] = max(peak[0], kinetic)
        # positive while moving; 0 before any motion (no crossing from rest at t = 0)
        return kinetic - frac * peak[0] if peak[0] > 0 else 0.0

    g.memory = peak  # what a checkpoint keeps of it (EventWatch.saved)
    return g


#: built-in events: factories (run, options) -> g(t, state), with the direction of the crossing
EVENTS = Registry("event")
EVENTS.register("first-contact", (_first_contact, -1.0), "the first level with a contact force (some lambda_i < 0)")
EVENTS.register("separation", (_separation, -1.0), "every contact node free again (no lambda_i < 0) after a contact")
EVENTS.register(
    "rest",
    (_rest, -1.0),
    "the kinetic energy 1/2 V.MV below a fraction of its largest value so far (rest:FRACTION)",
    parameters=(Parameter("fraction", 0.01, "fraction of the initial kinetic energy", float, 0.0, 1.0),),
)


def events_list(events: Any) -> list:
    """``simulate``'s ``events`` as a list: one name (``"separation"``, or comma-separated
    names) or one :class:`Event` is a list of one, not a sequence of characters."""
    if events is None:
        return []
    if isinstance(events, str):
        return parse_stop_at(events, "events")
    if isinstance(events, Event):
        return [events]
    try:
        out = list(events)
    except TypeError:
        raise InputError(
            f"events must be event names, Event objects or a list of them, got {type(events).__name__}"
        ) from None
    for e in out:
        if not isinstance(e, (str, Event)):
            raise InputError(
                f"events: {e!r} is neither an event name ({', '.join(EVENTS.names(aliases=False))}) nor an Event"
            )
    return out


def parse_stop_at(spec: str | Sequence[str] | None, where: str = "--stop-at") -> list[str]:
    """Names (with options) of built-in events, validated: ``"separation"``, ``"rest:0.001"``,
    a comma-separated string or a list; an InputError naming ``where`` and the allowed names."""
    if spec is None:
        return []
    if not isinstance(spec, (str, list, tuple)):
        raise InputError(
            f"{where} must be an event name or a list of them ({', '.join(EVENTS.names(aliases=False))}), got {spec!r}"
        )
    items = [x.strip() for x in spec.split(",")] if isinstance(spec, str) else list(spec)
    out = []
    for item in items:
        if not isinstance(item, str) or not item:
            raise InputError(
                f"{where}: an event name is a non-empty string, got {item!r}; allowed: "
                f"{', '.join(EVENTS.names(aliases=False))}"
            )
        name, _, value = item.partition(":")
        try:
            entry = EVENTS.get(name)
        except InputError:
            raise InputError(
                f"{where}: unknown event {name!r}; allowed: {', '.join(EVENTS.names(aliases=False))} (rest:FRACTION)"
            ) from None
        if value:
            if not entry.parameters:
                raise InputError(f"{where}: event {entry.name!r} takes no value, got {item!r}")
            entry.parameters[0].convert(value, f"{where} {entry.name}")
        out.append(f"{entry.name}:{value}" if value else entry.name)
    return out


def builtin_event(spec: str, run: Run) -> Event:
    """The terminal :class:`Event` of a built-in name (``rest:0.001``)."""
    name, _, value = spec.partition(":")
    entry = EVENTS.get(name)
    options = {p.name: p.default for p in entry.parameters}
    if value:
        options[entry.parameters[0].name] = entry.parameters[0].convert(value, name)
    factory, direction = entry.obj
    return Event(spec, factory(run, options), terminal=True, direction=direction)


class EventWatch(Observer):
    """Evaluates the events after every level (the last observer: the level is recorded first)."""

    def __init__(self, events: Sequence[Event | str]):
        self.specs = list(events)
        self.met: list[dict] = []

    def start(self, run: Run) -> None:
        self.events = [e if isinstance(e, Event) else builtin_event(e, run) for e in self.specs]
        self.previous = [float(e.function(run.initial.t, run.initial)) for e in self.events]
        self.done = [False] * len(self.events)

    checkpoint_key = "events"

    def saved(self, n: int) -> dict:
        memory = [list(getattr(e.function, "memory", [])) for e in self.events]
        return {
            "previous": list(self.previous),
            "done": [int(x) for x in self.done],
            "memory": memory,
            "met": [dict(m) for m in self.met],
            "names": [e.name for e in self.events],
        }

    def resume(self, run: Run, n: int, state: State, data: dict) -> None:
        names = [e.name for e in self.events]
        if list(data["names"]) != names:  # another set of events: they start afresh from this level
            self.previous = [float(e.function(state.t, state)) for e in self.events]
            self.met = [dict(m) for m in data["met"]]
            return
        self.previous = [float(x) for x in data["previous"]]
        self.done = [bool(x) for x in data["done"]]
        self.met = [dict(m) for m in data["met"]]
        for e, mem in zip(self.events, data["memory"], strict=True):
            if hasattr(e.function, "memory"):
                e.function.memory[:] = [float(x) for x in mem]

    def would_stop(self, state: State) -> bool:
        """Whether a terminal event not met yet would end the run at ``state`` (nothing changed:
        the events' memories are put back), for a step control that locates it."""
        for k, e in enumerate(self.events):
            if not e.terminal or self.done[k]:
                continue
            memory = list(getattr(e.function, "memory", []))
            g0, g1 = self.previous[k], float(e.function(state.t, state))
            if memory:
                e.function.memory[:] = memory
            if (g0 * g1 < 0 or (g1 == 0 and g0 != 0)) and (e.direction == 0 or (g1 - g0) * e.direction > 0):
                return True
        return False

    def record(self, run: Run, n: int, state: State) -> None:
        stop = None
        for k, e in enumerate(self.events):
            g0, g1 = self.previous[k], float(e.function(state.t, state))
            self.previous[k] = g1
            crossed = (g0 * g1 < 0 or (g1 == 0 and g0 != 0)) and (e.direction == 0 or (g1 - g0) * e.direction > 0)
            if crossed and not self.done[k]:
                self.done[k] = e.name in ("first-contact",)  # the first contact happens once
                self.met.append({"name": e.name, "t": float(state.t), "level": int(n), "terminal": bool(e.terminal)})
                if e.terminal and stop is None:
                    stop = e
        if stop is not None:
            raise StopRun(f"stopped at event {stop.name} (t = {state.t:.6g}, level {n})")
