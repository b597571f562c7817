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

import hashlib
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import scipy.sparse as sp

from ..errors import InputError, NonFiniteError
from .assembly import assemble_nodal, assemble_vector, geometry, gradient_operator, sum_of
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
class TangentTerms:
    """dP/dF of a law at points (...) as the sum of the forms that the tangent assembly contracts with the shape
    gradients in a few matrix products (:func:`tangent_stiffness`) instead of a 9 x 9 (3D) tensor per point:

        A_iJjL = a M_iJ N_jL  +  c Q_iL R_jJ  +  delta_ij T_JL  +  B_ij delta_JL,

    ``outer`` = (a, M, N), ``crossed`` = (c, Q, R), ``geometric`` = T, ``spatial`` = B; a, c numbers or arrays
    broadcasting to the points (...), the others (..., d, d) [stress] (T, B: None when absent).  Over a cell,
    with V^X = X grad N^T (V^X_ia = X_iJ dN_a/dX_J), the block of nodes a, b and components i, j is
    sum_q w_q [a V^M_ia V^N_jb + c V^Q_ib V^R_ja + delta_ij (G T G^T)_ab + B_ij (G G^T)_ab]."""

    outer: tuple[float | np.ndarray, np.ndarray, np.ndarray]
    crossed: tuple[float | np.ndarray, np.ndarray, np.ndarray]
    geometric: np.ndarray | None = None
    spatial: np.ndarray | None = None

    def tensor(self) -> np.ndarray:
        """A (..., d, d, d, d), indices i, J, j, L."""
        (a, M, N), (c, Q, R) = self.outer, self.crossed
        s = (Ellipsis,) + (None,) * 4
        A = np.asarray(a)[s] * M[..., :, :, None, None] * N[..., None, None, :, :]
        A += np.asarray(c)[s] * Q[..., :, None, None, :] * np.swapaxes(R, -1, -2)[..., None, :, :, None]
        d = M.shape[-1]
        for i in range(d):
            if self.geometric is not None:
                A[..., i, :, i, :] += self.geometric
            if self.spatial is not None:
                A[..., :, i, :, i] += self.spatial
        return A


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

    def piola(self, F: np.ndarray, grad: np.ndarray | None = None) -> np.ndarray:
        """The first Piola-Kirchhoff stress P = F S (..., d, d) [stress]; ``grad`` = F - I, the displacement
        gradient as computed (None: F - I here), from which the strain is formed without cancellation:
        E = (grad + grad^T + grad^T grad) / 2 (at the small strains of a stiff body, E from F^T F - I keeps
        eps / |E| of its digits: a steel beam under its weight, 1e-11 of the stress)."""
        return _mm(F, self.stress_E(_strain(F, grad)))

    def stress_E(self, E: np.ndarray) -> np.ndarray:
        """S (..., d, d) from the Green-Lagrange strain E [stress]."""
        return self.stress_C(2.0 * E + np.eye(E.shape[-1]))

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

    def tangent_terms(self, F: np.ndarray) -> TangentTerms:
        """dP/dF, the derivative of the first Piola-Kirchhoff stress P = F S, as :class:`TangentTerms` (laws
        give it in closed form from their invariants)."""
        raise NotImplementedError

    def piola_and_tangent(self, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(P (..., d, d), A (..., d, d, d, d)): P and A_iJjL = dP_iJ / dF_jL = F_iI CC_IJKL F_jK + delta_ij S_JL
        [stress] (major symmetry A_iJjL = A_jLiJ), the tensor of :meth:`tangent_terms`."""
        return self.piola(F), self.tangent_terms(F).tensor()

    def energy_C(self, C: np.ndarray) -> np.ndarray:
        """W as a function of the right Cauchy-Green tensor C (..., d, d)."""
        raise NotImplementedError

    def stress_C(self, C: np.ndarray) -> np.ndarray:
        """S = 2 dW/dC (..., d, d)."""
        raise NotImplementedError

    def tangent_C(self, C: np.ndarray) -> np.ndarray:
        """CC = 4 d^2W/dC^2 (..., d, d, d, d)."""
        raise NotImplementedError


def _inv(A: np.ndarray) -> np.ndarray:
    """A^-1 (..., d, d) of 2 x 2 or 3 x 3 matrices: the adjugate over the determinant."""
    if A.shape[-1] == 2:
        det = determinants(A)
        inv = np.empty_like(A, dtype=float)  # in A's memory order, as below
        inv[..., 0, 0], inv[..., 0, 1] = A[..., 1, 1] / det, -A[..., 0, 1] / det
        inv[..., 1, 0], inv[..., 1, 1] = -A[..., 1, 0] / det, A[..., 0, 0] / det
        return inv
    (a, b, c), (d, e, f), (g, h, i) = (tuple(A[..., r, k] for k in range(3)) for r in range(3))
    adj = np.empty_like(A, dtype=float)  # the cofactors' transpose, row by row (in A's memory order)
    adj[..., 0, 0], adj[..., 0, 1], adj[..., 0, 2] = e * i - f * h, c * h - b * i, b * f - c * e
    adj[..., 1, 0], adj[..., 1, 1], adj[..., 1, 2] = f * g - d * i, a * i - c * g, c * d - a * f
    adj[..., 2, 0], adj[..., 2, 1], adj[..., 2, 2] = d * h - e * g, b * g - a * h, a * e - b * d
    det = a * adj[..., 0, 0] + b * adj[..., 1, 0] + c * adj[..., 2, 0]
    adj /= det[..., None, None]
    return adj


def _mm(A: np.ndarray, B: np.ndarray, transpose_a: bool = False) -> np.ndarray:
    """A B (or A^T B) of stacks of small matrices (..., d, d), entry by entry: C_ik = sum_j A_ij B_jk, in A's memory
    order.  On the component-major stacks of :func:`displacement_gradients` (each entry contiguous over the cells)
    a product is 9 x 3 vector operations: 92 against 418 us for numpy's batched ``matmul`` on 3,208 tetrahedra
    (docs/performance.md)."""
    d = A.shape[-1]
    At = np.swapaxes(A, -1, -2) if transpose_a else A
    out = np.empty_like(A, shape=np.broadcast_shapes(A.shape, B.shape), dtype=float)
    for i in range(d):
        for k in range(d):
            acc = At[..., i, 0] * B[..., 0, k]
            for j in range(1, d):
                acc += At[..., i, j] * B[..., j, k]
            out[..., i, k] = acc
    return out


def _ddot(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A : B = sum_IJ A_IJ B_IJ (...) of stacks of small matrices (..., d, d)."""
    d = A.shape[-1]
    acc = np.zeros(np.broadcast_shapes(A.shape, B.shape)[:-2])
    for i in range(d):
        for j in range(d):
            acc += A[..., i, j] * B[..., i, j]
    return acc


def _green(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(C, E): the right Cauchy-Green tensor F^T F and the Green-Lagrange strain (C - I)/2."""
    C = _mm(F, F, transpose_a=True)
    return C, 0.5 * (C - np.eye(F.shape[-1]))


def _strain(F: np.ndarray, grad: np.ndarray | None) -> np.ndarray:
    """E = (H + H^T + H^T H) / 2 with H = ``grad`` (F - I when None)."""
    H = F - np.eye(F.shape[-1]) if grad is None else grad
    return 0.5 * (H + np.swapaxes(H, -1, -2) + _mm(H, H, transpose_a=True))


def _log_det(F: np.ndarray, grad: np.ndarray | None) -> np.ndarray:
    """ln det F with det F - 1 from the invariants of H = ``grad`` = F - I (log1p: no cancellation near 1):
    det(I + H) - 1 = tr H + det H in 2D, tr H + ((tr H)^2 - tr H^2) / 2 + det H in 3D (written per entry)."""
    if grad is None:
        return np.log(determinants(F))
    if grad.shape[-1] == 2:
        a, b, c, d = grad[..., 0, 0], grad[..., 0, 1], grad[..., 1, 0], grad[..., 1, 1]
        return np.log1p(a + d + (a * d - b * c))
    a, b, c = grad[..., 0, 0], grad[..., 0, 1], grad[..., 0, 2]
    d, e, f = grad[..., 1, 0], grad[..., 1, 1], grad[..., 1, 2]
    g, h, i = grad[..., 2, 0], grad[..., 2, 1], grad[..., 2, 2]
    ei_fh, di_fg, dh_eg = e * i - f * h, d * i - f * g, d * h - e * g
    second = a * e + a * i + e * i - b * d - c * g - f * h
    return np.log1p((a + e + i) + second + (a * ei_fh - b * di_fg + c * dh_eg))


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
        return 0.5 * lam * trE**2 + mu * _ddot(E, E)

    def stress_C(self, C: np.ndarray) -> np.ndarray:
        return self.stress_E(0.5 * (C - np.eye(C.shape[-1])))

    def stress_E(self, E: np.ndarray) -> np.ndarray:
        trE = np.trace(E, axis1=-2, axis2=-1)
        S = (2.0 * _lame(self.mu, E.shape)) * E  # in E's memory order (a sum with lam tr(E) I would not keep it)
        lam_trE = _lame(self.lam, trE.shape) * trE
        for i in range(E.shape[-1]):
            S[..., i, i] += lam_trE
        return S

    def tangent_C(self, C: np.ndarray) -> np.ndarray:
        d = C.shape[-1]
        shape = C.shape[:-2] + (d, d, d, d)
        lam, mu = _lame(self.lam, shape), _lame(self.mu, shape)
        eye = np.eye(d)
        base = lam * np.einsum("IJ,KL->IJKL", eye, eye) + mu * _symmetric_identity(d)
        return np.broadcast_to(base, shape)

    def tangent_terms(self, F: np.ndarray) -> TangentTerms:
        """A_iJjL = lam F_iJ F_jL + mu F_iL F_jJ + mu b_ij delta_JL + delta_ij S_JL, b = F F^T."""
        S = self.stress_C(_green(F)[0])
        lam, mu = _lame(self.lam, F.shape[:-2]), _lame(self.mu, F.shape[:-2])
        b = np.matmul(F, np.ascontiguousarray(np.swapaxes(F, -1, -2)))
        spatial = np.asarray(mu)[..., None, None] * b
        return TangentTerms(outer=(lam, F, F), crossed=(mu, F, F), geometric=S, spatial=spatial)


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
        det(I + X) - 1 from the invariants of X (log1p): no difference of two large energies.  C0^-1 by cofactors
        (:func:`_inv`; numpy's batched solve of 3 x 3 systems cost 6x more: docs/performance.md)."""
        d = C0.shape[-1]
        X = _mm(_inv(C0), C1 - C0)
        trX = np.trace(X, axis1=-2, axis2=-1)
        detX = determinants(X)
        if d == 2:
            rest = trX + detX
        else:
            rest = trX + 0.5 * (trX**2 - _ddot(X, np.swapaxes(X, -1, -2))) + detX
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

    def piola(self, F: np.ndarray, grad: np.ndarray | None = None) -> np.ndarray:
        """P = mu (F - H) + lam ln(J) H, H = F^-T (no C and no C^-1).  With ``grad`` = F - I as computed, F - H =
        grad + (F^-1 grad)^T (as I - F^-1 = F^-1 grad) and ln J = log1p(det F - 1) from grad's invariants: no
        difference of numbers near 1 (the base class's ``piola``)."""
        Fi = _inv(F)
        H = np.swapaxes(Fi, -1, -2)
        lam, mu = _lame(self.lam, F.shape), _lame(self.mu, F.shape)
        if grad is None:
            return mu * (F - H) + (lam * np.log(determinants(F))[..., None, None]) * H
        return mu * (grad + np.swapaxes(_mm(Fi, grad), -1, -2)) + (lam * _log_det(F, grad)[..., None, None]) * H

    def tangent_terms(self, F: np.ndarray) -> TangentTerms:
        """A_iJjL = lam H_iJ H_jL + (mu - lam ln J) H_iL H_jJ + mu delta_ij delta_JL,
        H = F^-T (plane strain: F_33 = 1 leaves the in-plane block of the same form)."""
        H = np.swapaxes(_inv(F), -1, -2)
        lam, mu = _lame(self.lam, F.shape[:-2]), _lame(self.mu, F.shape[:-2])
        geometric = np.broadcast_to(np.asarray(mu)[..., None, None] * np.eye(F.shape[-1]), F.shape)
        return TangentTerms(outer=(lam, H, H), crossed=(mu - lam * np.log(determinants(F)), H, H), geometric=geometric)


#: the finite-strain laws by name (``[material] model``; ``linear`` is today's small strain)
HYPERELASTIC_LAWS: dict[str, type[HyperelasticLaw]] = {
    SaintVenantKirchhoffLaw.name: SaintVenantKirchhoffLaw,
    NeoHookeanLaw.name: NeoHookeanLaw,
}


def _parts(
    mesh: Mesh, law: HyperelasticLaw, cells: np.ndarray | None = None
) -> list[tuple[Mesh, HyperelasticLaw, np.ndarray]]:
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
            if not keep.all():  # kept with the mesh (its geometry and gradient operator are built once)
                key = f"law part {cut.start} " + hashlib.blake2b(np.ascontiguousarray(cells).tobytes()).hexdigest()
                part, ids = mesh.cached(key, lambda p=part, k=keep: Mesh(p.points, p.cells[k], p.cell_type)), ids[keep]
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
    grad, wdet, G = displacement_gradients(mesh, U)
    return grad + np.eye(mesh.dim), wdet, G


def displacement_gradients(mesh: Mesh, U: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(grad_X u, wdet, G): :func:`deformation_gradients` with F - I as summed from the nodes (the strain of a stiff
    body is formed from it without cancellation, not from F)."""
    wdet, G = geometry(mesh)
    if reference_element(mesh.cell_type).constant_gradients:  # G and F constant on a cell: one point is exact
        wdet, G = mesh.cached("one-point geometry", lambda: (wdet.sum(axis=1, keepdims=True), G[:, :1].copy()))
    d = mesh.dim
    e, q, nv, _ = G.shape
    if q == 1:  # F_iJ = delta_iJ + (D U)_iJe: one sparse product (measured: 0.37 against 1.0 ms on 5,740 tetrahedra)
        D = _gradient_operator(mesh, G)
        return _by_cell((D @ np.asarray(U, dtype=float)).reshape(d, d, e, 1)), wdet, G
    u = np.asarray(U, dtype=float).reshape(-1, d)[mesh.cells]  # (e, nv, d)
    Gr = _gradients_by_cell(mesh, G)
    # F_iJ = sum_a u_ai dN_a/dX_J at every point: one (d, nv) x (nv, q d) product per cell (measured: 1.5 against 2.9
    # ms with a product per point, 5,120 hexahedra)
    grad = np.matmul(u.transpose(0, 2, 1), Gr).reshape(e, d, q, d)
    return _by_cell(np.ascontiguousarray(grad.transpose(1, 3, 0, 2))), wdet, G  # component-major, as on P1 cells


def _gradients_by_cell(mesh: Mesh, G: np.ndarray) -> np.ndarray:
    """(e, nv, q d) the shape gradients of ``G`` (e, q, nv, d) by cell, [a, (q, J)], kept with the mesh."""
    e, q, nv, d = G.shape
    return mesh.cached("gradients by cell", lambda: np.ascontiguousarray(G.transpose(0, 2, 1, 3).reshape(e, nv, q * d)))


def _gradient_operator(mesh: Mesh, G: np.ndarray) -> sp.csr_matrix:
    """D of a one-point (P1) mesh, kept with it: D (d d e, n_nodes d) with (D U)_(i,J,e) = sum_a u_ai dN_a/dX_J on
    cell e [1/length], its rows component-major (each entry of grad u contiguous over the cells: :func:`_by_cell`):
    the deformation gradient's F - I, and D^T (w P) the internal force; ``G`` (e, 1, nv, d) its shape gradients.
    36 nonzeros per tetrahedron (12 per triangle); D^T is applied as D.T (not stored: 0.23 against 0.17 ms on
    5,740 tetrahedra, half the memory)."""

    def build() -> sp.csr_matrix:
        e, _, _, d = G.shape
        D = gradient_operator(mesh.cells, G[:, 0], mesh.n_nodes)  # rows (e, i, J)
        return D[np.arange(e * d * d).reshape(e, d, d).transpose(1, 2, 0).ravel()]

    return mesh.cached("gradient operator by entry", build)


def _by_cell(values: np.ndarray) -> np.ndarray:
    """The view (e, q, d, d) of component-major ``values`` (d, d, e, q): the layout of every array of F on P1 cells,
    which the element-wise formulas (:func:`_mm`, :func:`_inv`, the laws) keep."""
    return np.moveaxis(values, (0, 1), (-2, -1))


def _by_entry(values: np.ndarray) -> np.ndarray:
    """The flat component-major vector (d d e q,) of ``values`` (e, q, d, d): the right-hand side of D^T
    (no copy when ``values`` is laid out as :func:`_by_cell` gives)."""
    return np.moveaxis(values, (-2, -1), (0, 1)).ravel()


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
        grad, wdet, G = displacement_gradients(part, U)
        F = grad + np.eye(d)
        check_orientation(part, F, cut)
        P = part_law.piola(F, grad)
        f += _nodal_force(part, wdet[..., None, None] * P, G)
    return f


def _nodal_force(mesh: Mesh, wP: np.ndarray, G: np.ndarray) -> np.ndarray:
    """f (n_nodes d,) with f_a,i = sum_q,J dN_a/dX_J (w P)_iJ over the cells of a one-type ``mesh`` [force]: ``wP``
    (e, q, d, d) a first Piola stress times the points' weights, ``G`` (e, q, nv, d) the shape gradients."""
    e, q, nv, d = G.shape
    if q == 1:  # one point (simplices): f = D^T (w P), the gradient operator's transpose
        return _gradient_operator(mesh, G).T @ _by_entry(wP)
    # one (nv, q d) x (q d, d) product per cell
    Gr = _gradients_by_cell(mesh, G)
    return assemble_nodal(mesh, np.matmul(Gr, np.ascontiguousarray(wP.transpose(0, 1, 3, 2).reshape(e, q * d, d))))


def tangent_stiffness(
    mesh: Mesh, law: HyperelasticLaw, U: np.ndarray, cells: np.ndarray | None = None, project: bool = False
) -> sp.csr_matrix:
    """K(U) = df/dU (n_nodes d)^2, symmetric: K_ai,bj = int dN_a/dX_J A_iJjL dN_b/dX_L dX with A = dP/dF the
    law's :class:`TangentTerms` (the material part F CC F plus the geometric delta_ij S), contracted per block of
    cells by :func:`_element_tangents` [force / length].  ``project``: each cell's matrix K_e (nv d x nv d) made
    positive semi-definite, V max(Lambda, 0) V^T from its eigen-decomposition K_e = V Lambda V^T
    (:func:`project_psd`; Teran et al. 2005), so that the assembled K is too."""
    mats = []
    for part, part_law, cut in _parts(mesh, law, cells):
        F, wdet, G = deformation_gradients(part, U)
        check_orientation(part, F, cut)
        F = np.ascontiguousarray(F)  # cell-major: the blocks below are cells, their products numpy's batched ones
        e, q, nv, d = G.shape
        if _shared_geometry(part, wdet, G):  # translates of one cell: the shape gradients of the first serve all
            wdet, G = wdet[:1], G[:1]
        K = np.empty((e, d, d, nv, nv))
        for lo in range(0, e, TANGENT_CHUNK):  # blocks of cells: temporaries of a few MB, not of the mesh's size
            hi = min(lo + TANGENT_CHUNK, e)
            one = slice(0, 1) if G.shape[0] == 1 else slice(lo, hi)
            terms = part_law.take(lo, hi).tangent_terms(F[lo:hi])
            _element_tangents(terms, wdet[one], G[one], K[lo:hi])
            if project:
                project_psd(K[lo:hi])
        mats.append(assemble_vector(part, K.transpose(0, 3, 4, 1, 2)))
    return sum_of(mats) if len(mats) > 1 else mats[0]


def project_psd(K: np.ndarray) -> int:
    """Make each cell's tangent positive semi-definite, in place: K (e, d, d, nv, nv) as the (nv d)-square matrix
    of each cell, its eigenvalues below 0 set to 0 (the nearest PSD matrix in the Frobenius norm).  Only the cells
    with an eigenvalue below -1e-12 of their largest are rewritten; returns their number."""
    e, d, _, nv, _ = K.shape
    A = K.transpose(0, 3, 1, 4, 2).reshape(e, nv * d, nv * d)  # rows (a, i), columns (b, j)
    A = 0.5 * (A + np.swapaxes(A, 1, 2))
    w, V = np.linalg.eigh(A)
    bad = w[:, 0] < -1e-12 * np.abs(w).max(axis=1)
    if bad.any():
        Vb = V[bad]
        fixed = np.matmul(Vb * np.maximum(w[bad], 0.0)[:, None, :], np.swapaxes(Vb, 1, 2))
        K[bad] = fixed.reshape(-1, nv, d, nv, d).transpose(0, 2, 4, 1, 3)
    return int(bad.sum())


def _shared_geometry(mesh: Mesh, wdet: np.ndarray, G: np.ndarray) -> bool:
    """Whether every cell's weights and shape gradients (those the force uses too: the mesh's cached geometry)
    are the first cell's to 1e-12 (cells that are translates of one another), kept with that geometry."""

    def check() -> bool:
        if G.shape[0] < 2:
            return False
        spread = float(np.ptp(G, axis=0).max()), float(np.ptp(wdet, axis=0).max())
        return spread[0] <= 1e-12 * float(np.abs(G[0]).max()) and spread[1] <= 1e-12 * float(np.abs(wdet[0]).max())

    return mesh.cached(f"shared geometry {G.shape[1]}", check)


#: cells per block of :func:`tangent_stiffness`'s element computation
TANGENT_CHUNK = 512


def _element_tangents(terms: TangentTerms, w: np.ndarray, G: np.ndarray, out: np.ndarray) -> None:
    """The element tangents K[e, i, j, a, b] (``out``, (e, d, d, nv, nv)) of cells with dP/dF ``terms`` at their
    points (e, q, ...), weights w |det J| (e, q) and shape gradients G (e, q, nv, d) (both with e = 1 when the
    cells are translates of one another: the products with them are then one matrix product for all cells):

        K[e, i, j, a, b] = sum_q w_q [a V^M_ia V^N_jb + c V^Q_ib V^R_ja + delta_ij (G T G^T)_ab + B_ij (G G^T)_ab],

    V^X = X G^T (d x nv per point), :class:`TangentTerms`' notation; each term a product over q per cell and
    component pair, written in the order the assembly reads (a block (i, j) contiguous per cell)."""
    (a, M, N), (c, Q, R) = terms.outer, terms.crossed
    e, q, d = M.shape[0], M.shape[1], M.shape[-1]
    nv = G.shape[2]
    Gt = np.swapaxes(G, -1, -2)  # (., q, d, nv)
    V: dict[int, np.ndarray] = {}

    def columns(X: np.ndarray) -> np.ndarray:  # V^X (e, q, d, nv), once per distinct array of the terms
        if id(X) not in V:
            V[id(X)] = np.matmul(X, Gt)
        return V[id(X)]

    def left(X: np.ndarray, scale) -> np.ndarray:  # scale w V^X as (e, d, nv, q)
        return (columns(X) * (w * np.broadcast_to(scale, (e, q)))[:, :, None, None]).transpose(0, 2, 3, 1)

    def right(X: np.ndarray) -> np.ndarray:  # V^X as (e, d, q, nv)
        return columns(X).transpose(0, 2, 1, 3)

    np.matmul(left(M, a)[:, :, None], right(N)[:, None], out=out)
    out += np.matmul(left(R, c)[:, None], right(Q)[:, :, None])  # [i, j, a, b] = sum_q w c V^R_ja V^Q_ib
    w4 = w[:, :, None, None]
    common = G.shape[0] == 1  # the cells' translates: products with G are one matrix product for all
    if terms.geometric is not None:  # g_ab = sum_q w_q (G T G^T)_ab
        T = terms.geometric
        if common:  # sum_(q, J, L) T_qJL P_qJLab, P_qJLab = w_q dN_a/dX_J dN_b/dX_L
            P = w[0, :, None, None, None, None] * Gt[0, :, :, None, :, None] * Gt[0, :, None, :, None, :]
            g = T.reshape(e, q * d * d) @ P.reshape(q * d * d, nv * nv)
        else:
            GT = np.matmul(G * w4, T)  # (e, q, nv, d)
            g = np.matmul(GT.transpose(0, 2, 1, 3).reshape(e, nv, q * d), Gt.reshape(e, q * d, nv))
        g = g.reshape(e, nv, nv)
        for i in range(d):
            out[:, i, i] += g
    if terms.spatial is not None:  # B_ij sum_q w_q (G G^T)_ab
        lap = np.matmul(G * w4, Gt).reshape(G.shape[0], q, nv * nv)
        B = terms.spatial.reshape(e, q, d * d).transpose(0, 2, 1)  # (e, d d, q)
        sB = np.matmul(B.reshape(e * d * d, q), lap[0]) if common else np.matmul(B, lap)
        out += sB.reshape(e, d, d, nv, nv)


#: |dC|^2 relative to |C_mid|^2 below which the discrete gradient is the midpoint stress (its
#: correction is then round-off divided by round-off)
GONZALEZ_FLOOR = 1e-24


def _gonzalez(law: HyperelasticLaw, C0: np.ndarray, C1: np.ndarray) -> tuple:
    """(C_mid, dC, S(C_mid), phi, gap, |dC|^2 or 1 where cut off, cut off) of Gonzalez's discrete gradient
    S_alg = S(C_mid) + phi dC, phi = 2 gap / (dC:dC), gap = W(C1) - W(C0) - S(C_mid):dC/2 (:func:`algorithmic_stress`);
    phi = gap = 0 for Saint Venant-Kirchhoff (W quadratic in C) and where |dC|^2 <= GONZALEZ_FLOOR |C_mid|^2 (the
    correction there is round-off divided by round-off)."""
    Cm, dC = 0.5 * (C0 + C1), C1 - C0
    S = law.stress_C(Cm)
    zero = np.zeros(S.shape[:-2])
    if isinstance(law, SaintVenantKirchhoffLaw):
        return Cm, dC, S, zero, zero, np.ones_like(zero), np.ones(zero.shape, dtype=bool)
    dd = _ddot(dC, dC)
    small = dd <= GONZALEZ_FLOOR * _ddot(Cm, Cm)
    gap = np.where(small, 0.0, law.energy_difference_C(C0, C1) - 0.5 * _ddot(S, dC))
    safe = np.where(small, 1.0, dd)
    return Cm, dC, S, 2.0 * gap / safe, gap, safe, small


def algorithmic_stress(law: HyperelasticLaw, C0: np.ndarray, C1: np.ndarray) -> np.ndarray:
    """Gonzalez's discrete gradient S_alg (..., d, d) between C0 and C1 (spec 12):

        S_alg = S(C_mid) + 2 [W(C1) - W(C0) - S(C_mid) : dC / 2] dC / (dC : dC),

    C_mid = (C0 + C1)/2, dC = C1 - C0, so that S_alg : dC / 2 = W(C1) - W(C0) exactly.  For Saint
    Venant-Kirchhoff (W quadratic in C) the correction vanishes: S_alg = S(C_mid) = (S(C0) + S(C1))/2."""
    _, dC, S, phi, *_ = _gonzalez(law, C0, C1)
    return S + phi[..., None, None] * dC


def algorithmic_force(
    mesh: Mesh,
    law: HyperelasticLaw,
    U0: np.ndarray,
    U1: np.ndarray,
    cells: np.ndarray | None = None,
    level: dict | None = None,
) -> np.ndarray:
    """The energy-momentum step's internal force (n_nodes d,): f_a = int F_mid S_alg grad N_a dX,
    F_mid = I + grad (U0 + U1)/2 (spec 12).  f . (U1 - U0) = Pi(U1) - Pi(U0) to round-off, and
    sum f_a = 0, sum x_mid,a x f_a = 0 (x_mid = X + (U0 + U1)/2): a free body keeps its energy and
    its linear and angular momentum.  ``level``: a dict kept by the caller for one U0 (a step's Newton
    iterates), holding each part's F0 and C0 once formed (the same values: each is formed once a step)."""
    d = mesh.dim
    f = np.zeros(mesh.n_nodes * d)
    for j, (part, part_law, cut) in enumerate(_parts(mesh, law, cells)):
        if level is not None and j in level:
            F0, C0 = level[j]
        else:
            F0 = deformation_gradients(part, U0)[0]
            check_orientation(part, F0, cut)
            C0 = _green(F0)[0]
            if level is not None:
                level[j] = (F0, C0)
        F1, wdet, G = deformation_gradients(part, U1)
        check_orientation(part, F1, cut)
        S = algorithmic_stress(part_law, C0, _green(F1)[0])
        f += _nodal_force(part, wdet[..., None, None] * _mm(0.5 * (F0 + F1), S), G)
    return f


def algorithmic_tangent(
    mesh: Mesh, law: HyperelasticLaw, U0: np.ndarray, U1: np.ndarray, cells: np.ndarray | None = None
) -> sp.csr_matrix:
    """The exact Jacobian J = d f / d U1 (n_nodes d)^2 of :func:`algorithmic_force` at fixed U0 [force / length];
    not symmetric (Gonzalez's correction and the mixed F_mid, F1 below).  With P_alg = F_mid S_alg, C = F^T F,
    C_mid = (C0 + C1)/2, dC = C1 - C0, S_alg = S(C_mid) + phi dC, phi = 2 gap / (dC:dC),
    gap = W(C1) - W(C0) - S(C_mid):dC/2 (:func:`algorithmic_stress`), and dC1 = 2 sym(F1^T dF1):

        dP_alg/dF1 = 1/2 delta_ij S_alg,JL + 2 F_mid,iI A_IJKL F1,jK,
        A = CC(C_mid)/4 + phi I_sym + dC (x) h,
        h = (2 / dC:dC) [(S(C1) - S(C_mid))/2 - CC(C_mid):dC/8] - (4 gap / (dC:dC)^2) dC,

    CC = dS/dE the law's tangent, I_sym the symmetric fourth-order identity (h = 0 where the correction is cut
    off, :data:`GONZALEZ_FLOOR`; A = CC/4 for Saint Venant-Kirchhoff).  At U1 = U0 it is half the tangent
    stiffness.  A dense dP/dF per point contracted with the shape gradients (a Newton step's direction once its
    approximate tangent converges slowly: docs/finite_strain.md)."""
    mats = []
    for part, part_law, cut in _parts(mesh, law, cells):
        F0, wdet, G = deformation_gradients(part, U0)
        F1, _, _ = deformation_gradients(part, U1)
        check_orientation(part, F0, cut)
        check_orientation(part, F1, cut)
        e, q, nv, d = G.shape
        K = np.empty((e, d, d, nv, nv))
        half_sym = 0.5 * _symmetric_identity(d)
        for lo in range(0, e, TANGENT_CHUNK):
            hi = min(lo + TANGENT_CHUNK, e)
            sub = part_law.take(lo, hi)
            a0, a1 = F0[lo:hi], F1[lo:hi]
            C0, C1 = _green(a0)[0], _green(a1)[0]
            Cm, dC, Sm, phi, gap, safe, small = _gonzalez(sub, C0, C1)
            CC = sub.tangent_C(Cm)
            S_alg = Sm + phi[..., None, None] * dC
            A = 0.25 * CC
            if not isinstance(sub, SaintVenantKirchhoffLaw):
                h = (2.0 / safe)[..., None, None] * (
                    0.5 * (sub.stress_C(C1) - Sm) - 0.125 * np.einsum("...IJKL,...KL->...IJ", CC, dC)
                )
                h -= (4.0 * gap / (safe * safe))[..., None, None] * dC
                h = np.where(small[..., None, None], 0.0, h)
                A = A + phi[..., None, None, None, None] * half_sym
                A = A + dC[..., :, :, None, None] * h[..., None, None, :, :]
            Fm = 0.5 * (a0 + a1)
            T = 2.0 * np.einsum("...iI,...IJKL,...jK->...iJjL", Fm, A, a1)
            for i in range(d):
                T[..., i, :, i, :] += 0.5 * S_alg
            w = wdet[lo:hi]
            g = G[lo:hi]
            K[lo:hi] = np.einsum("eq,eqaJ,eqiJjL,eqbL->eijab", w, g, T, g, optimize=True)
        mats.append(assemble_vector(part, K.transpose(0, 3, 4, 1, 2)))
    return sum_of(mats) if len(mats) > 1 else mats[0]


def _out_of_plane_stress(law: HyperelasticLaw, C: np.ndarray) -> np.ndarray:
    """S_33 (...) of plane strain (F_33 = 1, E_33 = 0) [stress]: lam tr E (Saint Venant-Kirchhoff),
    lam ln J (Neo-Hookean)."""
    shape = C.shape[:-2]
    lam = _lame(law.lam, shape)
    if isinstance(law, SaintVenantKirchhoffLaw):
        return lam * 0.5 * (np.trace(C, axis1=-2, axis2=-1) - C.shape[-1])
    return lam * 0.5 * np.log(determinants(C))


def cell_fields(
    mesh: Mesh, law: HyperelasticLaw, U: np.ndarray, cells: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
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
