"""The option language of ``signorini compare``: schemes with options, masses, pairs, a reference."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ...dynamics.model.mass import MASS_VARIANTS
from ...dynamics.schemes import SCHEMES, make_scheme
from ...errors import InputError
from ...registry import parse_assignments


@dataclass(frozen=True)
class SchemeSpec:
    """A registry scheme with the options the user gave (validated, converted)."""

    name: str
    options: tuple[tuple[str, Any], ...] = ()

    @property
    def label(self) -> str:
        """``name`` or ``name[opt=value,...]`` (canonical name, options as given)."""
        if not self.options:
            return self.name
        return f"{self.name}[{','.join(f'{k}={_num(v)}' for k, v in self.options)}]"

    @property
    def option_dict(self) -> dict[str, Any]:
        return dict(self.options)


def _num(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _split_top_level(text: str, flag: str) -> list[str]:
    """Split on commas outside brackets; unbalanced brackets are an InputError."""
    parts, depth, cur = [], 0, []
    for ch in text:
        if ch == "[":
            depth += 1
            if depth > 1:
                raise InputError(f"{flag}: nested '[' in {text!r}")
        elif ch == "]":
            depth -= 1
            if depth < 0:
                raise InputError(f"{flag}: unbalanced ']' in {text!r}")
        if ch == "," and depth == 0:
            parts.append("".join(cur).strip())
            cur = []
        else:
            cur.append(ch)
    if depth:
        raise InputError(f"{flag}: missing ']' in {text!r}")
    parts.append("".join(cur).strip())
    if any(not p for p in parts):
        raise InputError(f"{flag}: empty entry in {text!r} (entries are separated by commas)")
    return parts


def parse_scheme(text: str, flag: str = "--schemes") -> SchemeSpec:
    """``name`` or ``name[opt=val,opt2=val]``, validated by :data:`SCHEMES`."""
    text = text.strip()
    name, opts = text, {}
    if "[" in text or "]" in text:
        if not (text.endswith("]") and text.count("[") == 1 and text.count("]") == 1 and text.index("[") > 0):
            raise InputError(f"{flag}: expected name or name[option=value,...], got {text!r}")
        name, inner = text[:-1].split("[", 1)
        opts = parse_assignments([s for s in inner.split(",") if s.strip()], f"{flag} {name.strip()}[...]")
    entry = SCHEMES.get(name.strip())  # unknown name: InputError listing the allowed ones
    converted = entry.options(opts, where=f"scheme {entry.name}")  # unknown option: lists the allowed ones
    make_scheme(entry.name, converted)  # cross-parameter checks
    return SchemeSpec(entry.name, tuple((k, converted[k]) for k in opts))


def parse_schemes(text: str) -> list[SchemeSpec]:
    specs = [parse_scheme(p) for p in _split_top_level(text, "--schemes")]
    seen = set()
    for s in specs:
        if s in seen:
            raise InputError(f"--schemes lists {s.label} twice")
        seen.add(s)
    return specs


def parse_masses(text: str) -> list[str]:
    names = [MASS_VARIANTS.resolve(p) for p in _split_top_level(text, "--masses")]
    if len(set(names)) != len(names):
        raise InputError(f"--masses lists a mass variant twice: {text!r}")
    return names


@dataclass(frozen=True)
class Pair:
    scheme: SchemeSpec
    mass: str

    @property
    def label(self) -> str:
        return f"{self.scheme.label} / {self.mass}"


def make_pairs(schemes: Sequence[SchemeSpec], masses: Sequence[str]) -> list[Pair]:
    """schemes x masses, scheme-major."""
    return [Pair(s, m) for s in schemes for m in masses]


def parse_reference(text: str) -> tuple[SchemeSpec, str | None, int]:
    """``LEVEL`` (CN and the default reference mass: None here, :func:`~.plan.reference_mass`) or
    ``scheme:mass:LEVEL``."""
    parts = text.rsplit(":", 2)
    if len(parts) not in (1, 3):
        raise InputError(f"--reference expects LEVEL or scheme:mass:LEVEL, got {text!r}")
    scheme = parse_scheme(parts[0], "--reference") if len(parts) == 3 else SchemeSpec("crank-nicolson")
    mass = MASS_VARIANTS.resolve(parts[1]) if len(parts) == 3 else None
    try:
        level = int(parts[-1])
    except ValueError:
        raise InputError(f"--reference: the level must be an integer, got {parts[-1]!r}") from None
    if level < 1:
        raise InputError(f"--reference: the level must be positive, got {level}")
    return scheme, mass, level
