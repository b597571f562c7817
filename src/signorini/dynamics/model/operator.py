"""The step operators of a scheme: K = c_M M + c_S S (S or an iterate's tangent K(U)), with damping per region
as a third term c C (:class:`Operator`, :class:`Tangent`, :class:`Viscous`).  Factorized by the step's solvers
(:mod:`~signorini.dynamics.solve.context`); made by the schemes and the damping."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from ...linalg.sparse import linear_combination


class Tangent:
    """A tangent stiffness K(U) (n, n) of one Newton iterate (finite strain, :mod:`~.elasticity`): an
    operator ``c_M M + c_S K(U)`` holds it in place of S.  Two tangents are the same only when they
    are the same object (each iterate's is factorized on its own).  ``at``: the displacement U (n,) it was
    made at, when known (a kept tangent turned with its bodies, :mod:`~..solve.turning`)."""

    def __init__(self, matrix: sp.spmatrix, at: np.ndarray | None = None):
        self.matrix = matrix
        self.at = at

    def __repr__(self) -> str:
        return f"Tangent(id={id(self):#x})"


class Viscous:
    """``c C``, a damping matrix C (n, n) that is not a combination of M and S (Rayleigh damping per
    region, :class:`~signorini.dynamics.model.damping.RegionalRayleigh`) times a step's coefficient c
    [1/time]: an operator holds it as its third term.  Two are the same when their coefficients are
    equal and their matrices the same object."""

    __slots__ = ("coefficient", "matrix")

    def __init__(self, coefficient: float, matrix: sp.spmatrix):
        self.coefficient = float(coefficient)
        self.matrix = matrix

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Viscous) and other.coefficient == self.coefficient and other.matrix is self.matrix

    def __hash__(self) -> int:
        return hash((self.coefficient, id(self.matrix)))

    def __repr__(self) -> str:
        return f"Viscous({self.coefficient:g} C)"


@dataclass(frozen=True)
class Operator:
    """The linear operator K = mass * M + stiffness * S of a scheme for a given dt; with a ``tangent``
    (finite strain), mass * M + stiffness * K(U) of that iterate; with ``viscous`` (damping per region),
    plus c C."""

    mass: float
    stiffness: float
    tangent: Tangent | None = None
    viscous: Viscous | None = None

    def matrix(self, M: sp.spmatrix, S: sp.spmatrix) -> sp.csr_matrix:
        return linear_combination(self.mass, M, *self.stiffness_part(S))

    def stiffness_matrix(self, S: Any) -> Any:
        """The stiffness this operator combines: the tangent's, or ``S``."""
        return S if self.tangent is None else self.tangent.matrix

    def stiffness_part(self, S: Any) -> tuple[float, Any]:
        """(b, B) with K = mass M + b B: (stiffness, S or the tangent), or with ``viscous``
        (1, stiffness S + c C)."""
        if self.viscous is None:
            return self.stiffness, self.stiffness_matrix(S)
        return 1.0, linear_combination(
            self.stiffness, self.stiffness_matrix(S), self.viscous.coefficient, self.viscous.matrix
        )

    def coefficients(self) -> list[float]:
        """[mass, stiffness] and, with ``viscous``, its coefficient (what a checkpoint records)."""
        return [self.mass, self.stiffness] + ([] if self.viscous is None else [self.viscous.coefficient])

    def ratio_to(self, other: Operator) -> float | None:
        """s with self = s * other, or None when they are not proportional."""
        if self.tangent is not other.tangent:
            return None
        if (self.viscous is None) != (other.viscous is None) or (
            self.viscous is not None and self.viscous.matrix is not other.viscous.matrix
        ):
            return None
        mine, theirs = self.coefficients(), other.coefficients()
        pairs = ((self.stiffness, other.stiffness), (self.mass, other.mass), *zip(mine[2:], theirs[2:], strict=True))
        for a, b in pairs:
            if b != 0.0:
                s = a / b
                break
        else:  # pragma: no cover - a zero operator is rejected earlier
            return None
        ok = all(np.isclose(a, s * b, rtol=1e-13, atol=0.0) for a, b in zip(mine, theirs, strict=True))
        return float(s) if ok and s > 0 else None
