"""The time-scheme contract (in the spirit of ``scipy.integrate.OdeSolver``).

A scheme integrates ``M U'' + S U = F(t) + B^T lambda`` with contact, one time level
at a time.  :func:`~signorini.dynamics.stepping.simulate.simulate` owns the loop; a scheme
provides, as a subclass of :class:`Scheme`:

1. ``name``, ``description``, ``parameters`` (a tuple of
   :class:`~signorini.registry.Parameter`, validated when the scheme is built from an
   options dict) and ``energy_definition`` (a formula, stated in ``summary.json``).
2. ``operator(dt)``: the linear operator ``K = c_M M + c_S S`` it solves with
   (:class:`~signorini.dynamics.solve.context.Operator`), or None for an explicit scheme.
   The run factorizes it once; proportional operators share one factorization.
3. ``starter`` (optional): the registry name of a one-step scheme that makes the
   first step of a two-step scheme, and ``start(ctx, first, second)`` which turns the
   starter's state into this scheme's state.  The starter reuses the run's
   factorization when its operator is proportional, else it is factorized once more
   (``counters['factorizations']`` says which happened).
4. ``step(ctx, state) -> State``: from the state at t_n and the
   :class:`~signorini.dynamics.solve.context.Context` (M, S, B, ``load(t)``,
   ``dirichlet(t)``, ``gaps(t)``, ``solve(op, rhs, bound, fixed_values, law, guess)``)
   to the state at t_{n+1} with the contact forces ``lam`` and the solver's ``info``.
   Vectors are full-space (all dofs, prescribed values on the Dirichlet dofs).  A
   ``guess`` of the unknown (e.g. :meth:`Scheme.taylor_guess`, or a function returning
   it, called only when the solve is iterative) lets CG start close to it; it changes
   nothing beyond the solver's tolerance.
5. ``energy(ctx, state) -> (kinetic, potential)``: the scheme's discrete energy, and
   ``energy_increment(ctx, old, new) -> EnergyParts | None``: the right-hand side of
   its exact energy identity for the step old -> new, split into the work of
   external loads and prescribed motion, the contact term and the scheme's numerical
   dissipation.  None when the scheme has no identity for that step.
6. ``impulse(ctx, old, new) -> (nc,)`` (optional): the contact impulse of the step per
   contact node, i.e. the P of the scheme's discrete momentum balance
   ``M (V^{n+1} - V^n) = ... + B^T P`` (<= 0).  Default: ``dt lambda^{n+1}``.

A scheme written outside the package only needs these methods; register it with
``SCHEMES.register(name, cls, cls.description, aliases, cls.parameters)`` or pass the
class itself to ``simulate``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from ...contact.solver import StepInfo
from ...errors import InputError
from ...registry import Entry, Parameter

if TYPE_CHECKING:
    from ..model.operator import Operator
    from ..solve.context import Context


@dataclass
class State:
    """The discrete state at one time level (full-space vectors).

    ``U``, ``V``, ``A`` : (n,) displacement, velocity, acceleration (A may be zero for
    schemes that do not use it; on massless dofs V = (U^{n+1} - U^n)/dt and A = 0).
    ``lam`` : (nc,) contact forces of the step that produced this level (<= 0).
    ``lam_t`` : (nc, d - 1) tangential contact forces in the nodal frames (friction), or
    None; taken from ``info.lam_t`` when not given.
    ``extra`` : scheme-specific data (e.g. the previous level of a two-step scheme).
    ``cache`` : products computed once per level (``M V``, ``S U``, ...).
    """

    t: float
    U: np.ndarray
    V: np.ndarray
    A: np.ndarray
    lam: np.ndarray
    info: StepInfo | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    cache: dict[str, Any] = field(default_factory=dict)
    lam_t: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.lam_t is None and self.info is not None:
            self.lam_t = self.info.lam_t

    def product(self, key: str, compute) -> Any:
        """``compute()`` once per state, memoized under ``key``."""
        if key not in self.cache:
            self.cache[key] = compute()
        return self.cache[key]

    def is_finite(self) -> bool:
        """Whether every value of U, V and lambda is finite (a sum propagates nan/inf)."""
        return bool(np.isfinite(self.U.sum() + self.V.sum() + self.lam.sum()))


#: the kinds of :attr:`Scheme.state_fields`: a full-space vector (n,), one value per contact
#: row (nc,), per contact row and tangent direction (nc, d - 1), one value per Dirichlet dof,
#: and a flag (bool)
STATE_FIELD_KINDS = ("dofs", "contact", "contact_t", "fixed", "flag")
#: state data of every scheme: ``R0``, the residual of the massless free dofs at t = 0
#: (:func:`~signorini.dynamics.stepping.setup.initial_state`); in a damped run (:mod:`~..model.damping`)
#: ``damping_velocity`` and ``damping_acceleration``, the scheme's own V and A that the level's
#: damping force C V_d is made of (:func:`damping_velocity`, :func:`damping_force`)
#: ``newton_residual``: the force residual r (n,) a finite-strain step's Newton left at its solution
#: (:attr:`~signorini.contact.solver.StepInfo.force_residual`), whose work is the next steps' ``solver`` part too
COMMON_STATE_FIELDS = {
    "R0": "dofs",
    "damping_velocity": "dofs",
    "damping_acceleration": "dofs",
    "newton_residual": "dofs",
}


@dataclass
class EnergyParts:
    """Right-hand side of a scheme's energy identity for one step [energy]."""

    external: float = 0.0  # work of time-dependent loads and of prescribed motion
    contact: float = 0.0  # contact term (normal forces)
    numerical: float = 0.0  # the scheme's own dissipation / start-up relaxation
    friction: float = 0.0  # work of the tangential contact forces (<= 0 when it dissipates)
    damping: float = 0.0  # work of the damping forces C V (<= 0: Rayleigh damping dissipates)
    solver: float = 0.0  # work of the force residual a finite-strain step's Newton left (0 when linear)

    @property
    def total(self) -> float:
        return self.external + self.contact + self.numerical + self.friction + self.damping + self.solver


class Scheme:
    """Base class of the time schemes; see the module docstring for the contract."""

    name: ClassVar[str] = "scheme"
    description: ClassVar[str] = ""
    parameters: ClassVar[tuple[Parameter, ...]] = ()
    starter: ClassVar[str | None] = None
    energy_definition: ClassVar[str] = ""
    #: positions satisfy nu.u <= g at every level (False: velocity-level or penalized contact)
    exact_contact: ClassVar[bool] = True
    #: works with massless free dofs (redistributed masses); False: refused in check_context
    massless_dofs_allowed: ClassVar[bool] = True
    #: needs the condensed (Delassus) contact solve of a direct backend: ``auto`` never
    #: picks cg for it, an explicit cg is refused (index sets, penalty compliances)
    needs_condensed_solve: ClassVar[bool] = False
    #: why the scheme refuses a frictional contact law (None: it carries friction, with
    #: the frictional work in its energy identity)
    friction_refusal: ClassVar[str | None] = "it does not implement tangential contact forces"
    #: the data a level of this scheme carries in ``State.extra`` besides t, U, V, A, lambda and
    #: lambda_t, declared so that a checkpoint saves and restores it field by field: name ->
    #: kind, one of :data:`STATE_FIELD_KINDS`.  A checkpoint refuses a key not declared here or
    #: in :data:`COMMON_STATE_FIELDS`; a value may also be absent (None).
    state_fields: ClassVar[dict[str, str]] = {}
    #: whether the step may change between levels (a dt schedule, ``resume --dt``): a one-step
    #: scheme's state at t_n is its whole state; False, with the reason, for a scheme whose
    #: state holds earlier levels of a fixed spacing
    variable_step: ClassVar[bool] = True
    variable_step_refusal: ClassVar[str] = ""
    #: why the scheme refuses Rayleigh damping (None: it carries it, with the damping forces'
    #: work in its energy identity, :meth:`damping_coefficient` and :func:`damping_force`)
    damping_refusal: ClassVar[str | None] = "its balance has no damping term"
    #: why the scheme refuses finite strain (a material model other than ``linear``); None: its step
    #: solves the nonlinear balance by Newton (:mod:`~signorini.dynamics.solve.newton`)
    finite_strain_refusal: ClassVar[str | None] = "its step has no Newton iteration for a nonlinear internal force yet"
    #: whether its steps' velocities get the momentum projection with finite strain
    #: (:func:`~signorini.dynamics.schemes.momentum_projection.applies`; energy-momentum)
    momentum_projection: ClassVar[bool] = False

    @property
    def conserving(self) -> bool:
        """Whether the scheme conserves energy by design, so that its numerical part of the energy
        identity is an error of either sign (crank-nicolson); False: its losses are intended
        damping (backward-euler), only a gain is an error (the adaptive control,
        :mod:`~signorini.dynamics.stepping.step_control`, and docs/schemes.md)."""
        return False

    def __init__(self, **options: Any):
        entry = Entry(self.name, type(self), self.description, (), self.parameters)
        self.options = entry.options(options, where=f"scheme {self.name}")
        for k, v in self.options.items():
            setattr(self, k, v)
        self.check()

    def check(self) -> None:
        """Cross-parameter validation (raise InputError)."""

    def check_context(self, ctx: Context, prepared: bool = False) -> None:
        """Refuse a problem or solver this scheme cannot handle (raise InputError).

        Called before the factorization (``prepared=False``) and after it
        (``prepared=True``, when ``ctx.solvers`` exist), so that nothing is written.
        """

    def _refuse_massless(self, ctx: Context, why: str, fix: str = "the 'standard' or 'lumped' mass") -> None:
        """InputError if the mass leaves free dofs massless (``why``: what goes wrong then)."""
        free_massless = np.setdiff1d(ctx.massless, ctx.fixed)
        if ctx.velocity_space is not None:
            raise InputError(
                f"scheme {self.name}: mass 'mixed-velocity' has massless directions that are not dofs (the kernel of "
                f"its velocity space's pairing), and {why} (docs/schemes.md); use {fix}"
            )
        if ctx.rotated_kernel:
            raise InputError(
                f"scheme {self.name}: mass {ctx.disc.mass_name!r} on a tilted or curved contact boundary leaves the "
                f"contact nodes massless along their normals, which are not coordinate axes, and {why} "
                f"(docs/schemes.md); use {fix}"
            )
        if free_massless.size:
            raise InputError(
                f"scheme {self.name}: mass {ctx.disc.mass_name!r} leaves {free_massless.size} free "
                f"dof{'s' if free_massless.size != 1 else ''} massless, "
                f"and {why} (docs/schemes.md); use {fix}"
            )

    def _needs_condensed_solve(self, ctx: Context, prepared: bool, what: str) -> None:
        uncondensed = any(getattr(s, "condensation", "") == "none" for s in ctx.solvers)
        if self.needs_condensed_solve and prepared and uncondensed:
            raise InputError(
                f"scheme {self.name}: {what} need the condensed contact solve of a direct backend "
                "(superlu, pardiso, cholmod or petsc), not cg or petsc-cg"
            )

    @property
    def label(self) -> str:
        """Name with its options, e.g. ``newmark(beta=0.3, gamma=0.6)``."""
        if not self.options:
            return self.name
        text = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in self.options.items())
        return f"{self.name}({text})"

    # -- the contract ---------------------------------------------------------------
    def operator(self, dt: float) -> Operator | None:
        raise NotImplementedError

    def damping_coefficient(self, dt: float) -> float:
        """c such that the step operator with damping is ``operator(dt) + c C``: the factor of C
        times the step's unknown in its balance (Newmark: gamma / (beta dt)) [1/time for a
        displacement unknown]."""
        raise NotImplementedError(f"scheme {self.name} does not carry damping")

    def step_operator(self, ctx: Context, dt: float) -> Operator | None:
        """The operator the step solves with: :meth:`operator`, plus ``c C`` when the run is damped."""
        op = self.operator(dt)
        if op is None or ctx.damping is None:
            return op
        return ctx.damping.fold(op, self.damping_coefficient(dt), ctx)

    def start(self, ctx: Context, first: State, second: State) -> State:
        """Turn the starter's state at t_1 into this scheme's state (two-step schemes)."""
        return second

    def step(self, ctx: Context, state: State) -> State:
        raise NotImplementedError

    @staticmethod
    def taylor_guess(ctx: Context, state: State) -> np.ndarray:
        """U + dt V + dt^2/2 A: second-order estimate of U at t_{n+1}, the starting point
        of an iterative solve for it (bar3d n = 16, CN: 8% fewer CG iterations than
        starting from U^n)."""
        return state.U + ctx.dt * state.V + (0.5 * ctx.dt * ctx.dt) * state.A

    def step_control_refusal(self) -> str:
        """Why this scheme (with its options) cannot run under the energy control ("" when it can):
        it cannot change its step, or it is only conditionally stable (a changing step may cross
        its stability limit)."""
        if not self.variable_step:
            return f"it cannot change its step ({self.variable_step_refusal})"
        return ""

    def contact_energy(self, ctx: Context, state: State, by_row: bool = False) -> Any:
        """Energy stored in the contact law at ``state``, outside E (a penalty's springs) [energy];
        0 for exact contact.  The energy control counts the contact work net of its change.
        ``by_row``: row by row (nc,), or None when it is 0 (exact contact)."""
        return None if by_row else 0.0

    def local_error(self, ctx: Context, old: State, new: State, dt_before: float | None = None) -> np.ndarray | None:
        """An estimate of the step's local error in the displacement (n,), or None when the
        scheme has none (the energy control then judges the step by its energy alone).
        ``dt_before``: the step that made ``old`` (None at level 0)."""
        return None

    def energy(self, ctx: Context, state: State) -> tuple[float, float]:
        """(kinetic, potential): 1/2 V.MV and 1/2 U.SU - U.F(t) by default."""
        return mechanical_energy(ctx, state)

    def load_potential(self, ctx: Context, state: State) -> float:
        """The loads' part of :meth:`energy`'s potential: -U.F(t) by default [energy].

        The history splits the potential into ``elastic_energy`` (the rest: 1/2 U.SU) and
        ``load_potential`` (this); a scheme whose potential weighs the loads otherwise
        (Paoli-Schatzman's mean of two levels) overrides it."""
        return -float(state.U @ ctx.load(state.t))

    def energy_increment(self, ctx: Context, old: State, new: State) -> EnergyParts | None:
        return None

    def impulse(self, ctx: Context, old: State, new: State) -> np.ndarray:
        """Contact impulse of the step old -> new per contact node, shape (nc,) (<= 0) [force x time].

        The P of the scheme's momentum balance ``M (V^{n+1} - V^n) = ... + B^T P``.  This
        default, ``dt lambda^{n+1}`` (the force of the new level over the step), is exact
        for schemes whose balance holds the contact force of the new level only (backward
        Euler; Paoli-Schatzman and contact-stabilized Newmark, whose ``lam`` is the force
        of their balance); Newmark, theta, generalized-alpha and the velocity-level schemes
        override it.
        """
        return ctx.dt * new.lam


# ----------------------------------------------------------------------------- helpers
def products(ctx: Context, s: State) -> tuple[np.ndarray, np.ndarray]:
    """(M V, f(U)) of a state, computed once: f(U) = S U in linear elasticity, the internal force of
    finite strain otherwise (``ctx.elastic``, :mod:`~signorini.dynamics.solve.elasticity`)."""
    return s.product("MV", lambda: ctx.Mop @ s.V), s.product("SU", lambda: ctx.elastic.force(s.U))


def elastic_work_error(ctx: Context, dU: np.ndarray, old: State, new: State, w_new: float) -> float:
    """Delta Pi - dU . (w f^{n+1} + (1 - w) f^n) [energy]: what a scheme's weighting of the internal force
    f misses of the stored energy's change, a numerical term of its identity: (1/2 - w) dU.S dU in linear
    elasticity (zero for w = 1/2), third order in dU with finite strain for w = 1/2."""
    (_, f0), (_, f1) = products(ctx, old), products(ctx, new)
    return ctx.elastic.work_error(dU, old.U, new.U, f0, f1, w_new)


def mechanical_energy(ctx: Context, s: State) -> tuple[float, float]:
    """(1/2 V.MV, Pi(U) - U.F(t)) [energy]; Pi(U) = 1/2 U.SU in linear elasticity."""
    MV, SU = products(ctx, s)
    F = ctx.load(s.t)
    return 0.5 * float(s.V @ MV), ctx.elastic.energy(s.U, SU) - float(s.U @ F)


def residual(ctx: Context, s: State) -> np.ndarray | None:
    """R = M A + S U - F - B^T lambda of a level, where it can be non-zero, else None.

    On the Dirichlet dofs R is the reaction (computed when the prescribed values vary,
    for the work of the prescribed motion); on the free dofs it vanishes except at
    t = 0 when massless dofs start out of equilibrium (``extra['R0']``).
    """

    varying = ctx.has_fixed and ctx.disc.dirichlet_varies
    if not varying and "R0" not in s.extra:
        return None

    def compute():
        R = None
        if "R0" in s.extra:
            R = s.extra["R0"].copy()
        if varying:
            R = np.zeros(s.U.size) if R is None else R
            R[ctx.fixed] = fixed_reaction(ctx, s)
        return R

    return s.product("R", compute)


def fixed_reaction(ctx: Context, s: State, rows: tuple | None = None) -> np.ndarray:
    """R_D = (M A + C V + S U - F - B^T lambda - T^T lambda_t)_D (|D|,) [force]: the reactions of the
    Dirichlet dofs D at level ``s``, computed once per level (the state's products); ``rows``:
    (M_D, S_D) taken once by a caller that needs them at every level
    (:class:`~signorini.dynamics.observe.reactions.Reactions`)."""

    def compute():
        D = ctx.fixed
        MD, SD = rows if rows is not None else (ctx.M[D], ctx.S[D])
        R = (
            MD @ s.A
            + ctx.elastic.force_rows(s.U, D, SD)
            - ctx.load(s.t)[D]
            - ctx.rows.contact_on_fixed(s.lam, s.lam_t, s.t)
        )
        Fd = damping_force(ctx, s)
        return R if Fd is None else R + Fd[D]

    return s.product("RD", compute)


def load_work(ctx: Context, old: State, new: State, w_new: float) -> float:
    """dU.F_w - Delta(U.F) with F_w = w F^{n+1} + (1 - w) F^n: zero for constant loads."""
    F0, F1 = ctx.load(old.t), ctx.load(new.t)
    if F1 is F0:
        return 0.0
    dU = new.U - old.U
    return float(dU @ (w_new * F1 + (1 - w_new) * F0) - (new.U @ F1 - old.U @ F0))


def friction_work(ctx: Context, dX: np.ndarray, lam_t: np.ndarray | None) -> float:
    """(T dX) . lambda_t: the work of the tangential contact forces lambda_t (nc, d - 1)
    over the displacement dX (n,) [energy]; 0 without friction."""
    if lam_t is None or ctx.rows.T is None:
        return 0.0
    return float((ctx.rows.T @ dX) @ lam_t.ravel())


def contact_works(
    ctx: Context, dU: np.ndarray, old: State, new: State, w_new: float | np.ndarray, w_old: float | None = None
) -> tuple[float, float]:
    """(normal, tangential) work of the contact forces w lambda^{n+1} + w_old lambda^n (w_old
    = 1 - w by default) over dU, each level's multipliers through its own rows
    (:meth:`Context.rows_of`: they differ after a contact pair re-paired a slave node between
    the levels) [energy].  ``w_new``: one weight, or one per contact row (nc,) (energy-momentum).
    The normal work row by row (nc,) is kept in ``new.cache["contact_rows"]``."""
    w_old = 1 - w_new if w_old is None else w_old
    B0, T0 = ctx.rows.rows_of(old.t)
    BdU = ctx.rows.B @ dU
    B0dU = BdU if B0 is ctx.rows.B else B0 @ dU
    if new.lam.size:  # row by row (kept with the new level: the spurious energy's contact cycles, EnergyRecorder)
        new.cache["contact_rows"] = BdU * (w_new * new.lam) + B0dU * (w_old * old.lam)
    if np.ndim(w_new):  # per row: each level's forces weighted through its own rows
        normal = float(BdU @ (w_new * new.lam) + B0dU @ (w_old * old.lam)) if new.lam.size else 0.0
        tangential = 0.0
        if ctx.rows.T is not None:
            if new.lam_t is not None:
                tangential += float((ctx.rows.T @ dU) @ weighted(new.lam_t, None, w_new).ravel())
            if old.lam_t is not None and T0 is not None:
                tangential += float((T0 @ dU) @ weighted(None, old.lam_t, w_new).ravel())
        return normal, tangential
    if B0 is ctx.rows.B:
        normal = float(BdU @ (w_new * new.lam + w_old * old.lam))
        return normal, friction_work(ctx, dU, weighted(new.lam_t, old.lam_t, w_new))
    normal = w_new * float(BdU @ new.lam) + w_old * float(B0dU @ old.lam)
    tangential = 0.0
    if ctx.rows.T is not None:
        if new.lam_t is not None:
            tangential += w_new * float((ctx.rows.T @ dU) @ new.lam_t.ravel())
        if old.lam_t is not None:
            tangential += w_old * float((T0 @ dU) @ old.lam_t.ravel())
    return normal, tangential


def weighted(a: np.ndarray | None, b: np.ndarray | None, w: float | np.ndarray) -> np.ndarray | None:
    """w a + (1 - w) b, or None when both are None (frictionless levels); ``w`` one weight or one per row of a
    and b (their first axis)."""
    if a is None and b is None:
        return None
    a = np.zeros_like(b) if a is None else a
    b = np.zeros_like(a) if b is None else b
    if np.ndim(w):
        w = np.reshape(w, (-1,) + (1,) * (a.ndim - 1))
    return w * a + (1 - w) * b


def reaction_work(ctx: Context, old: State, new: State, w_new: float) -> tuple[float, float]:
    """dU . (w R^{n+1} + (1 - w) R^n), split into (Dirichlet dofs, free dofs)."""
    R0, R1 = residual(ctx, old), residual(ctx, new)
    if R0 is None and R1 is None:
        return 0.0, 0.0
    n = new.U.size
    Rw = w_new * (R1 if R1 is not None else np.zeros(n)) + (1 - w_new) * (R0 if R0 is not None else np.zeros(n))
    dU = new.U - old.U
    fixed = float(dU[ctx.fixed] @ Rw[ctx.fixed]) if ctx.has_fixed else 0.0
    return fixed, float(dU @ Rw) - fixed


def damping_velocity(s: State) -> tuple[np.ndarray, np.ndarray]:
    """(V_d, A_d): the velocity and acceleration the damping force C V_d of level ``s`` is made of.

    The scheme's own update of V and A on every dof, without the replacement of
    :meth:`~signorini.dynamics.solve.context.Context.massless_update` (V = dU/dt on massless dofs): with
    it, the damping velocity of a massless node would mix two rules from one step to the next and
    the damping's work could be positive (measured: a CN run with the default mass and beta =
    1e-2 doubled its energy).  Equal to (V, A) on every dof with mass; (V, A) at level 0."""
    return s.extra.get("damping_velocity", s.V), s.extra.get("damping_acceleration", s.A)


def damping_force(ctx: Context, s: State) -> np.ndarray | None:
    """C V_d (n,), the damping force of level ``s``'s balance [force], computed once per level (the
    state's products); None undamped."""
    if ctx.damping is None:
        return None
    return s.product("CVd", lambda: ctx.damping.force(ctx, damping_velocity(s)[0]))


def damping_split(ctx: Context, dU: np.ndarray, old: State, new: State, w_new: float) -> tuple[float, float]:
    """(damping, rest): the work of the damping forces of the step, -dU . (w C V_d^{n+1} + (1 - w)
    C V_d^n) (:func:`damping_force`), split into the dissipation of the step's mean velocity
    dU/dt, -dU . C dU / dt <= 0 (the ``damping_dissipation`` column), and the rest, the scheme's
    numerical part (zero for Crank-Nicolson, theta and Moreau-Jean, whose mean velocity is dU/dt;
    O(dt^2) for Newmark with gamma != 1/2 and generalized-alpha) [energy]; (0, 0) undamped."""
    if ctx.damping is None:
        return 0.0, 0.0
    F0, F1 = damping_force(ctx, old), damping_force(ctx, new)
    exact = -float(dU @ (w_new * F1 + (1 - w_new) * F0))
    h = new.t - old.t
    mean = -float(dU @ ctx.damping.force(ctx, dU)) / h if h > 0 else exact
    return mean, exact - mean


def newton_residual(s: State) -> np.ndarray | None:
    """The force residual r (n,) the Newton iterations of the step to level ``s`` left (None: a linear step, level 0
    or a step solved exactly)."""
    return s.extra.get("newton_residual")


def solver_work(
    ctx: Context, dU: np.ndarray, old: State, new: State, w_old: float, w_new: float, massless_old: float | None = None
) -> float:
    """The step's ``solver`` part of the energy identity [energy]: dU.(w_old r^n + w_new r^{n+1}), r the levels' force
    residuals left by Newton (:func:`newton_residual`; a level without one counts 0), the weights of each level's
    balance in the scheme's identity (Crank-Nicolson: 1/2, 1/2; theta: 1 - theta, theta); ``massless_old``: the
    weight of r^n on the massless dofs when it differs (a scheme that balances its rows with mass at t_{n+1} only).
    With it the identity closes to round-off whatever ``newton_tol`` (tests/dynamics/test_solver_work.py)."""
    r0, r1 = newton_residual(old), newton_residual(new)
    out = 0.0
    if r1 is not None:
        out += w_new * float(dU @ r1)
    if r0 is not None:
        if massless_old is None:
            out += w_old * float(dU @ r0)
        else:
            ml = ctx.massless
            full = w_old * float(dU @ r0)
            out += full + (massless_old - w_old) * float(dU[ml] @ r0[ml])
    return out
