"""Rayleigh damping C = alpha M + beta S (docs/schemes.md, "Damping").

The equation of motion becomes ``M A + C V + S U = F + B^T lambda``, with M the mass in use
(a redistribution damps what it keeps: a massless contact node gets no mass-proportional
damping) and S the stiffness.  alpha [1/time] damps the low frequencies, beta [time] the high
ones: a mode of angular frequency omega decays with the damping ratio

    zeta(omega) = alpha / (2 omega) + beta omega / 2.

A scheme that carries damping solves its step with ``K + c C`` (``c`` its
:meth:`~signorini.dynamics.schemes.base.Scheme.damping_coefficient`), which for a Rayleigh C
is again a combination of M and S: one factorization per step size, as without damping, on
every backend.  The velocity V_d of each level's damping force C V_d is the scheme's own
(``extra['damping_velocity']``, :func:`~signorini.dynamics.schemes.base.damping_force`) so that
the energy identity closes exactly: its work over a step is the ``damping_dissipation`` column
of ``history.csv``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import InputError
from ..fem.material import RANGE

if TYPE_CHECKING:
    from .context import Context, Operator

#: the keys of a damping table (``[material] damping = { alpha = ..., beta = ... }``)
DAMPING_KEYS = ("alpha", "beta")


@dataclass(frozen=True)
class Rayleigh:
    """Rayleigh damping C = alpha M + beta S.

    Parameters
    ----------
    alpha : mass-proportional coefficient [1/time], >= 0.
    beta : stiffness-proportional coefficient [time], >= 0.
    """

    alpha: float = 0.0
    beta: float = 0.0

    def __post_init__(self) -> None:
        for name in DAMPING_KEYS:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise InputError(f"damping {name} must be a number >= 0, got {v!r}")
            try:
                x = float(v)
            except OverflowError:
                x = float("inf")
            if not np.isfinite(x) or x < 0:
                raise InputError(f"damping {name} must be a finite number >= 0, got {v!r}")
            if x != 0 and not RANGE[0] <= x <= RANGE[1]:
                raise InputError(f"damping {name} = {x:g} is outside {RANGE[0]:g} <= {name} <= {RANGE[1]:g} (or 0): "
                                 "products of such values leave double precision; change units")  # fmt: skip
            object.__setattr__(self, name, x)

    @property
    def active(self) -> bool:
        """Whether C is not zero."""
        return self.alpha > 0 or self.beta > 0

    def ratio(self, omega: float | np.ndarray) -> float | np.ndarray:
        """The modal damping ratio zeta = alpha / (2 omega) + beta omega / 2 at angular frequency omega."""
        return self.alpha / (2 * omega) + self.beta * omega / 2

    def force(self, ctx: Context, V: np.ndarray) -> np.ndarray:
        """C V = alpha M V + beta S V (n,) [force]."""
        out = np.zeros_like(V)
        if self.alpha:
            out += self.alpha * (ctx.Mop @ V)
        if self.beta:
            out += self.beta * (ctx.Sop @ V)
        return out

    def fold(self, op: Operator, c: float) -> Operator:
        """``op + c C``: the step operator of a scheme whose balance holds ``c C`` times its unknown."""
        from .context import Operator

        return Operator(op.mass + c * self.alpha, op.stiffness + c * self.beta)

    def describe(self) -> dict[str, Any]:
        """``summary.json`` ``damping``: model ``rayleigh``, or ``none`` when C = 0."""
        return {"model": "rayleigh" if self.active else "none", "alpha": float(self.alpha), "beta": float(self.beta)}


#: no damping (what ``summary.json`` describes for an undamped run)
UNDAMPED = Rayleigh()


def make_damping(spec: Rayleigh | Mapping[str, Any] | None, where: str = "damping") -> Rayleigh | None:
    """A :class:`Rayleigh` from ``{alpha, beta}`` (each optional, 0 by default), or None when
    ``spec`` is None or both coefficients are zero (no damping: the runs are exactly as without)."""
    if spec is None:
        return None
    if isinstance(spec, Rayleigh):
        return spec if spec.active else None
    if not isinstance(spec, Mapping):
        raise InputError(f"'{where}' must be a table {{ alpha = ..., beta = ... }}, got {spec!r}")
    unknown = sorted(set(spec) - set(DAMPING_KEYS))
    if unknown:
        raise InputError(f"'{where}': unknown key {unknown[0]!r}; allowed: {', '.join(DAMPING_KEYS)}")
    try:
        damping = Rayleigh(**{k: spec[k] for k in DAMPING_KEYS if k in spec})
    except InputError as exc:
        raise InputError(f"'{where}.{str(exc).split()[1]}': {exc}") from None
    return damping if damping.active else None
