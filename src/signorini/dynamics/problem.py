"""A dynamic contact problem and its discrete operators on the free dofs."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..contact.contact_set import ContactSet
from ..contact.obstacles import RigidObstacle
from ..dynamics.mass import MASS_VARIANTS, mass_matrix
from ..errors import InputError
from ..fem.assembly import body_load, stiffness_matrix, surface_load
from ..fem.material import IsotropicElastic
from ..fem.mesh import Mesh
from ..fem.space import Constraints, Dirichlet, Value, VectorSpace


@dataclass
class Problem:
    """Linear elastodynamics with nodal Signorini contact against a rigid obstacle.

    Parameters
    ----------
    mesh, material : geometry and isotropic material.
    contact_tag : boundary tag of Gamma_C.
    obstacle : the rigid obstacle.
    dirichlet : Dirichlet conditions (constant in time).
    u0, v0 : initial displacement and velocity (constant vector or function of x);
        the Dirichlet values override ``u0`` and the velocity of fixed dofs is 0.
    body_force : constant vector or function of x [force / length^d].
    tractions : tag -> constant traction vector [force / length^(d-1)].
    """

    mesh: Mesh
    material: IsotropicElastic
    contact_tag: str
    obstacle: RigidObstacle
    dirichlet: Sequence[Dirichlet] = ()
    u0: Value = 0.0
    v0: Value = 0.0
    body_force: Value | Callable | None = None
    tractions: dict[str, Sequence[float]] = field(default_factory=dict)
    name: str = "problem"


@dataclass
class Discretization:
    """Operators restricted to the free dofs (Dirichlet dofs eliminated).

    ``F`` already contains the lifting ``-S_fD u_D``; ``energy_offset`` is the constant
    ``1/2 u_D.S_DD u_D - u_D.F_D`` that turns the reduced energy into the full one.
    """

    problem: Problem
    space: VectorSpace
    constraints: Constraints
    contact: ContactSet
    B: sp.csr_matrix  # (nc, n_free)
    S: sp.csr_matrix
    M: sp.csr_matrix
    F: np.ndarray
    U0: np.ndarray
    V0: np.ndarray
    energy_offset: float
    mass_name: str
    timings: dict[str, float] = field(default_factory=dict)


def discretize(problem: Problem, mass: str = "seed") -> Discretization:
    """Assemble S, the chosen mass variant, loads, contact set and initial data."""
    import time

    if mass not in MASS_VARIANTS:
        raise InputError(f"unknown mass {mass!r}; allowed: {', '.join(MASS_VARIANTS)}")
    t0 = time.perf_counter()
    mesh = problem.mesh
    space = VectorSpace(mesh)
    cons = Constraints(space, problem.dirichlet)
    contact = ContactSet.from_tag(space, problem.contact_tag, problem.obstacle, cons)
    S_full = stiffness_matrix(mesh, problem.material)
    M_full = mass_matrix(mass, mesh, problem.material.rho, contact.nodes, contact.normals)
    t1 = time.perf_counter()
    F_full = np.zeros(space.n_dofs)
    if problem.body_force is not None:
        F_full += body_load(mesh, problem.body_force)
    for tag, t in problem.tractions.items():
        F_full += surface_load(mesh, tag, t)
    U0_full = space.interpolate(problem.u0)
    U0_full[cons.fixed] = cons.values
    V0_full = space.interpolate(problem.v0)
    f = cons.free
    S, lift = cons.reduce_with_lifting(S_full)
    M = cons.reduce(M_full)
    F = F_full[f] - lift
    uD = cons.values
    SDD = S_full[cons.fixed][:, cons.fixed] if cons.fixed.size else sp.csr_matrix((0, 0))
    offset = 0.5 * float(uD @ (SDD @ uD)) - float(uD @ F_full[cons.fixed]) if uD.size else 0.0
    B = contact.B[:, f].tocsr()
    U0, V0 = U0_full[f], V0_full[f]
    viol = B @ U0 - contact.gaps
    tol = 1e-10 * max(1.0, float(np.max(np.abs(contact.gaps))) if contact.size else 1.0)
    if np.any(viol > tol):
        i = int(np.argmax(viol))
        raise InputError(
            f"initial displacement penetrates the obstacle at contact node {int(contact.nodes[i])} "
            f"(nu.u0 - g = {viol[i]:.3g} > 0); choose u0 with nu.u0 <= g"
        )
    timings = {"assembly": t1 - t0, "reduction": time.perf_counter() - t1}
    return Discretization(problem, space, cons, contact, B, S, M, F, U0, V0, offset, mass, timings)
