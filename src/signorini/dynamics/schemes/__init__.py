"""Time schemes: the :class:`~.base.Scheme` contract and the :data:`SCHEMES` registry.

A scheme is addressable by name or alias (``SCHEMES``), passed as a class, or passed
as an instance; :func:`make_scheme` validates its options against its parameters.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ...errors import InputError
from ...registry import Registry
from .base import EnergyParts, Scheme, State
from .contact_stabilized import ContactStabilizedNewmark
from .energy_momentum import EnergyMomentum
from .generalized_alpha import HHT, GeneralizedAlpha
from .moreau_jean import EnergyConserving, MoreauJean
from .newmark import CrankNicolson, Newmark
from .paoli_schatzman import PaoliSchatzman
from .penalty import PenaltyCN
from .step_problem import StepProblem, solve_step
from .theta import BackwardEuler, Theta

SCHEMES = Registry("scheme")


def register_scheme(cls: type[Scheme], aliases: tuple[str, ...] = (), name: str | None = None) -> type[Scheme]:
    """Add a :class:`Scheme` subclass to :data:`SCHEMES` under ``name`` (default ``cls.name``)."""
    SCHEMES.register(name or cls.name, cls, cls.description, aliases, cls.parameters)
    return cls


register_scheme(CrankNicolson, ("cn",))
register_scheme(BackwardEuler, ("be",))
register_scheme(Newmark)
register_scheme(Theta)
register_scheme(PaoliSchatzman, ("ps",))
register_scheme(HHT)
register_scheme(GeneralizedAlpha)
register_scheme(MoreauJean)
register_scheme(PenaltyCN)
register_scheme(ContactStabilizedNewmark, ("csn",))
register_scheme(EnergyConserving)
register_scheme(EnergyMomentum)


def friction_schemes() -> list[str]:
    """The registered schemes that carry a frictional contact law."""
    return [e.name for e in SCHEMES if e.obj.friction_refusal is None]


def damping_schemes() -> list[str]:
    """The registered schemes that carry Rayleigh damping."""
    return [e.name for e in SCHEMES if e.obj.damping_refusal is None]


def finite_strain_schemes() -> list[str]:
    """The registered schemes that run finite strain (a Newton step)."""
    return [e.name for e in SCHEMES if e.obj.finite_strain_refusal is None]


def make_scheme(scheme: str | type[Scheme] | Scheme, options: Mapping[str, Any] | None = None) -> Scheme:
    """A scheme instance from a registry name/alias, a Scheme subclass or an instance."""
    if isinstance(scheme, Scheme):
        if options:
            raise InputError("scheme options cannot be given with a scheme instance; pass the class or a name")
        return scheme
    if isinstance(scheme, type) and issubclass(scheme, Scheme):
        return scheme(**dict(options or {}))
    entry = SCHEMES.get(str(scheme))
    return entry.obj(**dict(options or {}))


__all__ = [
    "SCHEMES",
    "BackwardEuler",
    "ContactStabilizedNewmark",
    "CrankNicolson",
    "EnergyConserving",
    "EnergyMomentum",
    "EnergyParts",
    "GeneralizedAlpha",
    "HHT",
    "MoreauJean",
    "PenaltyCN",
    "Newmark",
    "PaoliSchatzman",
    "Scheme",
    "State",
    "StepProblem",
    "Theta",
    "damping_schemes",
    "friction_schemes",
    "make_scheme",
    "register_scheme",
    "solve_step",
]
