"""Isotropic materials: Lamé constants, density, stress and von Mises; the material model.

A material's ``model`` says how its body deforms: ``linear`` (small strains, :class:`IsotropicElastic`,
the default) or a hyperelastic law of finite strain (:class:`SaintVenantKirchhoff`,
:class:`NeoHookean`; :mod:`signorini.fem.hyperelastic`), each with the same Lamé constants and
density, whose tangent at rest is the linear stiffness.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

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
    #: the material model (:data:`MATERIAL_MODELS`): ``linear`` for this class
    model: ClassVar[str] = "linear"

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
        return _stress(self.lam, self.mu, self.young, eps)

    def stress3(self, eps: np.ndarray) -> np.ndarray:
        """The 3 x 3 Cauchy stress (..., 3, 3) of strains (..., d, d): plane strain's sigma_zz in 2D, uniaxial in 1D."""
        return _stress3(self.lam, self.mu, self.young, eps)

    def von_mises(self, eps: np.ndarray) -> np.ndarray:
        """von Mises stress sqrt(3/2 s:s), s the deviator of the 3D stress.

        In 2D (plane strain) the out-of-plane stress sigma_zz = lam tr(eps) is included;
        in 1D it is |sigma|.
        """
        return _von_mises(self.lam, self.mu, self.young, eps)


@dataclass(frozen=True)
class SaintVenantKirchhoff(IsotropicElastic):
    """Saint Venant-Kirchhoff finite strain: W = lam/2 (tr E)^2 + mu E:E, E = (F^T F - I)/2 (spec 12).

    The Lamé constants and density of :class:`IsotropicElastic` (``from_young`` too); the body's
    internal force is the Total Lagrangian one of :mod:`signorini.fem.hyperelastic`, invariant under
    rigid rotations, whose tangent at rest is the linear stiffness.  Softens in strong compression
    (its stress vanishes as a cell is squeezed flat): for large compressions use :class:`NeoHookean`."""

    model: ClassVar[str] = "saint-venant-kirchhoff"


@dataclass(frozen=True)
class NeoHookean(IsotropicElastic):
    """Compressible Neo-Hookean finite strain: W = mu/2 (I1 - d - 2 ln J) + lam/2 (ln J)^2, I1 = tr F^T F,
    J = det F (spec 12; plane strain in 2D, d = 2).  Its energy grows without bound as J -> 0."""

    model: ClassVar[str] = "neo-hookean"


#: the material models by name (``[material] model``): the class of each
MATERIAL_MODELS: dict[str, type[IsotropicElastic]] = {
    cls.model: cls for cls in (IsotropicElastic, SaintVenantKirchhoff, NeoHookean)
}


def with_model(material: IsotropicElastic, model: str) -> IsotropicElastic:
    """``material``'s constants under the model ``model`` (:data:`MATERIAL_MODELS`; InputError naming
    the allowed values)."""
    if model not in MATERIAL_MODELS:
        raise InputError(f"material model {model!r} is not known; allowed: {', '.join(MATERIAL_MODELS)}")
    return MATERIAL_MODELS[model](material.lam, material.mu, material.rho)


def _stress(lam, mu, young, eps: np.ndarray) -> np.ndarray:
    """sigma = lam tr(eps) I + 2 mu eps (E eps in 1D) for eps (..., d, d); lam, mu, young
    numbers or arrays broadcasting against eps's leading axes."""
    d = eps.shape[-1]
    if d == 1:
        return np.asarray(young)[..., None, None] * eps
    tr = np.trace(eps, axis1=-2, axis2=-1)
    lam, mu = np.asarray(lam), np.asarray(mu)
    return (lam * tr)[..., None, None] * np.eye(d) + 2 * mu[..., None, None] * eps


def _stress3(lam, mu, young, eps: np.ndarray) -> np.ndarray:
    """The 3 x 3 Cauchy stress (..., 3, 3) of :func:`_stress`: plane strain's sigma_zz = lam tr(eps) in 2D, the
    bar's axial stress E eps_xx alone in 1D (uniaxial)."""
    d = eps.shape[-1]
    sig = _stress(lam, mu, young, eps)
    if d == 3:
        return sig
    s3 = np.zeros(sig.shape[:-2] + (3, 3))
    s3[..., :d, :d] = sig
    if d == 2:
        s3[..., 2, 2] = np.asarray(lam) * np.trace(eps, axis1=-2, axis2=-1)
    return s3


def _von_mises(lam, mu, young, eps: np.ndarray) -> np.ndarray:
    """von Mises stress of :func:`_stress` (plane strain's sigma_zz = lam tr(eps) in 2D)."""
    if eps.shape[-1] == 1:
        return np.abs(_stress(lam, mu, young, eps)[..., 0, 0])
    sig = _stress3(lam, mu, young, eps)
    tr = np.trace(sig, axis1=-2, axis2=-1)
    dev = sig - tr[..., None, None] / 3.0 * np.eye(3)
    return np.sqrt(1.5 * np.einsum("...ij,...ij->...", dev, dev))


@dataclass(frozen=True)
class CellMaterial:
    """Per-cell isotropic materials: the Lamé constants and density of every cell (regions
    of different materials, :func:`cell_material`).

    Attributes
    ----------
    lam, mu : (n_cells,) Lamé constants [Pa].
    rho : (n_cells,) density [kg/m^d].

    Used by the assembly wherever an :class:`IsotropicElastic` is (stiffness, mass, loads,
    stress): ``lam``, ``mu``, ``rho`` and ``young`` are arrays over the cells instead of numbers.
    """

    lam: np.ndarray
    mu: np.ndarray
    rho: np.ndarray
    #: (n_cells,) the material model of every cell (:data:`MATERIAL_MODELS`); None: every cell linear
    models: np.ndarray | None = None

    @property
    def young(self) -> np.ndarray:
        """Young's modulus of every cell (n_cells,)."""
        return self.mu * (3 * self.lam + 2 * self.mu) / (self.lam + self.mu)

    def take(self, cells: np.ndarray) -> CellMaterial:
        """The materials of the cells ``cells`` (indices or mask): a sub-mesh's."""
        models = None if self.models is None else self.models[cells]
        return CellMaterial(self.lam[cells], self.mu[cells], self.rho[cells], models)

    def wave_speed(self, dim: int) -> float:
        """The largest compression wave speed of the cells [m/s] (as :meth:`IsotropicElastic.wave_speed`)."""
        modulus = self.young if dim == 1 else self.lam + 2 * self.mu
        return float(np.sqrt(modulus / self.rho).max(initial=0.0))

    def _per_cell(self, eps: np.ndarray, a: np.ndarray) -> np.ndarray:
        return a.reshape(a.shape + (1,) * (eps.ndim - 3))  # (n_cells, 1, ...) against eps (n_cells, nq, d, d)

    def stress(self, eps: np.ndarray) -> np.ndarray:
        """Cauchy stress (n_cells, ..., d, d) of strains ``eps`` (n_cells, ..., d, d)."""
        c = self._per_cell
        return _stress(c(eps, self.lam), c(eps, self.mu), c(eps, self.young), eps)

    def stress3(self, eps: np.ndarray) -> np.ndarray:
        """The 3 x 3 Cauchy stress (n_cells, ..., 3, 3) (as :meth:`IsotropicElastic.stress3`)."""
        c = self._per_cell
        return _stress3(c(eps, self.lam), c(eps, self.mu), c(eps, self.young), eps)

    def von_mises(self, eps: np.ndarray) -> np.ndarray:
        """von Mises stress (n_cells, ...) of strains ``eps`` (n_cells, ..., d, d)."""
        c = self._per_cell
        return _von_mises(c(eps, self.lam), c(eps, self.mu), c(eps, self.young), eps)


#: a material of the whole mesh: one for every cell, or one per cell
Material = IsotropicElastic | CellMaterial


def cell_material(
    n_cells: int,
    regions: dict[str, np.ndarray],
    default: IsotropicElastic,
    materials: dict[str, IsotropicElastic] | None,
) -> Material:
    """The material of every cell: ``materials[tag]`` on the cells of region ``tag``
    (``regions``: tag -> cell indices), ``default`` on the cells of no listed region.

    No ``materials`` (or every listed material equal to the default): ``default`` itself, so
    that a one-material run computes exactly as before.  A cell in two listed regions of
    different materials is refused (:class:`InputError` naming both tags).
    """
    if not materials or all(m == default for m in materials.values()):
        return default
    owner = np.full(n_cells, -1)
    tags = list(materials)
    for k, tag in enumerate(tags):
        if tag not in regions:
            known = ", ".join(sorted(regions)) or "none"
            raise InputError(f"material region {tag!r} is not a region of the mesh; its regions: {known}")
        cells = np.asarray(regions[tag])
        clash = owner[cells] >= 0
        if clash.any():
            other = tags[int(owner[cells[clash][0]])]
            if materials[other] != materials[tag]:
                raise InputError(
                    f"material regions {other!r} and {tag!r} share {int(clash.sum())} cell(s) and give them different "
                    "materials; list each cell's region once"
                )
        owner[cells] = k
    every = [*materials.values(), default]
    lam, mu, rho = (np.array([getattr(m, a) for m in every]) for a in ("lam", "mu", "rho"))
    models = np.array([m.model for m in every], dtype=object)
    linear = all(m.model == "linear" for m in every)
    return CellMaterial(lam[owner], mu[owner], rho[owner], None if linear else models[owner])  # owner -1: the default


def cell_models(material: Material, n_cells: int) -> np.ndarray:
    """(n_cells,) the material model of every cell (object array of :data:`MATERIAL_MODELS` names)."""
    if isinstance(material, CellMaterial):
        if material.models is None:
            return np.full(n_cells, "linear", dtype=object)
        return np.asarray(material.models, dtype=object)
    return np.full(n_cells, material.model, dtype=object)
