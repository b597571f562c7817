"""A dynamic contact problem and its discrete operators.

Data may depend on time: body force f(x, t), tractions t(x, t), Dirichlet values
u_D(x, t) (prescribed motion) and the obstacle's position (a moving plane or ball).
Operators are kept on the full space (all dofs, node-major); the time schemes work on
full vectors and the contact solver eliminates the Dirichlet dofs when it solves
(free rows, lifting with the prescribed values at the new time).  Kinetic and elastic
energies are therefore the full ones, and the work of a prescribed motion is the
work of the reaction forces on the fixed dofs (see :mod:`signorini.dynamics.schemes`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ...contact.contact_set import ContactSet
from ...contact.friction import FRICTIONLESS, Friction, make_friction
from ...contact.obstacles import RigidObstacle
from ...contact.pairs import ContactPair
from ...errors import InputError, NonFiniteError
from ...fem.assembly import body_load, stiffness_matrix, surface_load
from ...fem.fields import at_time, is_time_dependent
from ...fem.material import IsotropicElastic, Material, cell_material
from ...fem.mesh import Mesh
from ...fem.node_order import in_order
from ...fem.space import Constraints, Dirichlet, Value, VectorSpace
from .damping import Rayleigh, RegionalRayleigh, make_damping
from .mass import DEFAULT_MASS, MASS_VARIANTS, Redistribution, redistribute
from .mass_effect import mass_effect
from .owned_rows import mass_rows, stiffness_rows


@dataclass(frozen=True)
class RegionInitial:
    """The initial state of the nodes of a region's cells: ``displacement`` and ``velocity``
    (constant vectors (d,) or functions of the points (m, d) -> (m, d); None: the problem's
    ``u0``/``v0`` there).  A node shared with another listed region takes the later one's value."""

    tag: str
    velocity: Value | None = None
    displacement: Value | None = None


def initial_field(
    mesh: Mesh, space: VectorSpace, base: Value, regions: Sequence[RegionInitial], attribute: str
) -> np.ndarray:
    """The nodal field (n_dofs,) of ``base`` with the values of ``regions`` (their ``attribute``:
    ``velocity`` or ``displacement``) on the nodes of their cells."""
    U = space.interpolate(base)
    d = mesh.dim
    for r in regions:
        value = getattr(r, attribute)
        if value is None:
            continue
        nodes = mesh.region_nodes(r.tag)
        x = mesh.points[nodes]
        v = value(x) if callable(value) else np.broadcast_to(np.asarray(value, dtype=float), x.shape)
        v = np.asarray(v, dtype=float)
        if v.shape != x.shape:
            raise InputError(
                f"initial region {r.tag!r}: {attribute} must have {d} component(s) per node, got shape {v.shape}"
            )
        U.reshape(-1, d)[nodes] = v
    return U


@dataclass
class Problem:
    """Linear elastodynamics with nodal Signorini contact against a rigid obstacle.

    Parameters
    ----------
    mesh, material : geometry and isotropic material.  The mesh may hold several bodies (its
        connected components), in contact through ``pairs``.
    contact_tag : boundary tag of Gamma_C facing the rigid obstacle, or a list of tags (their
        union); None with ``obstacle=None`` when only ``pairs`` are in contact.
    contact_where : optional condition on the points (m, d) -> (m,) that restricts the
        contact nodes to part of the tagged boundary (``[contact] where``).
    obstacle : the rigid obstacle (fixed, or moving: a position that is a function of t), or
        None (no rigid obstacle: ``pairs`` only).
    dirichlet : Dirichlet conditions; a value may be a function of (x, t).
    u0, v0 : initial displacement and velocity (constant vector or function of x);
        the Dirichlet values override ``u0`` and ``v0`` on fixed dofs (the velocity of a
        prescribed motion is its time derivative at t = 0).
    body_force : constant vector, function of x, or of (x, t) [force / length^d].
    tractions : tag -> constant vector, function of x, or of (x, t) [force / length^(d-1)].
    friction : the contact law (:mod:`signorini.contact.friction`): None or ``"frictionless"``,
        ``"coulomb:0.3"``, ``"tresca:0.01"``, ``{"law": "coulomb", "coefficient": 0.3}`` or a
        :class:`~signorini.contact.friction.Friction` (normalized to one).
    follow_mass : True (default): a uniform body force f is applied as M_used f / rho, so that
        the body falls at g with every mass variant; False: the consistent load int f phi
        whatever the mass (GetFEM's and most codes' convention; with a redistributed mass the
        body is then not in free fall without stress) [``[loads] follow_mass``].
    pairs : contact between deformable surfaces, :class:`~signorini.contact.pairs.ContactPair`
        (slave facet tag, master facet tag, and its own contact law or None: ``friction``)
        each (docs/bodies.md).  The frictional rows of a run share one law kind
        (:func:`run_friction`).
    initial_acceleration : ``"equilibrium"`` (default): A0 solves M A0 = F(0) - S U0;
        ``"zero"``: A0 = 0 (GetFEM's Newmark start), the level-0 imbalance entering the
        energy identity as work [``[initial] acceleration``].
    materials : region tag -> :class:`~signorini.fem.material.IsotropicElastic`: the material
        of the cells of that region (``Mesh.regions``); ``material`` is the default of the cells
        in no listed region [``[material] regions``].  Stiffness, every mass variant and
        ``gravity`` use each cell's moduli and density.
    initial_regions : :class:`RegionInitial` s: the initial displacement and velocity of the
        nodes of a region's cells, over ``u0``/``v0`` (in the order given) [``[initial] regions``].
    gravity : an acceleration g (d,) [length / time^2], a constant vector or a function of t:
        the load M_used g (``follow_mass``) or int rho g phi (``follow_mass=False``), each cell
        with its own density [``[loads] gravity``].
    damping : Rayleigh damping C = alpha M + beta S, a :class:`~signorini.dynamics.model.damping.Rayleigh`
        or ``{"alpha": ..., "beta": ...}`` (None, or both zero: undamped) [``[material] damping``]; per
        region, a :class:`~signorini.dynamics.model.damping.RegionalRayleigh` [``[material] regions[k].damping``].
    initial_equilibrium : the bodies held by supports or resting in contact start in static equilibrium under
        the loads at t = 0 (:mod:`~signorini.dynamics.solve.initial_equilibrium`; free bodies keep ``u0``)
        [``[initial] equilibrium``].
    """

    mesh: Mesh
    material: IsotropicElastic
    contact_tag: str | Sequence[str] | None
    obstacle: RigidObstacle | None
    dirichlet: Sequence[Dirichlet] = ()
    u0: Value = 0.0
    v0: Value = 0.0
    body_force: Value | Callable | None = None
    tractions: dict[str, Sequence[float] | Callable] = field(default_factory=dict)
    name: str = "problem"
    contact_where: Callable[[np.ndarray], np.ndarray] | None = None
    friction: Friction | str | dict | None = None
    follow_mass: bool = True
    initial_acceleration: str = "equilibrium"
    pairs: Sequence[ContactPair] = ()
    materials: dict[str, IsotropicElastic] = field(default_factory=dict)
    initial_regions: Sequence[RegionInitial] = ()
    gravity: Value | Callable | None = None
    damping: Rayleigh | RegionalRayleigh | dict | None = None
    initial_equilibrium: bool = False

    def __post_init__(self) -> None:
        from .validate import check_problem

        check_problem(self)
        self.damping = make_damping(self.damping)
        self.friction = make_friction(self.friction)
        law = run_friction(self)  # refuses a mix of Coulomb and Tresca rows
        if law.frictional and self.mesh.dim == 1:
            raise InputError(f"friction {law.label!r} needs a 2D or 3D problem: a 1D bar has no tangent")


def pair_laws(problem: Problem) -> list[Friction]:
    """The contact law of each pair of ``problem``: its own, or the run's ``friction``."""
    return [problem.friction if p.friction is None else p.friction for p in problem.pairs]


def run_friction(problem: Problem) -> Friction:
    """The contact law of the run's solve: the one law kind of its frictional rows.

    The rows are the rigid obstacle's (law ``problem.friction``) and each pair's
    (:func:`pair_laws`).  Frictional rows must share one kind, coulomb or tresca, each with
    its own coefficient or threshold (:func:`row_friction`); frictionless rows go with either
    as coefficient or threshold 0, which is exactly frictionless (lambda_t = 0).  The law
    returned carries ``problem.friction``'s value when some row uses it, else the largest of
    the pairs' (``summary.json`` ``friction``; the pairs' own in ``pairs``).  A run mixing
    coulomb and tresca rows is an :class:`InputError`.
    """
    used = [("the rigid obstacle", problem.friction)] if problem.obstacle is not None else []
    used += [(f"pair {p.label}", law) for p, law in zip(problem.pairs, pair_laws(problem), strict=True)]
    kinds = sorted({law.law for _, law in used if law.frictional})
    if len(kinds) > 1:
        names = "; ".join(f"{who} {law.label}" for who, law in used if law.frictional)
        raise InputError(
            f"contact laws {names}: the frictional rows of a run share one law (all coulomb or all "
            "tresca, each pair its own value; frictionless pairs go with either)"
        )
    if not kinds:
        return FRICTIONLESS
    if problem.friction.law == kinds[0] and any(law is problem.friction for _, law in used):
        return problem.friction
    return max((law for _, law in used if law.law == kinds[0]), key=_parameter)


def _parameter(law: Friction) -> float:
    """The coefficient (Coulomb) or the threshold (Tresca) of ``law``; 0 frictionless."""
    return {"coulomb": law.coefficient, "tresca": law.threshold}.get(law.law, 0.0)


def row_friction(problem: Problem, contact: ContactSet) -> np.ndarray:
    """The coefficient mu_i (Coulomb) or threshold s_i (Tresca) of each contact row (nc,)
    under :func:`run_friction`: the rigid obstacle's rows ``problem.friction``'s, pair k's
    rows its law's (0 for a frictionless law)."""
    kind = run_friction(problem).law
    values = np.array([_parameter(law) if law.law == kind else 0.0 for law in [problem.friction, *pair_laws(problem)]])
    if contact.pair is None:
        return np.full(contact.size, values[0])
    return values[contact.pair + 1]


def friction_summary(problem: Problem) -> dict:
    """``summary.json`` ``friction``: :func:`run_friction` described and, when the rows' laws
    differ from it, ``pairs`` the pairs' laws and ``obstacle`` the rigid obstacle's, as labels
    (``coulomb:0.5``, ``frictionless``)."""
    law = run_friction(problem)
    out = law.describe()
    laws = pair_laws(problem)
    obstacle = problem.obstacle is not None and problem.friction != law
    if any(p != law for p in laws) or (laws and obstacle):
        out["pairs"] = [p.label for p in laws]
        if obstacle:
            out["obstacle"] = problem.friction.label
    return out


def with_friction(problem: Problem, spec: Friction | str | dict | None, where: str = "--friction") -> Problem:
    """``problem`` with the contact law ``spec`` everywhere (None: unchanged), validated as a new Problem: the
    run's law and every contact pair's own law are replaced (``--friction`` replaces the case file's laws)."""
    if spec is None:
        return problem
    import dataclasses

    law = make_friction(spec, where)
    pairs = tuple(dataclasses.replace(p, friction=None) for p in problem.pairs)
    return dataclasses.replace(problem, friction=law, pairs=pairs)


def in_node_order(problem: Problem, order: str) -> Problem:
    """``problem`` on its mesh in the node order ``order`` (:mod:`signorini.fem.node_order`;
    ``mesh``: itself): the mesh renumbered, with the initial data given as nodal arrays
    ((n_nodes, d) or (n_nodes d,)) permuted along; every other datum is a tag, a constant
    or a function of x, which follows the mesh by itself."""
    if order == "mesh":
        return problem
    mesh = in_order(problem.mesh, order)
    n, d = mesh.n_nodes, mesh.dim

    def nodal(value):
        if callable(value) or np.ndim(value) == 0 or np.size(value) != n * d or np.shape(value) == (d,):
            return value
        return np.asarray(value, dtype=float).reshape(n, d)[mesh.node_ids]

    return dataclasses.replace(problem, mesh=mesh, u0=nodal(problem.u0), v0=nodal(problem.v0))


def time_derivatives(f: Callable[[float], np.ndarray], h: float) -> tuple[np.ndarray, np.ndarray]:
    """(f'(0), f''(0)) by one-sided differences of second order with step h.

    f'(0) = (-3 f0 + 4 f1 - f2) / (2h), f''(0) = (2 f0 - 5 f1 + 4 f2 - f3) / h^2
    (exact for polynomials of degree 2, e.g. a constant-velocity or constant-
    acceleration motion).
    """
    f0, f1, f2, f3 = (np.asarray(f(k * h), dtype=float) for k in range(4))
    return (-3 * f0 + 4 * f1 - f2) / (2 * h), (2 * f0 - 5 * f1 + 4 * f2 - f3) / h**2


@dataclass
class Discretization:
    """Full-space operators, loads and constraints of a problem (all dofs).

    Attributes
    ----------
    M, S : (n, n) mass (variant ``mass_name``) and stiffness matrices.
    B : (nc, n) contact matrix; row i = nu_i^T on the dofs of contact node i.
    U0, V0 : (n,) initial displacement and velocity (prescribed values on fixed dofs).
    free, fixed : indices of free and Dirichlet dofs.
    """

    problem: Problem
    space: VectorSpace
    constraints: Constraints
    contact: ContactSet
    S: sp.csr_matrix
    M: sp.csr_matrix
    U0: np.ndarray
    V0: np.ndarray
    mass_name: str
    timings: dict[str, float] = field(default_factory=dict)
    _F_const: np.ndarray | None = None
    _varying: list = field(default_factory=list)
    #: the mass variant's effect on mass, centre and inertia (:mod:`~signorini.dynamics.model.mass_effect`)
    mass_effect: dict = field(default_factory=dict)
    #: the material of the cells: the problem's one, or per cell with regions (``materials``)
    material: Material | None = None
    #: ``mixed-velocity``'s pairing W (d n_v, d n): ker M = ker W, not a set of dofs (None for the other masses)
    velocity_pairing: sp.csr_matrix | None = None

    @property
    def B(self) -> sp.csr_matrix:
        """(nc, n) the contact rows: the contact set's own matrix (one owner; re-paired rows
        change it there)."""
        return self.contact.B

    @property
    def free(self) -> np.ndarray:
        return self.constraints.free

    @property
    def fixed(self) -> np.ndarray:
        return self.constraints.fixed

    @property
    def dirichlet_varies(self) -> bool:
        return self.constraints.time_dependent

    def load(self, t: float) -> np.ndarray:
        """F(t) (n,) = body load + tractions at time t [force]."""
        if not self._varying:
            return self._F_const
        F = self._F_const.copy()
        for build in self._varying:
            F += build(t)
        return F  # a non-finite load makes the state non-finite: the run stops as failed

    def dirichlet(self, t: float) -> np.ndarray:
        """Prescribed values on the fixed dofs at time t."""
        return self.constraints.values if not self.dirichlet_varies else self.constraints.values_at(t)

    def dirichlet_rates(self, h: float) -> tuple[np.ndarray, np.ndarray]:
        """Velocity and acceleration of the prescribed values at t = 0 (zero if constant)."""
        if not self.dirichlet_varies:
            z = np.zeros(self.fixed.size)
            return z, z
        return time_derivatives(self.constraints.values_at, h)

    def gaps(self, t: float) -> np.ndarray:
        """Contact gaps g(t) (nc,) [length]."""
        return self.contact.gaps_at(t)

    @property
    def friction(self) -> Friction:
        """The contact law of the run (frictionless unless given; with pairs :func:`run_friction`)."""
        return run_friction(self.problem)

    @property
    def friction_rows(self) -> np.ndarray:
        """The coefficient (Coulomb) or threshold (Tresca) of each contact row (nc,): :func:`row_friction`."""
        return row_friction(self.problem, self.contact)


def _uniform(f, mesh: Mesh) -> np.ndarray | None:
    """The force density when it is the same vector at every point (a constant, or a function
    of x, or of t only, such as ``"-9810 * min(t / 0.01, 1)"``), else None."""
    if not callable(f):
        return np.asarray(f, dtype=float).ravel()
    v = np.asarray(f(mesh.points), dtype=float).reshape(mesh.n_nodes, -1)
    return v[0].copy() if np.all(v == v[0]) else None


def _load_parts(
    problem: Problem, mesh: Mesh, n: int, red: Redistribution, material: Material
) -> tuple[np.ndarray, list]:
    """Constant part of F and builders of the time-dependent parts; body forces follow the mass.

    A uniform body force density f follows the mass as M (f / rho) when the density is one
    number; with regions of different densities f / rho is not one acceleration, and f is
    applied as the force density it is (through T^T for the extrapolated variants).
    ``gravity`` g is an acceleration: M_used g, or int rho g phi = M_consistent g."""
    F = np.zeros(n)
    varying = []
    rho = material.rho
    one_density = np.ndim(rho) == 0

    def body(f):
        if not problem.follow_mass:  # the consistent load int f phi, whatever the mass
            return body_load(mesh, f)
        return red.body_load(body_load(mesh, f), _uniform(f, mesh) if one_density else None, rho)

    consistent = None

    def weight(g):
        nonlocal consistent
        g = _gravity_vector(g, mesh)
        if problem.follow_mass:
            return red.M @ np.tile(g, n // g.size)
        if consistent is None:
            from ...fem.assembly import mass_matrix

            consistent = mass_matrix(mesh, rho)
        return consistent @ np.tile(g, n // g.size)

    sources = [(body, problem.body_force)] if problem.body_force is not None else []
    if problem.gravity is not None:
        sources.append((weight, problem.gravity))
    for tag, tr in problem.tractions.items():
        sources.append((lambda f, tag=tag: surface_load(mesh, tag, f), tr))
    for assemble, data in sources:
        if is_time_dependent(data):
            varying.append(lambda t, assemble=assemble, data=data: assemble(at_time(data, t)))
        else:
            F += assemble(data)
    return F, varying


def _gravity_vector(g, mesh: Mesh) -> np.ndarray:
    """Gravity (d,) from a constant vector or a function of the points that is the same at every
    point (an expression of t only, evaluated at one time); InputError otherwise."""
    v = _uniform(g, mesh)
    if v is None or v.size != mesh.dim:
        raise InputError(
            f"gravity must be one acceleration vector of {mesh.dim} component(s) (it may depend on t, not on x, y, z)"
        )
    return v


def _penetration_message(problem: Problem, contact, Bu0: np.ndarray, i: int) -> str:
    """Why the initial state violates contact at contact node ``i``: say what is really wrong
    (the obstacle's own words, :meth:`~signorini.contact.obstacles.RigidObstacle.node_inside_message`)."""
    ob, mesh = problem.obstacle, problem.mesh
    node = int(contact.nodes[i])
    g = float(contact.gaps[i])
    where = f"contact node {mesh.node_id(node)} at {np.round(mesh.points[node], 6).tolist()}"
    if ob.side_first and (side := _side_message(problem)):  # most likely a flipped surface
        return side
    if g < 0:  # the reference configuration itself is inside the obstacle
        return ob.node_inside_message(where, g, mesh.points, mesh.points[node])
    return (
        f"the initial displacement pushes {where} into the obstacle "
        f"(nu.u0 = {Bu0[i]:.3g} > gap {g:.3g}); choose u0 with nu.u0 <= gap"
    )


MAX_MAGNITUDE = 1e100


def check_magnitude(**arrays: np.ndarray) -> None:
    """Raise :class:`InputError` if data exceed MAX_MAGNITUDE (their squares would overflow)."""
    for name, a in arrays.items():
        a = np.asarray(a, dtype=float)
        if a.size and np.abs(a).max() > MAX_MAGNITUDE:
            raise InputError(f"{name} reach {np.abs(a).max():.3g} > {MAX_MAGNITUDE:g}: change units")


def _check_body_side(problem: Problem) -> None:
    """The body must start outside the obstacle: refuse a body mostly inside it."""
    message = _side_message(problem)
    if message:
        raise InputError(message)


def _side_message(problem: Problem) -> str | None:
    """Why the body is refused when more than half of its nodes start inside the obstacle (of a
    surface obstacle, more than half of the nodes that face it: those beyond its edge have an
    infinite gap; the obstacle's own words, :meth:`~signorini.contact.obstacles.RigidObstacle.body_inside_message`),
    else None."""
    ob, pts = problem.obstacle, problem.mesh.points
    phi = ob.gaps(pts, 0.0)
    phi = phi[np.isfinite(phi)]
    diam = float(np.ptp(pts, axis=0).max()) or 1.0
    inside = float(np.mean(phi < -1e-9 * diam)) if phi.size else 0.0
    if inside <= 0.5:
        return None
    return ob.body_inside_message(inside)


def check_finite_data(**arrays: np.ndarray) -> None:
    """Raise :class:`NonFiniteError` naming the first array with an inf or NaN entry."""
    for name, a in arrays.items():
        a = np.asarray(a, dtype=float)
        if not np.all(np.isfinite(a)):
            i = int(np.flatnonzero(~np.isfinite(a.ravel()))[0])
            raise NonFiniteError(
                f"non-finite value in {name} (entry {i} = {a.ravel()[i]}) before the first step; "
                "check the material, loads and initial data"
            )


def contact_node_count(problem: Problem) -> int:
    """Rows of B before discretizing: the rigid obstacle's contact nodes and the pairs' slave
    nodes (for the run-size estimate)."""
    m = problem.mesh
    rigid = m.nodes_of(problem.contact_tag).size if problem.contact_tag is not None else 0
    return rigid + sum(m.nodes_of(p.slave).size for p in problem.pairs)


def _check_pairs(problem: Problem, mass: str) -> None:
    """What contact pairs do not carry yet: ``seed-normal`` (InputError)."""
    if mass == "seed-normal":
        raise InputError(
            "mass 'seed-normal' needs one normal per contact node; with contact pairs use 'seed', "
            "'moment-preserving' or another variant"
        )


def discretize(problem: Problem, mass: str = DEFAULT_MASS, comm=None) -> Discretization:
    """Assemble S, the chosen mass variant, loads, contact set and initial data.

    ``comm``: the ranks of a distributed backend (:class:`~signorini.parallel.MPIComm`);
    S and M are then each rank's rows, :class:`~signorini.linalg.row_block.RowBlock` s
    assembled from the cells near its nodes (:mod:`~signorini.dynamics.model.owned_rows`)."""
    mass = MASS_VARIANTS.resolve(mass)
    t0 = time.perf_counter()
    mesh = problem.mesh
    mesh.check_cells()  # inverted or bow-tie cells (the command line checks meshes it reads)
    space = VectorSpace(mesh)
    cons = Constraints(space, problem.dirichlet)
    if problem.obstacle is not None:
        contact = ContactSet.from_tag(space, problem.contact_tag, problem.obstacle, cons, problem.contact_where)
    else:
        contact = ContactSet.empty(space)
    if problem.pairs:
        _check_pairs(problem, mass)
        finite = any(m.model != "linear" for m in (problem.material, *problem.materials.values()))
        contact = contact.with_pairs(space, list(problem.pairs), every=finite and space.dim > 1)
        for info, law in zip(contact.pair_info, pair_laws(problem), strict=True):
            info["friction"] = law.describe()
    normals = None if problem.pairs else contact.normals  # seed-normal only, refused with pairs
    material = cell_material(mesh.n_cells, mesh.regions, problem.material, problem.materials)
    if comm is None:
        S = stiffness_matrix(mesh, material)
        red = redistribute(mass, mesh, material.rho, contact.mass_nodes, normals)
    else:
        S = stiffness_rows(mesh, material, comm)
        red = mass_rows(mass, mesh, material.rho, contact.mass_nodes, normals, comm)
    M = red.M
    t1 = time.perf_counter()
    F, varying = _load_parts(problem, mesh, space.n_dofs, red, material)
    U0 = initial_field(mesh, space, problem.u0, problem.initial_regions, "displacement")
    U0[cons.fixed] = cons.values
    V0 = initial_field(mesh, space, problem.v0, problem.initial_regions, "velocity")
    if comm is not None and not (S.all_finite() and M.all_finite()):  # the verdict of all ranks
        raise NonFiniteError("non-finite value in S or M before the first step; check the material and the mesh")
    operators = {} if comm is not None else {"S": S.data, "M": M.data}
    check_finite_data(**operators, F=F, U0=U0, V0=V0, gaps=contact.gaps, dirichlet=cons.values)
    check_magnitude(
        **{"initial displacement": U0, "initial velocity": V0, "gaps": contact.gaps, "Dirichlet values": cons.values}
    )
    disc = Discretization(problem, space, cons, contact, S, M, U0, V0, mass, {}, F, varying)
    disc.material = material
    disc.velocity_pairing = red.W
    disc.mass_effect = mass_effect(M, mesh, material.rho)
    if red.T is not None:  # the largest |w|_1 of an extrapolated contact node (1 for a node's own value)
        rows = np.asarray(abs(red.T[contact.mass_nodes]).sum(axis=1)).ravel()
        disc.mass_effect["max_extrapolation_weight"] = float(rows.max(initial=0.0))
    viol = disc.B @ U0 - contact.gaps
    tol = 1e-10 * max(1.0, float(np.max(np.abs(contact.gaps))) if contact.size else 1.0)
    if np.any(viol > tol):
        # at a tie (to round-off), the node the user numbered first: the same on any node order
        worst = np.flatnonzero(viol >= viol.max() - 1e-3 * tol)
        i = int(worst[mesh.first_by_id(contact.nodes[worst])])
        if contact.pair is not None and contact.pair[i] >= 0:
            p = problem.pairs[int(contact.pair[i])]
            raise InputError(
                f"contact pair {p.slave!r} / {p.master!r}: slave node {mesh.node_id(contact.nodes[i])} at "
                f"{np.round(mesh.points[contact.nodes[i]], 6).tolist()} starts {viol[i]:.3g} inside the master "
                "surface (with the initial displacement); the bodies must start apart or touching"
            )
        raise InputError(_penetration_message(problem, contact, disc.B @ U0, i))
    if problem.obstacle is not None:
        _check_body_side(problem)
    disc.timings = {"assembly": t1 - t0, "reduction": time.perf_counter() - t1}
    return disc
