"""Registries: the single source of the names users can type.

Every pluggable family (time schemes, mass variants, obstacles, linear-algebra
backends, preconditioners, benchmarks) is a :class:`Registry` of :class:`Entry`
objects.  An entry carries its name, aliases, a one-line description and its
parameters with defaults and validators.  The command line (choices and help texts),
the case-file validator, the documentation tables (:func:`Registry.markdown_table`)
and the test parametrizations all read the registries, so adding an entry is the
only step needed to expose a new scheme, mass, obstacle or backend everywhere.

An unknown name or parameter is an :class:`~signorini.errors.InputError` that lists
the allowed ones; nothing falls through to a default.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from .errors import InputError

_MISSING = object()


class Vector(list):
    """Parameter kind: a constant vector (one number per space dimension)."""


class Motion(list):
    """Parameter kind: a vector that may be a function of t (a prescribed motion)."""


class RotationTable(dict):
    """Parameter kind: a rotation ``{ angle = a(t), axis = [...], center = [...] }`` (an inline
    table whose keys are listed by its consumer, e.g. :data:`signorini.contact.obstacles.ROTATION_KEYS`)."""


class FilePath(str):
    """Parameter kind: a file name (relative to the case file in case files)."""


@dataclass(frozen=True)
class Parameter:
    """A named option of a registry entry.

    ``kind`` is ``float``, ``int``, ``bool`` or ``str``; values given as strings (from
    the command line) are converted.  ``low``/``high`` bound numbers (inclusive unless
    ``open_low``/``open_high``); ``choices`` restricts strings.
    """

    name: str
    default: Any
    doc: str
    kind: type = float
    low: float | None = None
    high: float | None = None
    open_low: bool = False
    open_high: bool = False
    choices: tuple[str, ...] | None = None

    def bounds_text(self) -> str:
        if self.choices:
            return " | ".join(self.choices)
        lo = "" if self.low is None else f"{self.low} {'<' if self.open_low else '<='} "
        hi = "" if self.high is None else f" {'<' if self.open_high else '<='} {self.high}"
        if lo or hi:
            return f"{lo}{self.name}{hi}"
        kinds = {Vector: "vector", Motion: "vector or vector(t)", RotationTable: "table", FilePath: "path"}
        return kinds.get(self.kind, self.kind.__name__)

    def convert(self, value: Any, where: str) -> Any:
        """Return ``value`` converted to ``kind`` and checked, or raise naming ``where``."""
        key = f"{where}.{self.name}" if where else self.name
        if self.kind not in (bool, str, int, float):
            return value  # structured values (vectors, expressions) are checked by their consumer
        if self.kind is bool:
            if isinstance(value, bool):
                return value
            text = str(value).strip().lower()
            if text in ("1", "true", "yes", "on"):
                return True
            if text in ("0", "false", "no", "off"):
                return False
            raise InputError(f"'{key}' must be true or false, got {value!r}")
        if self.kind is str:
            if not isinstance(value, str):
                raise InputError(f"'{key}' must be a string, got {value!r}")
            if self.choices and value not in self.choices:
                raise InputError(f"unknown {key} {value!r}; allowed: {', '.join(self.choices)}")
            return value
        if isinstance(value, bool):
            raise InputError(f"'{key}' must be a number, got {value!r}")
        try:
            v = self.kind(float(value)) if self.kind is int and isinstance(value, str) else self.kind(value)
            integral = self.kind is not int or float(value) == v
        except (TypeError, ValueError):
            what = "an integer" if self.kind is int else "a number"
            raise InputError(f"'{key}' must be {what}, got {value!r}") from None
        except OverflowError:  # an integer beyond double precision (TOML has them)
            digits = len(str(abs(int(value)))) if isinstance(value, int) else None
            got = f"an integer of {digits} digits" if digits else repr(value)
            raise InputError(f"'{key}' must be a finite number (|x| < 1.8e308), got {got}") from None
        if not integral:
            raise InputError(f"'{key}' must be an integer, got {value!r}")
        if isinstance(v, float) and not math.isfinite(v):
            raise InputError(f"'{key}' must be finite, got {value!r}")
        bad_low = self.low is not None and (v <= self.low if self.open_low else v < self.low)
        bad_high = self.high is not None and (v >= self.high if self.open_high else v > self.high)
        if bad_low or bad_high:
            raise InputError(f"'{key}' must satisfy {self.bounds_text()}, got {value!r}")
        return v


@dataclass(frozen=True)
class Entry:
    """One registered name: the object it stands for and how to describe it."""

    name: str
    obj: Any
    description: str
    aliases: tuple[str, ...] = ()
    parameters: tuple[Parameter, ...] = ()
    #: what the entry supports, read by the choices and refusals that concern it (e.g. a
    #: backend's :class:`~signorini.linalg.base.BackendTraits`); None when the kind has none
    traits: Any = None

    def parameter(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        allowed = ", ".join(p.name for p in self.parameters) or "none"
        raise InputError(f"unknown option {name!r} for {self.name!r}; allowed: {allowed}")

    def options(self, given: Mapping[str, Any] | None = None, where: str = "") -> dict[str, Any]:
        """Defaults updated with ``given``, every value validated."""
        out = {p.name: p.default for p in self.parameters}
        for k, v in (given or {}).items():
            out[k] = self.parameter(k).convert(v, where or self.name)
        return out


@dataclass
class Registry:
    """Named entries of one kind (``kind`` is used in error messages, e.g. ``scheme``)."""

    kind: str
    entries: dict[str, Entry] = field(default_factory=dict)

    def register(
        self,
        name: str,
        obj: Any = _MISSING,
        description: str = "",
        aliases: tuple[str, ...] = (),
        parameters: tuple[Parameter, ...] = (),
        traits: Any = None,
    ) -> Any:
        """Register ``obj`` under ``name``; usable as a decorator when ``obj`` is omitted."""

        def add(o: Any) -> Any:
            taken = set(self.entries) | {a for e in self.entries.values() for a in e.aliases}
            for key in (name, *aliases):
                if key in taken:
                    raise ValueError(f"{self.kind} name {key!r} is already registered")
            self.entries[name] = Entry(name, o, description, tuple(aliases), tuple(parameters), traits)
            return o

        return add if obj is _MISSING else add(obj)

    def unregister(self, name: str) -> None:
        self.entries.pop(name, None)

    def resolve(self, name: str) -> str:
        """Canonical name of ``name`` or of an alias (case-insensitive)."""
        key = str(name).strip().lower()
        for e in self.entries.values():
            if key == e.name or key in e.aliases:
                return e.name
        raise InputError(f"unknown {self.kind} {name!r}; allowed: {', '.join(self.names())}")

    def get(self, name: str) -> Entry:
        return self.entries[self.resolve(name)]

    def __contains__(self, name: object) -> bool:
        try:
            self.resolve(str(name))
        except InputError:
            return False
        return True

    def __iter__(self) -> Iterator[Entry]:
        return iter(list(self.entries.values()))

    def names(self, aliases: bool = True) -> list[str]:
        """Canonical names (and aliases), in registration order."""
        out = []
        for e in self.entries.values():
            out.append(e.name)
            if aliases:
                out.extend(e.aliases)
        return out

    def help_text(self) -> str:
        """One line per entry for ``--help``: ``name (alias): description [params]``."""
        parts = []
        for e in self.entries.values():
            alias = f" ({', '.join(e.aliases)})" if e.aliases else ""
            opts = f" [{', '.join(f'{p.name}={p.default}' for p in e.parameters)}]" if e.parameters else ""
            parts.append(f"{e.name}{alias}{opts}")
        return ", ".join(parts)

    def markdown_table(self) -> str:
        """The documentation table of this registry (generated, never edited by hand)."""
        lines = ["| name | aliases | options (default) | description |", "|---|---|---|---|"]
        for e in self.entries.values():
            opts = "; ".join(f"`{p.name}` = {p.default} ({p.bounds_text()}): {p.doc}" for p in e.parameters)
            lines.append(f"| `{e.name}` | {', '.join(e.aliases) or '-'} | {opts or '-'} | {e.description} |")
        return "\n".join(lines) + "\n"


def parse_assignments(items: list[str] | None, flag: str) -> dict[str, str]:
    """``["a=1", "b=x"]`` -> ``{"a": "1", "b": "x"}``; errors name ``flag``."""
    out: dict[str, str] = {}
    for item in items or []:
        if "=" not in item:
            raise InputError(f"{flag} expects NAME=VALUE, got {item!r}")
        k, v = item.split("=", 1)
        out[k.strip()] = v.strip()
    return out
