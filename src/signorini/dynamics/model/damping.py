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
import scipy.sparse as sp

from ...errors import InputError
from ...fem.material import RANGE

if TYPE_CHECKING:
    from ..solve.context import Context
    from .operator import Operator

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
                raise InputError(
                    f"damping {name} = {x:g} is outside {RANGE[0]:g} <= {name} <= {RANGE[1]:g} (or 0): "
                    "products of such values leave double precision; change units"
                )
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

    def fold(self, op: Operator, c: float, ctx: Context | None = None) -> Operator:
        """``op + c C``: the step operator of a scheme whose balance holds ``c C`` times its unknown
        (a combination of M and S again)."""
        from .operator import Operator

        return Operator(op.mass + c * self.alpha, op.stiffness + c * self.beta, op.tangent)

    def describe(self) -> dict[str, Any]:
        """``summary.json`` ``damping``: model ``rayleigh``, or ``none`` when C = 0."""
        return {"model": "rayleigh" if self.active else "none", "alpha": float(self.alpha), "beta": float(self.beta)}


#: no damping (what ``summary.json`` describes for an undamped run)
UNDAMPED = Rayleigh()


@dataclass(frozen=True)
class RegionalRayleigh:
    """Rayleigh damping with coefficients per region (``[material] regions = [{ tag, damping }]``)::

        C = D_a^(1/2) M D_a^(1/2) + sum_c beta_c S_c

    with S_c the stiffness of cell c (``sum_c beta_c S_c`` is the stiffness assembled with the
    moduli of each cell times its beta) and D_a the diagonal of every dof's alpha: the mass-weighted
    mean over the node's cells, ``a_i = sum_c rho_c |c| alpha_c / sum_c rho_c |c|``.  Where the
    regions are bodies (no node shared: M has no entry between them) C = sum_r (alpha_r M_r + beta_r S_r)
    exactly, M_r the mass in use on body r; a node shared by two regions gets the mean of their
    alphas (docs/schemes.md, "Damping").  One region's coefficients on every cell: C = alpha M + beta S
    as :class:`Rayleigh` (which a uniform table gives, exactly as before).

    C is not a combination of M and S: the step operator holds it as a third term
    (:class:`~signorini.dynamics.solve.context.Viscous`), which the serial direct backends factorize (the
    others refuse it by name).

    Parameters
    ----------
    default : the coefficients of the cells in no listed region (``[material] damping``).
    regions : (tag, :class:`Rayleigh`) of each region that has its own (``regions[k].damping``).
    """

    default: Rayleigh
    regions: tuple[tuple[str, Rayleigh], ...]

    @property
    def active(self) -> bool:
        return self.default.active or any(r.active for _, r in self.regions)

    @property
    def beta(self) -> float:
        """The largest beta of the cells [time]."""
        return max([self.default.beta, *(r.beta for _, r in self.regions)])

    def cell_coefficients(self, mesh: Any) -> tuple[np.ndarray, np.ndarray]:
        """(alpha, beta) of every cell (n_cells,) each: a region's own, the default elsewhere.  A cell in
        two listed regions of different coefficients is refused (:class:`InputError` naming both)."""
        alpha = np.full(mesh.n_cells, self.default.alpha)
        beta = np.full(mesh.n_cells, self.default.beta)
        owner = np.full(mesh.n_cells, -1)
        for k, (tag, r) in enumerate(self.regions):
            if tag not in mesh.regions:
                known = ", ".join(sorted(mesh.regions)) or "none"
                raise InputError(f"damping region {tag!r} is not a region of the mesh; its regions: {known}")
            cells = np.asarray(mesh.regions[tag])
            shared = cells[owner[cells] >= 0]
            differ = shared[(alpha[shared] != r.alpha) | (beta[shared] != r.beta)]
            if differ.size:
                other = self.regions[int(owner[differ[0]])][0]
                raise InputError(
                    f"damping regions {other!r} and {tag!r} share {differ.size} cell(s) and give "
                    "them different damping; list each cell's region once"
                )
            owner[cells] = k
            alpha[cells], beta[cells] = r.alpha, r.beta
        return alpha, beta

    def matrix(self, mesh: Any, material: Any, M: sp.spmatrix, S: sp.spmatrix) -> sp.csr_matrix:
        """C (n, n) [force time / length] for the mass in use ``M`` and the stiffness ``S`` of
        ``material`` on ``mesh``."""
        from ...fem.assembly import nodal_average, scaled_stiffness

        alpha, beta = self.cell_coefficients(mesh)
        rho = np.broadcast_to(np.asarray(material.rho, dtype=float), (mesh.n_cells,))
        a = nodal_average(mesh, rho * alpha) / nodal_average(mesh, rho)  # mass-weighted, per node
        root = sp.diags(np.repeat(np.sqrt(a), S.shape[0] // mesh.n_nodes))
        C = root @ M @ root
        if np.any(beta > 0):
            C = C + (beta[0] * S if np.all(beta == beta[0]) else scaled_stiffness(mesh, material, beta))
        C = sp.csr_matrix(C)
        C.sum_duplicates()
        C.sort_indices()
        return C

    def force(self, ctx: Context, V: np.ndarray) -> np.ndarray:
        """C V (n,) [force]."""
        return ctx.damping_matrix @ V

    def fold(self, op: Operator, c: float, ctx: Context | None = None) -> Operator:
        """``op + c C`` with C held as the operator's third term."""
        from .operator import Operator, Viscous

        base = 0.0 if op.viscous is None else op.viscous.coefficient
        return Operator(op.mass, op.stiffness, op.tangent, Viscous(base + c, ctx.damping_matrix))

    def describe(self) -> dict[str, Any]:
        """``summary.json`` ``damping``: the section's coefficients and each region's."""
        out = self.default.describe()
        out["model"] = "rayleigh"
        out["regions"] = [{"tag": tag, "alpha": float(r.alpha), "beta": float(r.beta)} for tag, r in self.regions]
        return out


def regional_damping(
    default: Rayleigh | None, regions: Mapping[str, Rayleigh | None]
) -> Rayleigh | RegionalRayleigh | None:
    """The damping of a mesh whose regions may have their own: ``default`` (or None) when every region's equals
    it, else a :class:`RegionalRayleigh` (None entries of ``regions``: undamped regions)."""
    base = default or UNDAMPED
    own = tuple((tag, r or UNDAMPED) for tag, r in regions.items())
    if all(r == base for _, r in own):
        return default
    return RegionalRayleigh(base, own)


def make_damping(
    spec: Rayleigh | RegionalRayleigh | Mapping[str, Any] | None, where: str = "damping"
) -> Rayleigh | RegionalRayleigh | None:
    """A :class:`Rayleigh` from ``{alpha, beta}`` (each optional, 0 by default), or None when
    ``spec`` is None or both coefficients are zero (no damping: the runs are exactly as without);
    a :class:`RegionalRayleigh` as it is (None when no region is damped)."""
    if spec is None:
        return None
    if isinstance(spec, RegionalRayleigh):
        return spec if spec.active else None
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
