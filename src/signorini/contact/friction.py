"""Contact laws with friction and their per-step solve on the condensed (Delassus) system.

A law is an entry of :data:`CONTACT_LAWS`: ``frictionless`` (Signorini, one multiplier
per node), ``tresca`` (a threshold s >= 0, a force per unit area) and ``coulomb`` (a
coefficient mu >= 0).  A frictional law has d multipliers per contact node, in the
node's frame (:mod:`signorini.contact.frames`): the normal force lambda_n (<= 0 in
compression, the sign convention of :mod:`signorini.contact.obstacles`) and the
tangential force lambda_t (d - 1 components).

The discrete law of a step (docs/friction.md).  With v_n = nu.x - bound (minus the
gap, <= 0 when admissible) and v_t = T x - c_t the slip of the step (for a position
level scheme x = U^{n+1} and c_t = T (U^n + obstacle translation), the tangential part
of U^{n+1} - U^n relative to the obstacle; for a velocity-level scheme the slip rate):

    v_n <= 0,   lambda_n <= 0,   v_n lambda_n = 0                          (Signorini)
    |lambda_t| <= r,   lambda_t = -r v_t / |v_t| where v_t != 0           (friction)

with r = mu |lambda_n| (Coulomb) or r = s w_i where lambda_n < 0 (Tresca, on the nodes
in contact; w_i is the node's contact area); mu and s may differ per node (contact pairs
with their own laws, docs/bodies.md).  Both are imposed at t_{n+1}, with
lambda^{n+1}.  They are written as the Alart-Curnier fixed point

    F(l) = l - Pi(l - rho v(l)) = 0,    v(l) = v_free + W l,

Pi per node: lambda_n = min(0, z_n), lambda_t = projection of z_t on the disc of radius
r(z) = mu max(0, -z_n) (Coulomb) or s w_i [z_n < 0] (Tresca), and solved by
semismooth Newton with a backtracking line search on |F|^2 (:func:`solve_cone`); if it
stalls, a projected block Gauss-Seidel on the same projection takes over (counted as a
fallback) and a step that neither solves is a :class:`ConvergenceError`.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConvergenceError, InputError
from ..registry import Parameter, Registry

#: node statuses reported in contact.npz and the fields
SEPARATED, STICK, SLIP = 0, 1, 2
#: Newton stops here (relative residual), or where it stalls below the tolerance
ROUND_OFF = 1e-15
#: Tresca: contact sets tried per step (each one convex problem)
MAX_CONTACT_SETS = 30

CONTACT_LAWS = Registry("contact law")
CONTACT_LAWS.register("frictionless", "frictionless", "Signorini contact without friction (one multiplier per node)")
CONTACT_LAWS.register(
    "tresca",
    "tresca",
    "Tresca friction on the nodes in contact: |lambda_t| <= s w_i (given slip threshold)",
    parameters=(Parameter("threshold", 0.0, "slip threshold s [force/length^(d-1)]", float, 0.0),),
)
CONTACT_LAWS.register(
    "coulomb",
    "coulomb",
    "Coulomb friction: |lambda_t| <= mu |lambda_n|, imposed at t_{n+1}",
    parameters=(Parameter("coefficient", 0.0, "friction coefficient mu", float, 0.0),),
)


@dataclass(frozen=True)
class Friction:
    """A contact law of :data:`CONTACT_LAWS` with its parameter.

    ``coefficient`` mu (Coulomb) and ``threshold`` s [force / length^(d-1)] (Tresca);
    the unused one is 0.
    """

    law: str = "frictionless"
    coefficient: float = 0.0
    threshold: float = 0.0

    @property
    def frictional(self) -> bool:
        """Whether the law has tangential multipliers (tresca or coulomb, even with 0)."""
        return self.law != "frictionless"

    def components(self, dim: int) -> int:
        """Multipliers per contact node: 1 frictionless, d with friction."""
        return dim if self.frictional else 1

    def describe(self) -> dict[str, Any]:
        """The law and its parameter, as in summary.json (``friction``)."""
        if self.law == "coulomb":
            return {"law": "coulomb", "coefficient": self.coefficient}
        if self.law == "tresca":
            return {"law": "tresca", "threshold": self.threshold}
        return {"law": "frictionless"}

    @property
    def label(self) -> str:
        """``coulomb:0.3``, ``tresca:0.01`` or ``frictionless`` (the --friction spelling)."""
        value = {"coulomb": self.coefficient, "tresca": self.threshold}.get(self.law)
        return self.law if value is None else f"{self.law}:{value:g}"


FRICTIONLESS = Friction()
_PARAMETER = {"tresca": "threshold", "coulomb": "coefficient"}


def make_friction(spec: Friction | str | Mapping[str, Any] | None, where: str = "friction") -> Friction:
    """A :class:`Friction` from None, ``"coulomb:0.3"``, ``"tresca:0.01"``, ``"frictionless"``,
    a mapping ``{law = "coulomb", coefficient = 0.3}`` or a Friction; an
    :class:`InputError` naming ``where`` and the allowed values otherwise."""
    if spec is None:
        return FRICTIONLESS
    if isinstance(spec, Friction):
        spec = {
            "law": spec.law,
            **({_PARAMETER[spec.law]: getattr(spec, _PARAMETER[spec.law])} if spec.frictional else {}),
        }
    text = isinstance(spec, str)
    if text:
        name, sep, value = spec.partition(":")
        law = _resolve(name, where)
        if law == "frictionless" and sep:
            raise InputError(f"{where}: frictionless takes no value, got {spec!r} (e.g. coulomb:0.3)")
        if law != "frictionless" and not sep:
            raise InputError(f"{where}: {law} needs a value, e.g. {law}:{0.3 if law == 'coulomb' else 0.01}")
        spec = {"law": law, **({_PARAMETER[law]: value.strip()} if sep else {})}
    if not isinstance(spec, Mapping):
        raise InputError(f'{where} must be a table such as {{ law = "coulomb", coefficient = 0.3 }}, got {spec!r}')
    opts = dict(spec)
    if "law" not in opts:
        raise InputError(f"{where}.law is missing; allowed: {', '.join(CONTACT_LAWS.names())}")
    law = _resolve(str(opts.pop("law")), where)
    entry = CONTACT_LAWS.get(law)
    unknown = sorted(set(opts) - {p.name for p in entry.parameters})
    if unknown:
        allowed = ", ".join(p.name for p in entry.parameters) or "none"
        raise InputError(f"{where}: unknown option {unknown[0]!r} for law {law!r}; allowed: {allowed}")
    if not text:  # a table's values are numbers (a case file's "0.3" is refused like its other numbers)
        for key, value in opts.items():
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise InputError(f"{where}.{key} must be a number, got {value!r}")
    values = entry.options(opts, where=where)
    missing = [p.name for p in entry.parameters if p.name not in opts]
    if missing:
        raise InputError(f"{where}: law {law!r} needs {missing[0]!r} (e.g. {missing[0]} = 0.3)")
    return Friction(law, float(values.get("coefficient", 0.0)), float(values.get("threshold", 0.0)))


def _resolve(name: str, where: str) -> str:
    """The registry name of law ``name``, or an :class:`InputError` naming ``where``."""
    try:
        return CONTACT_LAWS.resolve(name)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


@dataclass
class ConeResult:
    """The solution of one condensed frictional problem on m nodes."""

    lam: np.ndarray  # (m, d) multipliers in the nodal frames (normal first)
    v: np.ndarray  # (m, d) v_free + W lam: minus the gap, then the slip
    status: np.ndarray  # (m,) SEPARATED, STICK or SLIP
    iterations: int
    fallback: bool
    residual: float  # |F|_inf / (rho * length scale): the cone-complementarity residual [-]


def _project(
    z: np.ndarray, mu: float | np.ndarray, radius: np.ndarray | None, fixed: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pi(z) per node (m, d), the disc radii r (m,) and |z_t| (m,) (see the module docstring);
    ``mu``: one Coulomb coefficient or one per node (m,); ``fixed``: the radii are ``radius``
    whatever z_n (the inner problem of Tresca)."""
    out = np.empty_like(z)
    zn = z[:, 0]
    out[:, 0] = np.minimum(zn, 0.0)
    if radius is None:
        r = mu * np.maximum(-zn, 0.0)
    else:
        r = radius if fixed else np.where(zn < 0.0, radius, 0.0)
    zt = z[:, 1:]
    norm = np.linalg.norm(zt, axis=1)
    factor = np.where(norm > r, r / np.where(norm > 0, norm, 1.0), 1.0)
    out[:, 1:] = zt * factor[:, None]
    return out, r, norm


def _jacobian_blocks(
    z: np.ndarray, mu: float | np.ndarray, radius: np.ndarray | None, fixed: bool = False
) -> np.ndarray:
    """A generalized Jacobian of Pi at z: (m, d, d) blocks, one per node (``mu`` as :func:`_project`)."""
    m, d = z.shape
    D = np.zeros((m, d, d))
    zn = z[:, 0]
    contact = zn < 0.0
    D[:, 0, 0] = contact
    _, r, norm = _project(z, mu, radius, fixed)
    stick = (norm <= r) & (r > 0)
    slip = norm > r
    eye = np.eye(d - 1)
    safe = np.where(norm > 0, norm, 1.0)
    e = z[:, 1:] / safe[:, None]
    D[:, 1:, 1:] = np.where(stick[:, None, None], eye, 0.0)
    scale = np.where(slip, r / safe, 0.0)
    D[:, 1:, 1:] += scale[:, None, None] * (eye - e[:, :, None] * e[:, None, :])
    if radius is None:  # dr/dz_n = -mu in contact (Coulomb)
        mu_col = mu if np.ndim(mu) == 0 else np.asarray(mu)[:, None]
        D[:, 1:, 0] = np.where((slip & contact)[:, None], -mu_col * e, 0.0)
    return D


def _status(lam: np.ndarray, r: np.ndarray, norm: np.ndarray, fixed: bool = False) -> np.ndarray:
    """SEPARATED, STICK or SLIP per node: touching is a compressive normal force, or with a
    fixed (Tresca) radius a tangential one (a node of the fallback's union at zero pressure)."""
    status = np.full(lam.shape[0], SEPARATED, dtype=np.int8)
    touching = lam[:, 0] < 0.0
    if fixed:
        touching |= np.any(lam[:, 1:] != 0.0, axis=1)
    status[touching] = np.where(norm[touching] > r[touching], SLIP, STICK)
    return status


def solve_cone(
    W: np.ndarray,
    v_free: np.ndarray,
    mu: float | np.ndarray = 0.0,
    radius: np.ndarray | None = None,
    warm: np.ndarray | None = None,
    scale: float = 1.0,
    tol: float = 1e-12,
    max_iter: int = 50,
    max_sweeps: int = 5000,
) -> ConeResult:
    """Solve the frictional contact problem of m nodes on the condensed system.

    Coulomb: one semismooth Newton solve (:func:`_solve`).  Tresca acts on the nodes in
    contact only, a radius that jumps with the contact status: it is solved as a sequence
    of problems with fixed radii s w_i on a contact set A (each convex: Signorini plus a
    given threshold), A updated to the nodes in contact at the solution until it repeats
    (then the radii match the law), at most ``MAX_CONTACT_SETS`` times.  When A cycles (a
    node in contact without its threshold and separated with it) the threshold acts on
    the union of the two sets: a counted fallback.

    Parameters
    ----------
    W : (m d, m d) Delassus matrix in the nodal frames, node-major [length / force].
    v_free : (m, d) minus the gaps and the slips of the motion without contact forces [length].
    mu : Coulomb coefficient, one for every node or (m,) one per node (used when ``radius`` is None).
    radius : (m,) Tresca thresholds s w_i [force], or None for Coulomb.
    warm : (m, d) starting multipliers (the previous step's).
    scale : length scale of the residual (the gaps of the problem).
    tol : relative tolerance on |F|_inf / (rho scale).
    """
    if radius is None:
        return _solve(W, v_free, mu, None, False, warm, scale, tol, max_iter, max_sweeps)
    radius = np.asarray(radius, dtype=float)
    lam = None if warm is None else np.asarray(warm, dtype=float)
    A = (v_free[:, 0] > 0) if lam is None else (lam[:, 0] < 0) | (v_free[:, 0] > 0)
    iterations, fallback, seen = 0, False, set()
    for _ in range(MAX_CONTACT_SETS):
        res = _solve(W, v_free, 0.0, np.where(A, radius, 0.0), True, lam, scale, tol, max_iter, max_sweeps)
        iterations += res.iterations
        fallback |= res.fallback
        rho = 1.0 / float(np.mean(np.diag(W)))
        A_new = (res.lam[:, 0] - rho * res.v[:, 0]) < 0
        if np.array_equal(A_new, A):
            res.iterations, res.fallback = iterations, fallback
            return res
        seen.add(A.tobytes())
        union = A | A_new
        A, lam = A_new, res.lam
        if A_new.tobytes() in seen:
            # a node in contact without its threshold and separated with it: the law's radius is
            # set-valued there (touching, zero pressure).  Counted fallback: the threshold acts
            # on the union of the two sets, one convex problem (docs/friction.md)
            res = _solve(W, v_free, 0.0, np.where(union, radius, 0.0), True, lam, scale, tol, max_iter, max_sweeps)
            res.iterations, res.fallback = iterations + res.iterations, True
            return res
    raise ConvergenceError(f"the Tresca contact set did not settle in {MAX_CONTACT_SETS} updates; reduce the time step")


def _solve(
    W: np.ndarray,
    v_free: np.ndarray,
    mu: float | np.ndarray,
    radius: np.ndarray | None,
    fixed: bool,
    warm: np.ndarray | None,
    scale: float,
    tol: float,
    max_iter: int,
    max_sweeps: int,
) -> ConeResult:
    """Semismooth Newton (then the counted Gauss-Seidel fallback) on F(l) = l - Pi(l - rho v(l))."""
    m, d = v_free.shape
    if m == 0:
        return ConeResult(np.zeros((0, d)), v_free.copy(), np.zeros(0, np.int8), 0, False, 0.0)
    rho = 1.0 / float(np.mean(np.diag(W)))
    lam = np.zeros((m, d)) if warm is None else np.array(warm, dtype=float)
    b = v_free.ravel()

    def residual_of(lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        v = b + W @ lam.ravel()
        z = lam - rho * v.reshape(m, d)
        return lam - _project(z, mu, radius, fixed)[0], z

    def size(F: np.ndarray) -> float:
        return float(np.max(np.abs(F))) / (rho * scale)

    F, z = residual_of(lam)
    res = size(F)
    it = 0
    eye = np.eye(m * d)
    IrW = eye - rho * W
    # Newton goes on to round-off (semismooth Newton ends in one step once the stick/slip and
    # contact structure is right); tol decides whether a stalled iteration has converged
    while res > ROUND_OFF and it < max_iter:
        it += 1
        D = _jacobian_blocks(z, mu, radius, fixed)
        # J = I - D (I - rho W) with D block diagonal: node i's rows are D_i times its rows
        # of (I - rho W), O(m^2 d^3) instead of a dense product
        J = eye - np.einsum("iab,ibk->iak", D, IrW.reshape(m, d, m * d)).reshape(m * d, m * d)
        try:
            step = np.linalg.solve(J, -F.ravel()).reshape(m, d)
        except np.linalg.LinAlgError:
            break
        merit = float(F.ravel() @ F.ravel())
        t = 1.0
        for _ in range(30):
            trial = lam + t * step
            F_trial, z_trial = residual_of(trial)
            if float(F_trial.ravel() @ F_trial.ravel()) <= (1.0 - 1e-4 * t) * merit or size(F_trial) <= tol:
                break
            t *= 0.5
        else:
            break
        if size(F_trial) >= res and res <= tol:
            break  # no progress at round-off
        lam, F, z = trial, F_trial, z_trial
        res = size(F)
    fallback = False
    if not res <= tol:
        lam, sweeps = _gauss_seidel(W, b, lam, rho, mu, radius, fixed, tol, scale, max_sweeps, d)
        it += sweeps
        fallback = True
        F, z = residual_of(lam)
        res = size(F)
        if not res <= max(tol, 1e-10):
            raise ConvergenceError(
                f"the frictional contact solve did not converge (semismooth Newton then {sweeps} Gauss-Seidel "
                f"sweeps; residual {res:.3g}); reduce the time step, or the friction coefficient or threshold"
            )
    # exact zeros where the projection says so (no round-off multipliers on separated nodes):
    # the normal force where it is not compressive, the tangential one where the disc's
    # radius is zero there (a fixed Tresca radius keeps its force: zeroing it would leave
    # x inconsistent with lambda, a node pushed into the obstacle), then v from that lambda
    free = lam[:, 0] >= 0.0
    lam[free, 0] = 0.0
    if radius is None or not fixed:
        lam[free, 1:] = 0.0
    else:
        lam[free & (radius <= 0.0), 1:] = 0.0
    v = (b + W @ lam.ravel()).reshape(m, d)
    _, r, norm = _project(lam - rho * v, mu, radius, fixed)
    return ConeResult(lam, v, _status(lam, r, norm, fixed), it, fallback, res)


def _gauss_seidel(W, b, lam, rho, mu, radius, fixed, tol, scale, max_sweeps, d) -> tuple[np.ndarray, int]:
    """Projected block Gauss-Seidel on the nodes (the counted fallback of :func:`solve_cone`).

    Node i is updated with its own block's rho_i = 1 / mean(diag W_ii): lam_i <- Pi(lam_i -
    rho_i v_i); the sweep stops when |F|_inf / (rho scale) <= tol.
    """
    m = lam.shape[0]
    x = lam.ravel().copy()
    diag = np.diag(W).reshape(m, d).mean(axis=1)
    rad = None if radius is None else np.asarray(radius)
    mus = None if np.ndim(mu) == 0 else np.asarray(mu)
    for sweep in range(1, max_sweeps + 1):
        for i in range(m):  # the fallback only: a counted, rare path
            sl = slice(i * d, (i + 1) * d)
            vi = b[sl] + W[sl] @ x
            zi = (x[sl] - vi / diag[i])[None, :]
            mu_i = mu if mus is None else mus[i : i + 1]
            x[sl] = _project(zi, mu_i, None if rad is None else rad[i : i + 1], fixed)[0][0]
        v = b + W @ x
        F = x - _project((x - rho * v).reshape(m, d), mu, rad, fixed)[0].ravel()
        if float(np.max(np.abs(F))) / (rho * scale) <= tol:
            return x.reshape(m, d), sweep
    return x.reshape(m, d), max_sweeps
