"""Isotropic linear elasticity: Lamé constants, density, stress and von Mises."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

RANGE = (1e-100, 1e100)  # magnitudes whose products and squares stay normal doubles


@dataclass(frozen=True)
class IsotropicElastic:
    """Isotropic linear-elastic material, sigma = lam tr(eps) I + 2 mu eps.

    Parameters
    ----------
    lam, mu : Lamé constants [Pa].  Required: mu > 0 and 3 lam + 2 mu > 0.
    rho : mass density [kg/m^d], rho > 0.

    In 1D the stiffness uses Young's modulus ``E = mu (3 lam + 2 mu) / (lam + mu)``;
    build a 1D bar with :meth:`from_young` (``nu = 0`` gives lam = 0, mu = E/2).
    2D problems are plane strain.
    """

    lam: float
    mu: float
    rho: float = 1.0

    def __post_init__(self) -> None:
        for name in ("lam", "mu", "rho"):
            v = getattr(self, name)
            if not isinstance(v, (int, float, np.floating, np.integer)) or not np.isfinite(v):
                raise InputError(f"material {name} must be a finite number, got {v!r}")
            if abs(v) > RANGE[1] or (v != 0 and abs(v) < RANGE[0]):
                raise InputError(
                    f"material {name} = {v:g} is outside {RANGE[0]:g} <= |{name}| <= {RANGE[1]:g}: products of "
                    "such values leave double precision; change units"
                )
        if self.rho <= 0:
            raise InputError(f"material rho (density) must be > 0, got {self.rho}")
        if self.mu <= 0:
            raise InputError(f"material mu (shear modulus) must be > 0, got {self.mu}")
        if 3 * self.lam + 2 * self.mu <= 0:
            raise InputError(
                f"material needs a positive bulk modulus, 3 lam + 2 mu > 0; got lam={self.lam}, mu={self.mu}"
            )

    @classmethod
    def from_young(cls, E: float, nu: float = 0.0, rho: float = 1.0) -> IsotropicElastic:
        """Build from Young's modulus ``E`` > 0 and Poisson ratio -1 < ``nu`` < 0.5."""
        if not np.isfinite(E) or E <= 0 or not RANGE[0] <= E <= RANGE[1]:
            raise InputError(f"material E (Young's modulus) must be in [{RANGE[0]:g}, {RANGE[1]:g}], got {E}")
        if not (-1.0 < nu < 0.5):
            raise InputError(f"material nu (Poisson ratio) must satisfy -1 < nu < 0.5, got {nu}")
        lam = E * nu / ((1 + nu) * (1 - 2 * nu))
        mu = E / (2 * (1 + nu))
        return cls(lam, mu, rho)

    @property
    def young(self) -> float:
        """Young's modulus E = mu (3 lam + 2 mu) / (lam + mu)."""
        return self.mu * (3 * self.lam + 2 * self.mu) / (self.lam + self.mu)

    @property
    def poisson(self) -> float:
        """Poisson ratio nu = lam / (2 (lam + mu))."""
        return self.lam / (2 * (self.lam + self.mu))

    def wave_speed(self, dim: int) -> float:
        """Speed of the compression wave used for CFL-type scales [m/s]:
        sqrt(E/rho) in 1D, sqrt((lam + 2 mu)/rho) otherwise."""
        return float(np.sqrt((self.young if dim == 1 else self.lam + 2 * self.mu) / self.rho))

    def stress(self, eps: np.ndarray) -> np.ndarray:
        """Cauchy stress from strain tensors ``eps`` of shape (..., d, d)."""
        d = eps.shape[-1]
        if d == 1:
            return self.young * eps
        tr = np.trace(eps, axis1=-2, axis2=-1)
        return self.lam * tr[..., None, None] * np.eye(d) + 2 * self.mu * eps

    def von_mises(self, eps: np.ndarray) -> np.ndarray:
        """von Mises stress sqrt(3/2 s:s), s the deviator of the 3D stress.

        In 2D (plane strain) the out-of-plane stress sigma_zz = lam tr(eps) is included;
        in 1D it is |sigma|.
        """
        d = eps.shape[-1]
        sig = self.stress(eps)
        if d == 1:
            return np.abs(sig[..., 0, 0])
        if d == 2:
            s3 = np.zeros(sig.shape[:-2] + (3, 3))
            s3[..., :2, :2] = sig
            s3[..., 2, 2] = self.lam * np.trace(eps, axis1=-2, axis2=-1)
            sig = s3
        tr = np.trace(sig, axis1=-2, axis2=-1)
        dev = sig - tr[..., None, None] / 3.0 * np.eye(3)
        return np.sqrt(1.5 * np.einsum("...ij,...ij->...", dev, dev))
