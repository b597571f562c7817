"""The body's elastic response: the internal force, its energy and its tangent (linear or finite strain).

Every place that needs the elastic force of a level (a step's balance, its energy, the reactions of
the Dirichlet tags, the residual at t = 0) asks the run's :class:`Elasticity` (``ctx.elastic``):

    linear        f(U) = S U,                 Pi(U) = 1/2 U.SU,  K = S
    finite strain f(U) = int F S(E) grad N,   Pi(U) = int W(E),  K(U) = df/dU   (Total Lagrangian)

with the hyperelastic laws of :mod:`signorini.fem.hyperelastic` on the cells whose material model
is not ``linear`` and S U on the others (regions may mix models).  ``linear`` everywhere (the
default) keeps every product as before: ``f(U)`` is the cached product ``S @ U``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp

from ...fem.assembly import stiffness_matrix
from ...fem.dofmap import block_of
from ...fem.hyperelastic import (
    HYPERELASTIC_LAWS,
    algorithmic_force,
    algorithmic_tangent,
    cell_fields,
    deformation_gradients,
    internal_force,
    strain_energy,
    tangent_stiffness,
)
from ...fem.material import CellMaterial, cell_models
from ...fem.mesh import sub_mesh
from ...linalg.row_block import RowBlock

#: the round-off of the internal force relative to (|S| |U|)_i (:meth:`FiniteStrain.force_noise`): two machine
#: epsilons; measured: a block 0.5 m from its place stalls at 0.15-0.2 of eps max|S||U| (the bound is a maximum over
#: every row of every body)
FORCE_ROUNDOFF = 2.0 * np.finfo(float).eps

if TYPE_CHECKING:
    from .context import Context


class Elasticity:
    """Linear elasticity: f(U) = S U, Pi = 1/2 U.SU, K = S [force, energy, force / length]."""

    #: whether the internal force is nonlinear (finite strain): the implicit steps then iterate (Newton)
    finite = False
    #: the material models of the body, by name (summary.json ``material_model``)
    models: tuple[str, ...] = ("linear",)

    def __init__(self, ctx: Context):
        self.ctx = ctx

    def force(self, U: np.ndarray) -> np.ndarray:
        """f(U) (n,) [force]."""
        return self.ctx.Sop @ U

    def energy(self, U: np.ndarray, fU: np.ndarray | None = None) -> float:
        """Pi(U) [energy]; ``fU``: f(U) when already computed (linear: 1/2 U.fU)."""
        return 0.5 * float(U @ (self.force(U) if fU is None else fU))

    def tangent(self, U: np.ndarray, project: bool = False) -> Any:
        """K(U) = df/dU (n, n) [force / length] (positive semi-definite already: ``project`` changes nothing)."""
        return self.ctx.S

    def force_rows(self, U: np.ndarray, rows: np.ndarray, S_rows: Any = None) -> np.ndarray:
        """f(U) on the dofs ``rows`` (the reactions of the Dirichlet dofs); ``S_rows``: S[rows] taken once."""
        return (self.ctx.S[rows] if S_rows is None else S_rows) @ U

    def algorithmic_force(
        self, U0: np.ndarray, U1: np.ndarray, f0: np.ndarray | None = None, f1: np.ndarray | None = None
    ) -> np.ndarray:
        """The energy-momentum force (n,): S (U0 + U1)/2 = (f0 + f1)/2, so that f . (U1 - U0) = Pi(U1) - Pi(U0)
        [force]; ``f0``, ``f1``: f(U0), f(U1) when already computed."""
        if f0 is not None and f1 is not None:
            return 0.5 * (f0 + f1)
        return self.force(0.5 * (U0 + U1))

    def algorithmic_tangent(self, U0: np.ndarray, U1: np.ndarray) -> Any:
        """d f_alg / d U1 = S / 2 (n, n) [force / length] (the linear step is solved in one solve: never asked for
        there, given for the interface's sake)."""
        return 0.5 * self.ctx.S

    def work_error(
        self, dU: np.ndarray, U0: np.ndarray, U1: np.ndarray, f0: np.ndarray, f1: np.ndarray, w: float
    ) -> float:
        """Delta Pi - dU . (w f1 + (1 - w) f0) [energy]: what a scheme's weighting of the internal force misses of
        the stored energy's change between U0 and U1 = U0 + dU (f0, f1 their forces).  Linear:
        (1/2 - w) dU . S dU = (1/2 - w) dU . (f1 - f0), zero for w = 1/2 (the trapezoid is exact)."""
        return 0.0 if w == 0.5 else (0.5 - w) * float(dU @ (f1 - f0))

    def counters(self) -> dict[str, int]:
        """The run's counters of the nonlinear solve (none when linear)."""
        return {}


class FiniteStrain(Elasticity):
    """Finite strain on the cells of a hyperelastic model, linear on the others (module docstring).

    Parameters
    ----------
    ctx : the run's context (its mesh, materials and linear stiffness S, whose part on the
        linear cells this response keeps).
    """

    finite = True

    def __init__(self, ctx: Context):
        super().__init__(ctx)
        disc = ctx.disc
        mesh, material = disc.problem.mesh, disc.material
        self.mesh = mesh
        models = cell_models(material, mesh.n_cells)
        self.models = tuple(sorted(set(models.tolist())))
        lam = material.lam if isinstance(material, CellMaterial) else float(material.lam)
        mu = material.mu if isinstance(material, CellMaterial) else float(material.mu)
        #: (law over the whole mesh's cells, the cells it acts on or None for every cell)
        self.groups: list[tuple[Any, np.ndarray | None]] = []
        for name in self.models:
            if name == "linear":
                continue
            cells = np.flatnonzero(models == name)
            self.groups.append((HYPERELASTIC_LAWS[name](lam, mu), None if cells.size == mesh.n_cells else cells))
        #: (n_cells,) which cells are hyperelastic (None: every cell)
        self.hyperelastic = None if "linear" not in self.models else models != "linear"
        linear = np.flatnonzero(models == "linear")
        #: the linear cells' stiffness (None: no linear cell)
        self.S_linear: sp.csr_matrix | None = None
        if linear.size:
            part = material.take(linear) if isinstance(material, CellMaterial) else material
            self.S_linear = stiffness_matrix(sub_mesh(mesh, linear), part).tocsr()
        #: counts: force evaluations, tangents assembled, tangents factorized (:mod:`~.newton`), line-search
        #: halvings, tangents corrected (each cell's tangent made positive semi-definite), directions of the plain
        #: tangent with the active set held (:meth:`~.newton._Factor.kkt`)
        self.evaluations = 0
        self.tangents = 0
        self.factorizations = 0
        self.line_search_steps = 0
        self.tangent_corrections = 0
        self.kkt_directions = 0
        self.exact_directions = 0
        self.accelerated_iterations = 0
        #: steps started with a tangent kept from a level before, and those of them started again without it
        self.kept_tangent_steps = 0
        self.kept_tangent_restarts = 0
        self._last: tuple[np.ndarray, np.ndarray] | None = None
        #: the last two (U, energy) pairs
        self._energies: list[tuple[np.ndarray, float]] = []
        self._by_rows: list | None = None
        self._abs_S: sp.csr_matrix | None = None
        #: the level U0 of the last energy-momentum force and each law group's F0, C0 there (formed once a step)
        self._level: tuple[np.ndarray, list[dict]] | None = None

    def force(self, U: np.ndarray) -> np.ndarray:
        last = self._last
        if last is not None and (last[0] is U or np.array_equal(last[0], U)):
            return last[1]
        self.evaluations += 1
        f = np.zeros(U.size) if self.S_linear is None else self.S_linear @ U
        for law, cells in self.groups:
            f += internal_force(self.mesh, law, U, cells)
        self._last = (np.array(U, copy=True), f)
        return f

    def force_noise(self, U: np.ndarray) -> float:
        """The round-off of the internal force g(U) [force]: ``FORCE_ROUNDOFF`` max_i (|S| |U|)_i.

        Total Lagrangian, F = I + sum_a u_a (x) grad N_a is summed from the nodal displacements, whose size is
        the distance the body travelled, so F carries eps |u| |grad N| and g the terms of the linear stiffness
        S times |u|: a body far from its reference place (a block that slid off another and falls) cannot have
        its force residual below this, whatever Newton does."""
        S = self.ctx.S
        if self._abs_S is None:
            self._abs_S = abs(S.local if isinstance(S, RowBlock) else S).tocsr()
        local = float(np.max(self._abs_S @ np.abs(U), initial=0.0))
        return FORCE_ROUNDOFF * (float(max(S.comm.gather(local))) if isinstance(S, RowBlock) else local)

    def energy(self, U: np.ndarray, fU: np.ndarray | None = None) -> float:
        for V, e in self._energies:  # a step asks for the energies of its two levels more than once
            if V is U or np.array_equal(V, U):
                return e
        e = 0.0 if self.S_linear is None else 0.5 * float(U @ (self.S_linear @ U))
        e += sum(strain_energy(self.mesh, law, U, cells) for law, cells in self.groups)
        self._energies = [*self._energies[-1:], (np.array(U, copy=True), e)]
        return e

    def displacement_gradient(self, U: np.ndarray) -> float:
        """max |F - I| = max |grad_X u| over the quadrature points of the hyperelastic cells (entrywise) [-]."""
        out = 0.0
        for part, cut in self.mesh.parts():
            F = deformation_gradients(part, U)[0]
            if self.hyperelastic is not None:
                F = F[self.hyperelastic[cut.start : cut.stop]]
            out = max(out, float(np.abs(F - np.eye(F.shape[-1])).max(initial=0.0)))
        return out

    def tangent(self, U: np.ndarray, project: bool = False) -> sp.csr_matrix | RowBlock:
        """K(U) (n, n), or with ``project`` its convexified form: each hyperelastic cell's tangent with its negative
        eigenvalues set to 0 (:func:`~signorini.fem.hyperelastic.tangent_stiffness`); on the ranks of a distributed
        backend (M and S by rows) this rank's rows of it, a
        :class:`~signorini.linalg.row_block.RowBlock`, assembled from the cells that touch its own nodes
        (:meth:`_rank_groups`)."""
        self.tangents += 1
        groups = self._rank_groups()
        mats = [
            tangent_stiffness(self.mesh, law, U, cells, project) for law, cells in groups if cells is None or cells.size
        ]
        if self.S_linear is not None:
            mats.append(self.S_linear)
        n = self.mesh.n_nodes * self.mesh.dim
        K = mats[0] if mats else sp.csr_matrix((n, n))  # a rank whose nodes touch no cell of a law: no rows of it
        for A in mats[1:]:
            K = K + A
        M = self.ctx.M
        return RowBlock(K.tocsr()[M.lo : M.hi], M.bounds, M.comm) if isinstance(M, RowBlock) else K.tocsr()

    def _rank_groups(self) -> list:
        """Each law and its cells: with M by rows (a distributed backend) only the cells that touch this rank's
        own nodes (made once; a row of K at a node sums the cells around that node only, so these cells give
        this rank's rows exactly, docs/parallel.md), else :attr:`groups`."""
        M = self.ctx.M
        if not isinstance(M, RowBlock):
            return self.groups
        if self._by_rows is None:
            from ..model.owned_rows import cells_near

            d = self.mesh.dim
            near = cells_near(self.mesh, np.arange(block_of(M.lo, d), block_of(M.hi, d)), 1)
            self._by_rows = [
                (law, near if cells is None else np.intersect1d(cells, near)) for law, cells in self.groups
            ]
        return self._by_rows

    def algorithmic_force(
        self, U0: np.ndarray, U1: np.ndarray, f0: np.ndarray | None = None, f1: np.ndarray | None = None
    ) -> np.ndarray:
        """The energy-momentum force (n,): Gonzalez's discrete gradient on the hyperelastic cells,
        S (U0 + U1)/2 on the linear ones, so that f . (U1 - U0) = Pi(U1) - Pi(U0) [force] (``f0``, ``f1``
        unused: the discrete gradient is not their mean)."""
        f = np.zeros(U0.size) if self.S_linear is None else self.S_linear @ (0.5 * (U0 + U1))
        level = self._level
        if level is None or not (level[0] is U0 or np.array_equal(level[0], U0)):  # a new step: its level's F0, C0
            level = self._level = (np.array(U0, copy=True), [{} for _ in self.groups])
        for (law, cells), memo in zip(self.groups, level[1], strict=True):
            f += algorithmic_force(self.mesh, law, U0, U1, cells, memo)
        return f

    def algorithmic_tangent(self, U0: np.ndarray, U1: np.ndarray) -> sp.csr_matrix:
        """The exact Jacobian d f_alg / d U1 (n, n) of :meth:`algorithmic_force` at fixed U0 (not symmetric:
        :func:`~signorini.fem.hyperelastic.algorithmic_tangent`; S / 2 on the linear cells) [force / length].
        On one process (the direction it serves is assembled whole, :mod:`~.newton`)."""
        self.tangents += 1
        n = U0.size
        K = sp.csr_matrix((n, n)) if self.S_linear is None else 0.5 * self.S_linear
        for law, cells in self.groups:
            K = K + algorithmic_tangent(self.mesh, law, U0, U1, cells)
        return K.tocsr()

    def force_rows(self, U: np.ndarray, rows: np.ndarray, S_rows: Any = None) -> np.ndarray:
        return self.force(U)[rows]

    def work_error(
        self, dU: np.ndarray, U0: np.ndarray, U1: np.ndarray, f0: np.ndarray, f1: np.ndarray, w: float
    ) -> float:
        """Delta Pi - dU . (w f1 + (1 - w) f0) from the stored energies (third order in dU for w = 1/2)."""
        return self.energy(U1, f1) - self.energy(U0, f0) - float(dU @ (w * f1 + (1 - w) * f0))

    def cell_fields(self, U: np.ndarray) -> dict[str, np.ndarray]:
        """Per cell: ``cauchy_stress`` (n_cells, 3, 3) in the current configuration, ``green_lagrange`` (n_cells,
        3, 3) and ``strain_energy_density`` W (n_cells,), cell means (:func:`~signorini.fem.hyperelastic.cell_fields`);
        on the linear cells the small-strain stress (plane strain's sigma_zz = lam tr eps), strain and
        W = 1/2 sigma:eps, as means over the cell's points."""
        from ...fem.assembly import geometry, strain

        n = self.mesh.n_cells
        sig, E, W = np.zeros((n, 3, 3)), np.zeros((n, 3, 3)), np.zeros(n)
        for law, cells in self.groups:
            ids, s_, e_, w_ = cell_fields(self.mesh, law, U, cells)
            sig[ids], E[ids], W[ids] = s_, e_, w_
        linear = np.setdiff1d(np.arange(n), np.concatenate([np.arange(n) if c is None else c for _, c in self.groups]))
        if linear.size:  # small strain: sigma(eps), eps and W = 1/2 sigma:eps, each a mean over the cell's points
            sub = sub_mesh(self.mesh, linear)
            material = self.ctx.disc.material
            d = self.mesh.dim
            start = 0
            for block, _ in sub.parts():
                ids = linear[start : start + block.n_cells]
                start += block.n_cells
                mat = material.take(ids) if isinstance(material, CellMaterial) else material
                wdet = geometry(block)[0]
                w = wdet / wdet.sum(axis=1, keepdims=True)
                eps = strain(block, U)  # (e, q, d, d)
                sq = mat.stress(eps)
                sig[ids, :d, :d] = np.einsum("eq,eqij->eij", w, sq)
                if d == 2:  # plane strain: sigma_zz = lam tr(eps)
                    lam = np.broadcast_to(np.asarray(mat.lam, dtype=float), ids.shape)
                    sig[ids, 2, 2] = lam * np.einsum("eq,eq->e", w, np.trace(eps, axis1=2, axis2=3))
                E[ids, :d, :d] = np.einsum("eq,eqij->eij", w, eps)
                W[ids] = 0.5 * np.einsum("eq,eqij,eqij->e", w, sq, eps)
        return {"cauchy_stress": sig, "green_lagrange": E, "strain_energy_density": W}

    def counters(self) -> dict[str, int]:
        """The run's counts (summary.json ``counters``): ``tangent_factorizations``, ``line_search_backtracks`` (the
        halvings of the line searches; ``line_search_steps``, its earlier name, kept) and ``tangent_corrections`` (the
        tangents made positive semi-definite per cell because the plain one could not be factorized or did not give
        a descent direction) and ``kkt_directions`` (Newton directions of the plain indefinite tangent with the
        active contact rows held, where the corrected one converges slowly) and ``exact_directions`` (Newton
        directions of a scheme's exact Jacobian where its symmetric tangent approximates it: energy-momentum),
        ``kept_tangent_steps`` (steps started with a tangent kept from a level before) and ``kept_tangent_restarts``
        (those of them started again with an operator of their own)."""
        return {
            "tangent_factorizations": self.factorizations,
            "line_search_steps": self.line_search_steps,
            "line_search_backtracks": self.line_search_steps,
            "tangent_corrections": self.tangent_corrections,
            "kkt_directions": self.kkt_directions,
            "exact_directions": self.exact_directions,
            "accelerated_iterations": self.accelerated_iterations,
            "kept_tangent_steps": self.kept_tangent_steps,
            "kept_tangent_restarts": self.kept_tangent_restarts,
        }


def elasticity(ctx: Context) -> Elasticity:
    """The run's elastic response: :class:`FiniteStrain` when a cell's material model is not ``linear``."""
    models = cell_models(ctx.disc.material, ctx.disc.problem.mesh.n_cells)
    if np.all(models == "linear"):
        return Elasticity(ctx)
    return FiniteStrain(ctx)
