"""What the schemes cannot run, refused by name before a step: friction a scheme does not carry, finite strain
with a scheme, a mesh, a pairing, an obstacle, a backend or a damping that does not carry it (InputError naming
the combination and what does)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from ...contact.friction import Friction
from ...errors import InputError
from ...fem.material import cell_models
from ...linalg.base import backend_traits
from . import SCHEMES, finite_strain_schemes, friction_schemes

if TYPE_CHECKING:
    from ..solve.context import Context


def check_friction_schemes(friction: Friction, schemes: Sequence, finite: bool = False) -> None:
    """InputError naming the first scheme that cannot carry ``friction``, with the registered schemes that can
    (``finite``: those that also run finite strain).  ``schemes``: registry names, or scheme objects (a user's
    scheme, registered or not: its own ``friction_refusal``)."""
    if not friction.frictional:
        return
    for scheme in schemes:
        name, why = (
            (scheme, SCHEMES.get(scheme).obj.friction_refusal)
            if isinstance(scheme, str)
            else (scheme.name, scheme.friction_refusal)
        )
        if why:
            able = [s for s in friction_schemes() if not finite or s in finite_strain_schemes()]
            which = f"schemes that do{' with finite strain' if finite else ''}: {', '.join(able)}"
            raise InputError(f"scheme {name} cannot carry friction ({friction.label}): {why}; {which}")


def check_finite_strain(ctx: Context, schemes: list) -> None:
    """Refuse, naming the combination, what finite strain does not carry yet (InputError): a scheme without
    a Newton step, a 1D bar, contact pairs with ``pairing=frozen``, an obstacle without normals in the current
    configuration, an iterative backend, stiffness-proportional damping, a mass that treats the normal apart
    (``seed-normal``)."""
    if not ctx.elastic.finite:
        return
    what = f"finite strain ([material] model {', '.join(m for m in ctx.elastic.models if m != 'linear')})"
    for s in schemes:
        if s.finite_strain_refusal:
            raise InputError(
                f"scheme {s.name} cannot run {what}: {s.finite_strain_refusal}; schemes that do: "
                f"{', '.join(finite_strain_schemes())}"
            )
    problem = ctx.disc.problem
    if ctx.disc.space.dim == 1:
        raise InputError(f"{what} needs a 2D (plane strain) or 3D mesh, not a 1D bar; use model 'linear'")
    if problem.pairs and ctx.solver_options.get("pairing", "small-sliding") == "frozen":
        raise InputError(
            f"solver option pairing='frozen' does not apply to {what}: its contact pairs are paired "
            "in the current configuration at every Newton iteration (large sliding); leave pairing "
            "out, or use model 'linear'"
        )
    ob = problem.obstacle
    kind = "" if ob is None else type(ob).__name__.removesuffix("Obstacle").lower()
    if ob is not None and ctx.disc.contact.size and ob.body_normals(ctx.disc.contact.points[:1], 0.0) is None:
        raise InputError(
            f"{what} against a {kind} obstacle is not done yet (its normals in the current "
            "configuration); a plane or a sphere, fixed or moving, is"
        )
    backend = ctx.solver_options.get("backend", "auto")
    if not backend_traits(backend).finite_strain:
        raise InputError(
            f"{what} with backend {backend!r} is not done yet: its Newton step factorizes a tangent per "
            "iterate; use superlu, cholmod, pardiso, petsc or auto"
        )
    beta = 0.0 if ctx.damping is None else ctx.damping.beta
    if beta and hasattr(ctx.damping, "cell_coefficients"):  # per region: only the hyperelastic cells' beta matters
        mesh = ctx.disc.problem.mesh
        hyper = cell_models(ctx.disc.material, mesh.n_cells) != "linear"
        beta = float(ctx.damping.cell_coefficients(mesh)[1][hyper].max(initial=0.0))
    if beta:
        raise InputError(
            f"{what} with stiffness-proportional damping (beta = {beta:g} on its cells) is refused: "
            "beta S V with the reference stiffness S damps rigid rotations; use alpha only"
        )
    if ctx.disc.mass_name == "seed-normal":
        raise InputError(
            f"{what} with mass 'seed-normal' is refused: it removes the inertia along the contact "
            "normal only, so a rotating body does not keep its angular momentum; use a mass that "
            "treats every component alike (moment-preserving, seed, standard, lumped)"
        )


def check_finite_strain_solvers(ctx: Context) -> None:
    """After the set-up's factorizations: refuse a finite-strain run (or one damped per region) whose backend,
    chosen by ``auto``, has no factor (cg when no factor fits ``memory_budget``): its Newton step factorizes
    every tangent (its step operators hold the damping matrix as a third term)."""
    what = None
    if ctx.elastic.finite:
        what = "finite strain ([material] model)"
    elif ctx.damping_matrix is not None:
        what = "damping per region ([material] regions[k].damping)"
    if what is None:
        return
    if any(getattr(s, "condensation", "") == "none" for s in ctx.solvers):
        raise InputError(
            f"{what} needs a factorization of every step operator, and backend 'auto' "
            f"picked cg (no factor fits memory_budget = {ctx.solver_options.get('memory_budget'):g} bytes): "
            "raise memory_budget, or give backend superlu, cholmod or pardiso"
        )
