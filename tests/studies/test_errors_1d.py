"""``errors_1d`` against a hand computation (issue 24, item 7).

Every 1D rate of the suite is computed by :func:`signorini.studies.study.errors_1d`; here
it is fed a History-like object whose errors are known in closed form, and the seven
numbers it returns are checked to 1e-12 (relative) against integrals written out below.

Set-up: ``bar1d`` at its defaults (L = 1, E = rho = 1 so c = 1, gap = 1/2), which is
spec 3.1's benchmark: the exact solution is given there as a zone table (u, u_x, u_t in
four zones bounded by the characteristics x = s and x = 1 - s, s = t mod 1, three
phases), reimplemented in :func:`zone_table` without ``signorini.studies.exact``.  With
N = 8 elements and dt = h/c the characteristics pass through nodes at every time level
t_n, so at every t_n the exact displacement is piecewise linear on the mesh (its
nodal interpolant is exact), the strain and the velocity are constant on each element.

The "computed" fields are the exact ones plus known perturbations:

* displacement U_i^n = u(x_i, t_n) + a_n + b_n x_i: the error is a_n + b_n x, so the H1
  error is int b_n^2 dx = b_n^2 L, the L2 error int (a_n + b_n x)^2 dx;
* velocity V_i^n = q_n + r_n x_i (no relation with the exact one): on element e the
  error is q_n + r_n x - c_e with c_e the exact (constant) velocity there;
* multiplier lambda^n = w (sigma(t_n) + eps_n) with contact weight w = 1/2; the contact
  stress sigma is spec 3.1's trace (0 on [0, 1), -E gap/L = -1/2 on [1, 2), 0 on [2, 3),
  right-continuous as the exact solution's);
* energy E^n = 1/8 + eta_n (spec 3.1: E = 1/8 at all times).

Level 0 carries garbage: ``errors_1d`` integrates over t_1 .. t_N only (rectangle rule).

Quadrature: ``errors_1d`` integrates in space with the composite midpoint rule on
``samples`` equal sub-intervals per element (width delta = h/samples).  It is exact for
the piecewise constant integrands (H1, the velocity's norm) and, for the square of a
function linear on the element with slope s, it is below the exact integral by exactly
h delta^2 s^2 / 12 (the midpoint rule's error delta^3 f''/24 per sub-interval, f'' = 2 s^2
constant).  The hand values below are the exact integrals minus that deficit, written
out; a separate test shows the deficit vanishes as ``samples`` grows.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from signorini.studies.benchmarks import get_benchmark
from signorini.studies.study import errors_1d, observed_rates

N = 8  # elements
T = 3.0  # one period 3L/c
TOL = 1e-12


def zone_table(x, t):
    """(u, u_x, u_t) of spec 3.1 (L = c = 1, u0 = 1/2 - x/2, v0 = 0), by its zone table."""
    x, t = np.broadcast_arrays(np.asarray(x, float), np.asarray(t, float))
    tau = np.mod(t, 3.0)
    k = np.floor(tau)
    s = tau - k
    left, right = s > x, s > 1 - x  # Z2: left only, Z3: right only, Z4: both, Z1: neither
    z1, z2, z3, z4 = ~left & ~right, left & ~right, ~left & right, left & right
    u, ux, ut = np.zeros(x.shape), np.zeros(x.shape), np.zeros(x.shape)

    def put(mask, uu, uxx, utt):
        u[mask] = np.broadcast_to(uu, x.shape)[mask]
        ux[mask] = uxx
        ut[mask] = utt

    free, contact, rebound = k == 0, k == 1, k == 2
    put(free & (z1 | z3), (1 - x) / 2, -0.5, 0.0)
    put(free & (z2 | z4), (1 - s) / 2, 0.0, -0.5)
    put(contact & z1, -s / 2, 0.0, -0.5)
    put(contact & z2, -x / 2, -0.5, 0.0)
    put(contact & z3, (x - 1) / 2, 0.5, 0.0)
    put(contact & z4, (s - 1) / 2, 0.0, 0.5)
    put(rebound & (z1 | z2), s / 2, 0.0, 0.5)
    put(rebound & (z3 | z4), (1 - x) / 2, -0.5, 0.0)
    return u, ux, ut


def contact_stress(t):
    """spec 3.1's trace: sigma_n(0, t) = -1/2 on [1, 2) mod 3, else 0."""
    return np.where(np.floor(np.mod(t, 3.0)) == 1, -0.5, 0.0)


def _case():
    b = get_benchmark("bar1d")
    p = b.params()
    assert (p["L"], p["E"], p["rho"], p["gap"]) == (1.0, 1.0, 1.0, 0.5)  # spec 3.1's numbers
    problem = b.problem(N)
    x = problem.mesh.points[:, 0]
    h = 1.0 / N
    dt = h  # c = 1: the characteristics move one element per step
    steps = round(T / dt)
    t = dt * np.arange(steps + 1)  # multiples of 1/8: exact in binary
    n = np.arange(steps + 1, dtype=float)
    pert = SimpleNamespace(
        a=0.01 * np.sin(1.3 * n),
        b=0.02 * np.cos(0.7 * n),
        q=0.03 * np.sin(0.9 * n + 0.2),
        r=-0.05 * np.cos(1.1 * n),
        eps=0.04 * np.sin(0.5 * n + 1.0),
        eta=1e-3 * np.cos(n),
    )
    u_exact = zone_table(x[None, :], t[:, None])[0]
    U = u_exact + pert.a[:, None] + pert.b[:, None] * x[None, :]
    V = pert.q[:, None] + pert.r[:, None] * x[None, :]
    w = 0.5
    lam = (w * (contact_stress(t) + pert.eps))[:, None]
    E0 = 1.0 / 8.0
    kinetic = E0 + pert.eta
    # level 0 is not part of the norms: make it absurd
    U[0] += 1e3
    V[0] -= 1e3
    lam[0] = 7.0
    kinetic[0] = 1e3
    history = SimpleNamespace(
        t=t,
        snapshots={"t": t.copy(), "u": U, "v": V},
        lam=lam,
        weights=np.array([w]),
        energy=kinetic + 0.0,
    )
    exact = b.exact(p, T)
    return history, problem, exact, x, h, dt, pert, E0


def _hand(samples):
    """The seven relative errors, integral by integral."""
    H, problem, exact, x, h, dt, pert, E0 = _case()
    L = 1.0
    delta = h / samples
    mid = 0.5 * (x[:-1] + x[1:])
    num = dict.fromkeys(("u_H1", "u_L2", "v_L2"), 0.0)
    den = dict.fromkeys(("u_H1", "u_L2", "v_L2"), 0.0)
    v_num, v_den = [], []
    for n in range(1, H.t.size):
        t = H.t[n]
        a, b, q, r = pert.a[n], pert.b[n], pert.q[n], pert.r[n]
        u_nodes = zone_table(x, t)[0]
        _, ux_e, ut_e = zone_table(mid, t)  # constant on each element
        # the exact displacement is linear on every element (checked, not assumed)
        assert np.allclose(np.diff(u_nodes) / h, ux_e, rtol=0, atol=1e-15)
        # H1: the error's derivative is b; the exact strain is constant per element
        num["u_H1"] += b * b * L
        den["u_H1"] += np.sum(h * ux_e**2)
        # L2 of the linear error a + b x, minus the midpoint deficit L delta^2 b^2 / 12
        num["u_L2"] += a * a * L + a * b * L**2 + b * b * L**3 / 3 - L * delta**2 * b * b / 12
        # L2 of the exact u: per element h (u_i^2 + u_i u_j + u_j^2)/3 minus h delta^2 s_e^2 / 12
        ui, uj = u_nodes[:-1], u_nodes[1:]
        den["u_L2"] += np.sum(h * (ui * ui + ui * uj + uj * uj) / 3 - h * delta**2 * ux_e**2 / 12)
        # velocity error q + r x - c_e, linear on each element with slope r
        e0, e1 = q + r * x[:-1] - ut_e, q + r * x[1:] - ut_e
        step_num = np.sum(h * (e0 * e0 + e0 * e1 + e1 * e1) / 3 - h * delta**2 * r * r / 12)
        step_den = np.sum(h * ut_e**2)
        num["v_L2"] += step_num
        den["v_L2"] += step_den
        v_num.append(step_num)
        v_den.append(step_den)
    out = {k: np.sqrt(num[k] / den[k]) for k in num}
    out["v_Linf"] = np.sqrt(max(v_num) / max(v_den))
    sig = contact_stress(H.t[1:])
    out["stress"] = np.sqrt(np.sum(pert.eps[1:] ** 2) / np.sum(sig**2))
    Tn = H.t[-1]
    out["energy_L2"] = np.sqrt(np.sum(pert.eta[1:] ** 2) * dt / Tn) / E0
    out["energy_Linf"] = np.max(np.abs(pert.eta[1:])) / E0
    return out


@pytest.mark.parametrize("samples", [1, 3, 8])
def test_errors_1d_equals_the_hand_computation(samples):
    H, problem, exact, *_ = _case()
    got = errors_1d(H, problem, exact, samples=samples)
    want = _hand(samples)
    assert set(got) == set(want)
    for k, v in want.items():
        assert v > 1e-4, (k, v)  # every norm is exercised by a non-trivial error
        assert abs(got[k] - v) <= TOL * v, (k, got[k], v)


def test_the_hand_reference_is_the_exact_solution_of_spec_3_1():
    """The zone table the hand values use agrees with ``ExactBar1D`` (at the sample points)."""
    _, _, exact, x, h, dt, *_ = _case()
    xs = np.linspace(0, 1, 1001)[1:-1] + 1e-4  # off the characteristics
    for t in np.arange(1, 25) * dt:
        u, ux, ut = zone_table(xs, t)
        assert np.allclose(exact.u(xs, t + 0 * xs), u, rtol=0, atol=1e-15)
        assert np.allclose(exact.u_x(xs, t + 0 * xs), ux, rtol=0, atol=1e-15)
        assert np.allclose(exact.u_t(xs, t + 0 * xs), ut, rtol=0, atol=1e-15)
        assert exact.contact_stress(t) == contact_stress(t)


def test_the_midpoint_deficit_vanishes_with_more_samples():
    """With many samples the L2 norms tend to the exact integrals (deficit ~ samples^-2)."""
    H, problem, exact, *_ = _case()
    coarse, fine = _hand(8), _hand(10**6)
    got = errors_1d(H, problem, exact, samples=400)
    for k in ("u_L2", "v_L2", "v_Linf"):
        assert coarse[k] != fine[k]  # the deficit is there at 8 samples ...
        assert abs(got[k] - fine[k]) <= 1e-6 * fine[k]  # ... and small at 400 (measured 1.0e-8 relative)


def test_zero_perturbation_gives_zero_displacement_errors():
    """The exact fields themselves: u errors 0 (the exact u is piecewise linear on the mesh)."""
    H, problem, exact, x, *_ = _case()
    H.snapshots["u"] = zone_table(x[None, :], H.t[:, None])[0]
    got = errors_1d(H, problem, exact)
    assert got["u_H1"] <= 1e-15 and got["u_L2"] <= 1e-15


def test_errors_1d_needs_a_snapshot_at_every_level():
    H, problem, exact, *_ = _case()
    H.snapshots = {k: v[::2] for k, v in H.snapshots.items()}
    with pytest.raises(ValueError, match="snapshot_every=1"):
        errors_1d(H, problem, exact)
    H.snapshots = {}
    with pytest.raises(ValueError, match="snapshot_every=1"):
        errors_1d(H, problem, exact)


def test_observed_rates_by_hand():
    """log(e_k/e_{k+1}) / log(h_k/h_{k+1}): exact power laws give their exponent; a zero error gives nan."""
    h = np.array([0.1, 0.05, 0.025, 0.0125])
    assert np.allclose(observed_rates(3.0 * h**0.5, h), [0.5, 0.5, 0.5], rtol=0, atol=1e-14)  # measured 1.1e-16
    e = [0.4, 0.1, 0.0, 0.01]
    r = observed_rates(e, h)
    assert abs(r[0] - 2.0) <= 1e-14 and np.isnan(r[1]) and np.isnan(r[2])  # measured 0


def test_quadratic_cells_are_evaluated_with_their_own_shape_functions():
    """Issue 54: on ``line3`` cells a displacement quadratic in x (and a velocity quadratic in x) is represented
    exactly, so its errors against itself are round-off; read as piecewise linear between the same nodes (the
    former evaluation) the L2 error of u would be (h^2/8)^2-sized, not zero."""
    b = get_benchmark("bar1d")
    problem = b.problem(4, {"order": 2})
    x = problem.mesh.points[:, 0]
    t = np.array([0.0, 0.25, 0.5])
    a = np.array([0.0, 1.0, -2.0])

    def u(X, T):
        return np.interp(T, t, a) * X * (1.0 - X)

    exact = SimpleNamespace(
        u=u,
        u_x=lambda X, T: np.interp(T, t, a) * (1.0 - 2.0 * X),
        u_t=lambda X, T: 3.0 * X**2,
        contact_stress=lambda T: np.ones_like(T),
        energy=lambda T: np.ones_like(T),
    )
    U = u(x[None, :], t[:, None])
    V = np.repeat(3.0 * x[None, :] ** 2, t.size, axis=0)
    H = SimpleNamespace(t=t, snapshots={"t": t, "u": U, "v": V}, lam=np.ones((3, 1)), weights=np.ones(1),
                        energy=np.ones(3))  # fmt: skip
    got = errors_1d(H, problem, exact)
    assert got["u_L2"] <= 1e-14 and got["u_H1"] <= 1e-14 and got["v_L2"] <= 1e-14, got
    linear = b.problem(4, {})  # P1 cells on the vertices only: the quadratic is not representable there
    Ul = u(linear.mesh.points[None, :, 0], t[:, None])
    Hl = SimpleNamespace(**{**vars(H), "snapshots": {"t": t, "u": Ul, "v": Ul}})
    assert errors_1d(Hl, linear, exact)["u_L2"] > 1e-3
