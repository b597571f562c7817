"""Finite strain (Total Lagrangian): hyperelastic laws and their internal force and tangent (spec 12).

Kinematics at a quadrature point: F = I + grad_X u (d x d; plane strain in 2D, F_33 = 1),
C = F^T F, E = (C - I)/2, J = det F.  A law gives the stored energy density W, the second
Piola-Kirchhoff stress S = dW/dE and its tangent CC = dS/dE (:class:`SaintVenantKirchhoffLaw`,
:class:`NeoHookeanLaw`).  Over a mesh (every cell type, mixed meshes as the sum of their one-type
parts, no Python loop over cells):

    energy        Pi(U) = sum_e sum_q w_q |det J_e| W(F)                    [energy]
    internal force f_a,i = sum_q w_q |det J| (F S)_iJ dN_a/dX_J              [force]
    tangent       K_ai,bk = sum_q w_q |det J| [dN_a/dX_I S_IJ dN_b/dX_J delta_ik
                                             + F_iI dN_a/dX_J CC_IJKL F_kK dN_b/dX_L]

with f = dPi/dU and K = df/dU.  Both laws reduce to linear elasticity for small strains (their
tangent at U = 0 is the linear stiffness matrix) and are invariant under rigid rotations:
f((R - I) X) = 0, sum_a f_a = 0 and sum_a x_a x f_a = 0 (x = X + U), so that a mass acting
alike on every component keeps the linear and angular momentum.

The laws take the Lamé constants as numbers or one value per cell (regions: a
:class:`~signorini.fem.material.CellMaterial`'s ``lam``, ``mu``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import scipy.sparse as sp

from ..errors import InputError, NonFiniteError
from .assembly import assemble_nodal, assemble_vector, geometry, sum_of
from .elements import determinants, reference_element
from .mesh import Mesh


def _lame(value, shape: tuple[int, ...]) -> np.ndarray | float:
    """A Lamé constant as a factor of arrays of ``shape`` (cells first): a number as it is, one
    value per cell broadcast over the remaining axes."""
    if np.ndim(value) == 0:
        return float(value)
    return np.asarray(value, dtype=float).reshape((-1,) + (1,) * (len(shape) - 1))


class InvertedCellError(NonFiniteError):
    """A state that inverts a cell (det F <= 0): no energy, no stress; a numerical failure of the step
    that reached it (exit 3, or a rejected step under the adaptive control).  ``what``: the cell and its
    det F, without the advice to the step."""

    def __init__(self, what: str):
        super().__init__(f"{what}: the deformation is beyond what the mesh can carry; reduce the step")
        self.what = what


@dataclass(frozen=True)
class HyperelasticLaw:
    """A stored energy W(E) of the Green-Lagrange strain; ``lam``, ``mu`` the Lamé constants [stress]
    (numbers, or arrays of one value per cell of the mesh they are used on)."""

    lam: float | np.ndarray
    mu: float | np.ndarray
    name: ClassVar[str] = ""

    def energy(self, F: np.ndarray) -> np.ndarray:
        """W (...) at the deformation gradients F (..., d, d) [energy / volume]."""
        return self.energy_C(_green(F)[0])

    def stress(self, F: np.ndarray) -> np.ndarray:
        """S = dW/dE (..., d, d) [stress]."""
        return self.stress_C(_green(F)[0])

    def tangent(self, F: np.ndarray) -> np.ndarray:
        """CC = dS/dE (..., d, d, d, d) [stress], with the minor and major symmetries."""
        return self.tangent_C(_green(F)[0])

    def energy_difference_C(self, C0: np.ndarray, C1: np.ndarray) -> np.ndarray:
        """W(C1) - W(C0) (...) [energy / volume]; laws override it with a form free of cancellation (the
        discrete gradient divides it, less S:dC/2, by |dC|^2)."""
        return self.energy_C(C1) - self.energy_C(C0)

    def take(self, lo: int, hi: int) -> HyperelasticLaw:
        """The law of the cells lo .. hi - 1 (per-cell constants sliced; numbers as they are)."""
        cut = lambda v: v if np.ndim(v) == 0 else np.asarray(v)[lo:hi]  # noqa: E731
        return type(self)(cut(self.lam), cut(self.mu))

    def stress_and_voigt_tangent(self, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(S (..., d, d), D (..., m, m)): the stress and the tangent in Voigt's order (:data:`VOIGT`),
        D_ab = CC_{I_a J_a I_b J_b} (m = 3 in 2D, 6 in 3D); laws override it to share their invariants."""
        C = _green(F)[0]
        I, J = VOIGT[F.shape[-1]]
        CC = self.tangent_C(C)
        return self.stress_C(C), CC[..., I[:, None], J[:, None], I[None, :], J[None, :]]

    def energy_C(self, C: np.ndarray) -> np.ndarray:
        """W as a function of the right Cauchy-Green tensor C (..., d, d)."""
        raise NotImplementedError

    def stress_C(self, C: np.ndarray) -> np.ndarray:
        """S = 2 dW/dC (..., d, d)."""
        raise NotImplementedError

    def tangent_C(self, C: np.ndarray) -> np.ndarray:
        """CC = 4 d^2W/dC^2 (..., d, d, d, d)."""
        raise NotImplementedError


#: the Voigt order of a symmetric tensor's components (I_a, J_a): 11, 22, 12 in 2D; 11, 22, 33, 12, 23, 13 in 3D
VOIGT = {2: (np.array([0, 1, 0]), np.array([0, 1, 1])), 3: (np.array([0, 1, 2, 0, 1, 0]), np.array([0, 1, 2, 1, 2, 2]))}


def _inv(A: np.ndarray) -> np.ndarray:
    """A^-1 (..., d, d) of 2 x 2 or 3 x 3 matrices: the adjugate over the determinant."""
    if A.shape[-1] == 2:
        adj = np.stack([np.stack([A[..., 1, 1], -A[..., 0, 1]], -1), np.stack([-A[..., 1, 0], A[..., 0, 0]], -1)], -2)
        return adj / determinants(A)[..., None, None]
    c0, c1, c2 = (
        np.cross(A[..., 1, :], A[..., 2, :]),
        np.cross(A[..., 2, :], A[..., 0, :]),
        np.cross(A[..., 0, :], A[..., 1, :]),
    )
    adj = np.stack([c0, c1, c2], axis=-1)
    return adj / np.einsum("...j,...j->...", A[..., 0, :], c0)[..., None, None]


def _green(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(C, E): the right Cauchy-Green tensor F^T F and the Green-Lagrange strain (C - I)/2."""
    C = np.matmul(np.swapaxes(F, -1, -2), F)
    return C, 0.5 * (C - np.eye(F.shape[-1]))


def _symmetric_identity(d: int) -> np.ndarray:
    """(delta_IK delta_JL + delta_IL delta_JK) (d, d, d, d)."""
    eye = np.eye(d)
    return np.einsum("IK,JL->IJKL", eye, eye) + np.einsum("IL,JK->IJKL", eye, eye)


@dataclass(frozen=True)
class SaintVenantKirchhoffLaw(HyperelasticLaw):
    """W = lam/2 (tr E)^2 + mu E:E; S = lam tr(E) I + 2 mu E; CC = lam I x I + mu (I (x) I)_sym.

    Exact under large rotations; not polyconvex (it softens in strong compression and can invert
    an element): meant for moderate strains with large rotations.
    """

    name: ClassVar[str] = "saint-venant-kirchhoff"

    def energy_C(self, C: np.ndarray) -> np.ndarray:
        E = 0.5 * (C - np.eye(C.shape[-1]))
        trE = np.trace(E, axis1=-2, axis2=-1)
        lam, mu = _lame(self.lam, trE.shape), _lame(self.mu, trE.shape)
        return 0.5 * lam * trE**2 + mu * np.einsum("...IJ,...IJ->...", E, E)

    def stress_C(self, C: np.ndarray) -> np.ndarray:
        E = 0.5 * (C - np.eye(C.shape[-1]))
        trE = np.trace(E, axis1=-2, axis2=-1)
        lam, mu = _lame(self.lam, E.shape), _lame(self.mu, E.shape)
        return lam * trE[..., None, None] * np.eye(C.shape[-1]) + 2.0 * mu * E

    def tangent_C(self, C: np.ndarray) -> np.ndarray:
        d = C.shape[-1]
        shape = C.shape[:-2] + (d, d, d, d)
        lam, mu = _lame(self.lam, shape), _lame(self.mu, shape)
        eye = np.eye(d)
        base = lam * np.einsum("IJ,KL->IJKL", eye, eye) + mu * _symmetric_identity(d)
        return np.broadcast_to(base, shape)

    def stress_and_voigt_tangent(self, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = F.shape[-1]
        m = 3 * (d - 1)
        normal = np.zeros((m, m))
        normal[:d, :d] = 1.0
        shear = np.diag(np.r_[2.0 * np.ones(d), np.ones(m - d)])  # mu (delta_IK delta_JL + delta_IL delta_JK)
        shape = F.shape[:-2] + (m, m)
        lam, mu = _lame(self.lam, shape), _lame(self.mu, shape)
        return self.stress_C(_green(F)[0]), lam * normal + mu * shear


@dataclass(frozen=True)
class NeoHookeanLaw(HyperelasticLaw):
    """Compressible Neo-Hookean: W = mu/2 (I1 - 3 - 2 ln J) + lam/2 (ln J)^2 (I1 = tr C, with
    C_33 = 1 in plane strain); S = mu (I - C^-1) + lam ln(J) C^-1;
    CC = lam Ci x Ci + (mu - lam ln J)(Ci_IK Ci_JL + Ci_IL Ci_JK), Ci = C^-1.

    Polyconvex; W grows without bound as J -> 0: a state with J <= 0 (an inverted element) has
    no energy and is refused (:func:`check_orientation`).
    """

    name: ClassVar[str] = "neo-hookean"

    def energy_C(self, C: np.ndarray) -> np.ndarray:
        d = C.shape[-1]
        lnJ = 0.5 * np.log(determinants(C))
        I1 = np.trace(C, axis1=-2, axis2=-1) + (3 - d)  # plane strain: C_33 = 1
        lam, mu = _lame(self.lam, lnJ.shape), _lame(self.mu, lnJ.shape)
        return 0.5 * mu * (I1 - 3.0 - 2.0 * lnJ) + 0.5 * lam * lnJ**2

    def energy_difference_C(self, C0: np.ndarray, C1: np.ndarray) -> np.ndarray:
        """mu/2 (tr dC - 2 dlnJ) + lam/2 dlnJ (lnJ0 + lnJ1) with dlnJ = 1/2 log det(I + X), X = C0^-1 dC,
        det(I + X) - 1 from the invariants of X (log1p): no difference of two large energies."""
        d = C0.shape[-1]
        X = np.linalg.solve(C0, C1 - C0)
        trX = np.trace(X, axis1=-2, axis2=-1)
        detX = determinants(X)
        if d == 2:
            rest = trX + detX
        else:
            rest = trX + 0.5 * (trX**2 - np.einsum("...ij,...ji->...", X, X)) + detX
        dlnJ = 0.5 * np.log1p(rest)
        lnJ0, lnJ1 = 0.5 * np.log(determinants(C0)), 0.5 * np.log(determinants(C1))
        lam, mu = _lame(self.lam, trX.shape), _lame(self.mu, trX.shape)
        trdC = np.trace(C1 - C0, axis1=-2, axis2=-1)
        return 0.5 * mu * (trdC - 2.0 * dlnJ) + 0.5 * lam * dlnJ * (lnJ0 + lnJ1)

    def stress_C(self, C: np.ndarray) -> np.ndarray:
        return self._stress(_inv(C), 0.5 * np.log(determinants(C)))

    def _stress(self, Ci: np.ndarray, lnJ: np.ndarray) -> np.ndarray:
        """S = mu (I - C^-1) + lam ln(J) C^-1 from C^-1 (..., d, d) and ln J (...)."""
        lam, mu = _lame(self.lam, Ci.shape), _lame(self.mu, Ci.shape)
        return mu * (np.eye(Ci.shape[-1]) - Ci) + lam * lnJ[..., None, None] * Ci

    def tangent_C(self, C: np.ndarray) -> np.ndarray:
        Ci = _inv(C)
        d = C.shape[-1]
        shape = C.shape[:-2] + (d, d, d, d)
        lnJ = 0.5 * np.log(determinants(C))[..., None, None, None, None]
        lam, mu = _lame(self.lam, shape), _lame(self.mu, shape)
        outer = np.einsum("...IJ,...KL->...IJKL", Ci, Ci)
        sym = np.einsum("...IK,...JL->...IJKL", Ci, Ci) + np.einsum("...IL,...JK->...IJKL", Ci, Ci)
        return lam * outer + (mu - lam * lnJ) * sym

    def stress_and_voigt_tangent(self, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        C = _green(F)[0]
        Ci = _inv(C)
        lnJ = 0.5 * np.log(determinants(C))
        I, J = VOIGT[F.shape[-1]]
        S = self._stress(Ci, lnJ)
        c = Ci[..., I, J]  # (..., m)
        a, b = I[:, None], J[:, None]
        k, l = I[None, :], J[None, :]  # noqa: E741
        sym = Ci[..., a, k] * Ci[..., b, l] + Ci[..., a, l] * Ci[..., b, k]
        lam_m = _lame(self.lam, sym.shape)
        return S, lam_m * c[..., :, None] * c[..., None, :] + (
            _lame(self.mu, sym.shape) - lam_m * lnJ[..., None, None]
        ) * sym


#: the finite-strain laws by name (``[material] model``; ``linear`` is today's small strain)
HYPERELASTIC_LAWS: dict[str, type[HyperelasticLaw]] = {
    SaintVenantKirchhoffLaw.name: SaintVenantKirchhoffLaw,
    NeoHookeanLaw.name: NeoHookeanLaw,
}


def _parts(mesh: Mesh, law: HyperelasticLaw, cells: np.ndarray | None = None
           ) -> list[tuple[Mesh, HyperelasticLaw, np.ndarray]]:  # fmt: skip
    """The one-type parts of ``mesh`` (only its cells ``cells``, sorted indices; None: all) with the law
    restricted to their cells, and the mesh's numbers of those cells."""
    if mesh.dim == 1:
        raise InputError(f"finite strain ({law.name}) needs a 2D (plane strain) or 3D mesh, not a 1D bar")
    out = []
    for part, cut in mesh.parts():
        ids = np.arange(cut.start, cut.stop)
        if cells is not None:
            keep = np.isin(ids, cells)
            if not keep.any():
                continue
            if not keep.all():
                part, ids = Mesh(part.points, part.cells[keep], part.cell_type), ids[keep]
        lam = law.lam if np.ndim(law.lam) == 0 else np.asarray(law.lam)[ids]
        mu = law.mu if np.ndim(law.mu) == 0 else np.asarray(law.mu)[ids]
        out.append((part, type(law)(lam, mu), ids))
    return out


def deformation_gradients(mesh: Mesh, U: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F, wdet, G) of a one-type mesh: F = I + grad_X u at every quadrature point (e, q, d, d),
    the weights w_q |det J| (e, q) and the reference shape gradients G (e, q, nv, d).  ``U`` (n_nodes d,)
    node-major.  On P1 cells (``ReferenceElement.constant_gradients``) one point per cell (q = 1, its weight the
    cell's measure): F is constant there, so every integrand of F is integrated exactly with a quarter of the
    work (tetrahedra)."""
    wdet, G = geometry(mesh)
    if reference_element(mesh.cell_type).constant_gradients:  # G and F constant on a cell: one point is exact
        wdet, G = wdet.sum(axis=1, keepdims=True), G[:, :1]
    d = mesh.dim
    u = np.asarray(U, dtype=float).reshape(-1, d)[mesh.cells]  # (e, nv, d)
    F = np.matmul(u.transpose(0, 2, 1)[:, None], G) + np.eye(d)  # F_iJ = sum_a u_ai dN_a/dX_J
    return F, wdet, G


def check_orientation(mesh: Mesh, F: np.ndarray, ids: np.ndarray | slice) -> None:
    """:class:`InvertedCellError` naming the first cell where det F <= 0 (an inverted element); ``ids``: the
    mesh's numbers of the cells of F (or their slice)."""
    J = determinants(F)
    bad = ~(J > 0)
    if bad.any():
        e, q = np.argwhere(bad)[0]
        ids = np.arange(ids.start, ids.stop) if isinstance(ids, slice) else ids
        cell = int(ids[e])
        raise InvertedCellError(f"cell {cell} is inverted (det F = {J[e, q]:.3g} <= 0 at quadrature point {q})")


def strain_energy(mesh: Mesh, law: HyperelasticLaw, U: np.ndarray, cells: np.ndarray | None = None) -> float:
    """Pi(U) = int W(F) dX over the reference configuration [energy]."""
    total = 0.0
    for part, part_law, cut in _parts(mesh, law, cells):
        F, wdet, _ = deformation_gradients(part, U)
        check_orientation(part, F, cut)
        total += float(np.sum(wdet * part_law.energy(F)))
    return total


def internal_force(mesh: Mesh, law: HyperelasticLaw, U: np.ndarray, cells: np.ndarray | None = None) -> np.ndarray:
    """f(U) (n_nodes d,) node-major: f_a,i = int (F S)_iJ dN_a/dX_J dX [force]."""
    d = mesh.dim
    f = np.zeros(mesh.n_nodes * d)
    for part, part_law, cut in _parts(mesh, law, cells):
        F, wdet, G = deformation_gradients(part, U)
        check_orientation(part, F, cut)
        P = np.matmul(F, part_law.stress(F))  # first Piola-Kirchhoff
        fe = np.matmul(G, (wdet[..., None, None] * P).transpose(0, 1, 3, 2)).sum(axis=1)  # (e, nv, d)
        f += assemble_nodal(part, fe)
    return f


def tangent_stiffness(
    mesh: Mesh, law: HyperelasticLaw, U: np.ndarray, cells: np.ndarray | None = None
) -> sp.csr_matrix:
    """K(U) = df/dU (n_nodes d)^2, symmetric: the geometric part (grad N_a . S grad N_b) I plus the
    material part B_a^T D B_b, with B (m x d per node, Voigt's order) the variation of the Green-Lagrange
    strain, 2 dE_IJ = F_kI dN_b/dX_J + F_kJ dN_b/dX_I (engineering shears) and D the law's tangent
    CC in Voigt's order [force / length]."""
    mats = []
    for part, part_law, cut in _parts(mesh, law, cells):
        F, wdet, G = deformation_gradients(part, U)
        check_orientation(part, F, cut)
        e, q, nv, d = G.shape
        Ke = np.empty((e, nv, nv, d, d))
        for lo in range(0, e, TANGENT_CHUNK):  # blocks of cells: temporaries of a few MB, not of the mesh's size
            hi = min(lo + TANGENT_CHUNK, e)
            Ke[lo:hi] = _tangent_blocks(part_law.take(lo, hi), F[lo:hi], wdet[lo:hi], G[lo:hi])
        mats.append(assemble_vector(part, Ke))
    return sum_of(mats) if len(mats) > 1 else mats[0]


#: cells per block of :func:`tangent_stiffness`'s element computation
TANGENT_CHUNK = 2048


def _tangent_blocks(law: HyperelasticLaw, F: np.ndarray, wdet: np.ndarray, G: np.ndarray) -> np.ndarray:
    """The element tangents K[e, a, b, i, j] (e, nv, nv, d, d) of cells with deformation gradients F (e, q, d, d),
    weights w |det J| (e, q) and shape gradients G (e, q, nv, d) (:func:`tangent_stiffness`)."""
    S, D = law.stress_and_voigt_tangent(F)
    e, q, nv, d = G.shape
    I, J = VOIGT[d]
    m = I.size
    Ft = np.swapaxes(F, -1, -2)  # Ft[..., I, k] = F_kI
    Gt = np.swapaxes(G, -1, -2)  # Gt[..., J, b] = dN_b/dX_J
    # B[e, q, a, b, k] = F_kI G_bJ + F_kJ G_bI for a = (I, J) (the normal rows counted once)
    B = Ft[:, :, I, None, :] * Gt[:, :, J, :, None]
    B[:, :, d:] += Ft[:, :, J[d:], None, :] * Gt[:, :, I[d:], :, None]
    B = B.reshape(e, q, m, nv * d)
    DB = np.matmul(D, B)  # (e, q, m, nv d)
    B *= wdet[:, :, None, None]
    mat = np.matmul(B.reshape(e, q * m, nv * d).transpose(0, 2, 1), DB.reshape(e, q * m, nv * d))  # (e, nv d, nv d)
    GS = np.matmul(G * wdet[:, :, None, None], S)  # (e, q, nv, d): w G S
    geo = np.matmul(GS.transpose(0, 2, 1, 3).reshape(e, nv, q * d), Gt.reshape(e, q * d, nv))
    Ke = mat.reshape(e, nv, d, nv, d).transpose(0, 1, 3, 2, 4)
    Ke[..., np.arange(d), np.arange(d)] += geo[..., None]
    return Ke


#: |dC|^2 relative to |C_mid|^2 below which the discrete gradient is the midpoint stress (its
#: correction is then round-off divided by round-off)
GONZALEZ_FLOOR = 1e-24


def algorithmic_stress(law: HyperelasticLaw, C0: np.ndarray, C1: np.ndarray) -> np.ndarray:
    """Gonzalez's discrete gradient S_alg (..., d, d) between C0 and C1 (spec 12):

        S_alg = S(C_mid) + 2 [W(C1) - W(C0) - S(C_mid) : dC / 2] dC / (dC : dC),

    C_mid = (C0 + C1)/2, dC = C1 - C0, so that S_alg : dC / 2 = W(C1) - W(C0) exactly.  For Saint
    Venant-Kirchhoff (W quadratic in C) the correction vanishes: S_alg = S(C_mid) = (S(C0) + S(C1))/2."""
    Cm, dC = 0.5 * (C0 + C1), C1 - C0
    S = law.stress_C(Cm)
    if isinstance(law, SaintVenantKirchhoffLaw):
        return S
    dd = np.einsum("...IJ,...IJ->...", dC, dC)
    gap = law.energy_difference_C(C0, C1) - 0.5 * np.einsum("...IJ,...IJ->...", S, dC)
    small = dd <= GONZALEZ_FLOOR * np.einsum("...IJ,...IJ->...", Cm, Cm)
    factor = np.where(small, 0.0, 2.0 * gap / np.where(small, 1.0, dd))
    return S + factor[..., None, None] * dC


def algorithmic_force(
    mesh: Mesh, law: HyperelasticLaw, U0: np.ndarray, U1: np.ndarray, cells: np.ndarray | None = None
) -> np.ndarray:
    """The energy-momentum step's internal force (n_nodes d,): f_a = int F_mid S_alg grad N_a dX,
    F_mid = I + grad (U0 + U1)/2 (spec 12).  f . (U1 - U0) = Pi(U1) - Pi(U0) to round-off, and
    sum f_a = 0, sum x_mid,a x f_a = 0 (x_mid = X + (U0 + U1)/2): a free body keeps its energy and
    its linear and angular momentum."""
    d = mesh.dim
    f = np.zeros(mesh.n_nodes * d)
    for part, part_law, cut in _parts(mesh, law, cells):
        F0, wdet, G = deformation_gradients(part, U0)
        F1, _, _ = deformation_gradients(part, U1)
        check_orientation(part, F0, cut)
        check_orientation(part, F1, cut)
        S = algorithmic_stress(part_law, _green(F0)[0], _green(F1)[0])
        P = np.matmul(0.5 * (F0 + F1), S)
        f += assemble_nodal(part, np.matmul(G, (wdet[..., None, None] * P).transpose(0, 1, 3, 2)).sum(1))
    return f


def _out_of_plane_stress(law: HyperelasticLaw, C: np.ndarray) -> np.ndarray:
    """S_33 (...) of plane strain (F_33 = 1, E_33 = 0) [stress]: lam tr E (Saint Venant-Kirchhoff),
    lam ln J (Neo-Hookean)."""
    shape = C.shape[:-2]
    lam = _lame(law.lam, shape)
    if isinstance(law, SaintVenantKirchhoffLaw):
        return lam * 0.5 * (np.trace(C, axis1=-2, axis2=-1) - C.shape[-1])
    return lam * 0.5 * np.log(determinants(C))


def cell_fields(mesh: Mesh, law: HyperelasticLaw, U: np.ndarray, cells: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Per cell of ``cells`` (None: every cell), volume-weighted means over its quadrature points:
    (ids (k,), Cauchy stress sigma = F S F^T / J (k, 3, 3) in the current configuration, Green-Lagrange
    strain E (k, 3, 3) and stored energy density W (k,) [stress, 1, energy / volume]).  Plane strain: the
    out-of-plane sigma_33 = S_33 / J, E_33 = 0."""
    ids_all, sig_all, E_all, W_all = [], [], [], []
    for part, part_law, ids in _parts(mesh, law, cells):
        F, wdet, _ = deformation_gradients(part, U)
        check_orientation(part, F, ids)
        d = mesh.dim
        C, E = _green(F)
        S = part_law.stress_C(C)
        J = determinants(F)
        sig = np.zeros(F.shape[:2] + (3, 3))
        sig[..., :d, :d] = np.einsum("eqiI,eqIJ,eqjJ->eqij", F, S, F) / J[..., None, None]
        if d == 2:
            sig[..., 2, 2] = _out_of_plane_stress(part_law, C) / J
        E3 = np.zeros_like(sig)
        E3[..., :d, :d] = E
        w = wdet / wdet.sum(axis=1, keepdims=True)
        ids_all.append(ids)
        sig_all.append(np.einsum("eq,eqij->eij", w, sig))
        E_all.append(np.einsum("eq,eqij->eij", w, E3))
        W_all.append(np.einsum("eq,eq->e", w, part_law.energy_C(C)))
    return tuple(np.concatenate(a) for a in (ids_all, sig_all, E_all, W_all))


def von_mises_of(sigma: np.ndarray) -> np.ndarray:
    """sqrt(3/2 s:s) of 3 x 3 stresses (..., 3, 3), s the deviator [stress]."""
    dev = sigma - np.trace(sigma, axis1=-2, axis2=-1)[..., None, None] / 3.0 * np.eye(3)
    return np.sqrt(1.5 * np.einsum("...ij,...ij->...", dev, dev))
