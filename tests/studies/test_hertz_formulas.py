"""Hertz's impact formulas re-derived here, independently of ``signorini.studies.hertz``
(issue 24, item 7), and compared with :func:`hertz_prediction` to 1e-10 relative.

The body (mass m, speed v towards a rigid plane) is a rigid mass whose approach delta
obeys m delta'' = -F(delta) with Hertz's static contact law F (K. L. Johnson, *Contact
Mechanics*, Cambridge University Press, 1985, section 11.4 "impact of elastic bodies":
quasi-static impact).  For a body on a *rigid* plane Johnson's relative quantities are
E* = E/(1 - nu^2) (the plane's compliance is zero), the body's radius R and its mass m.

Energy balance: (1/2) m v^2 = W(delta*) = int_0^delta* F; duration (the motion is
symmetric about the turning point) t_c = 2 int_0^delta* d delta / (v^2 - 2 W(delta)/m)^(1/2).

Sphere (Johnson 1985, section 4.2, eq. for two spheres with R2, E2 -> infinity):
F = (4/3) E* R^(1/2) delta^(3/2), W = (8/15) E* R^(1/2) delta^(5/2), hence
delta* = (15 m v^2 / (16 E* R^(1/2)))^(2/5), F* = F(delta*), a* = (R delta*)^(1/2), and
with delta = delta* x: t_c = 2 (delta*/v) int_0^1 (1 - x^(5/2))^(-1/2) dx, the integral
computed here with ``scipy.integrate.quad`` (not with the Beta function hertz.py uses).
Johnson prints t_c = 2.94 delta*/v = 2.87 (m^2/(R E*^2 v))^(1/5).

Disc per unit thickness (plane strain): Johnson's approach of a cylinder under a line
load P (1985, section 5.6), delta(P) = P/(pi E*) (2 ln(4R/b) - 1), b = (4 P R/(pi E*))^(1/2).
With k = 1/(pi E*) and C = ln(4 pi E* R) - 1 this is delta = k P (C - ln P), so
delta'(P) = k (C - 1 - ln P) (> 0 for P < e^(C - 1)) and, integrating by parts,

    W(P) = int_0^P p delta'(p) dp = (k P^2 / 2) (C - 1/2 - ln P)      (closed form)

P* solves W(P*) = m v^2 / 2 (``brentq`` on the closed form), delta* = delta(P*), the
half-width b* = (4 P* R/(pi E*))^(1/2), and t_c = 2 int_0^P* delta'(P) dP / (v^2 - 2 W(P)/m)^(1/2),
by ``quad`` after P = P* (1 - s^2) (which removes the inverse square root at P*).
"""

import math

import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from signorini.studies.hertz import hertz_prediction

TOL = 1e-10


def sphere_impact(R, E, nu, rho, v):
    """(max approach, peak force, duration, contact radius, m, E*) of a ball on a rigid plane."""
    Es = E / (1 - nu * nu)
    m = rho * 4.0 / 3.0 * math.pi * R**3
    d = (15 * m * v * v / (16 * Es * math.sqrt(R))) ** 0.4
    F = 4.0 / 3.0 * Es * math.sqrt(R) * d**1.5
    # int_0^1 (1 - x^(5/2))^(-1/2) dx with x = 1 - s^2 (smooth integrand; 1 - x^2.5 without cancellation)
    integral = quad(lambda s: 2 * s / math.sqrt(-math.expm1(2.5 * math.log1p(-s * s))), 0, 1, epsabs=0, epsrel=1e-13)
    tc = 2 * integral[0] * d / v
    return d, F, tc, math.sqrt(R * d), m, Es


def disc_impact(R, E, nu, rho, v):
    """The same for a disc per unit thickness with Johnson's line-contact law."""
    Es = E / (1 - nu * nu)
    m = rho * math.pi * R**2
    k = 1 / (math.pi * Es)
    C = math.log(4 * math.pi * Es * R) - 1

    def work(P):
        return 0.5 * k * P * P * (C - 0.5 - math.log(P)) if P > 0 else 0.0

    P_top = math.exp(C - 1)  # end of the increasing branch of delta(P)
    assert work(P_top) > 0.5 * m * v * v, "velocity beyond the line-contact law"
    Ps = brentq(lambda P: work(P) - 0.5 * m * v * v, 0.0, P_top, xtol=1e-300, rtol=1e-15)
    d = k * Ps * (C - math.log(Ps))

    def integrand(s):
        P = Ps * (1 - s * s)
        if P <= 0:
            return 0.0
        return 2 * Ps * s * k * (C - 1 - math.log(P)) / math.sqrt(2 / m * (work(Ps) - work(P)))

    tc = 2 * quad(integrand, 0, 1, epsabs=0, epsrel=1e-13, limit=200)[0]
    return d, Ps, tc, math.sqrt(4 * Ps * R / (math.pi * Es)), m, Es


def _close(got, want, tol=TOL):
    return abs(got - want) <= tol * abs(want)


# (R, E, nu, rho, v): the benchmarks' defaults, the second set of docs/verification.md, others
PARAMS = [
    (1.0, 1.0, 0.3, 1.0, 0.002),
    (0.5, 2.0, 0.3, 1.0, 0.001),
    (1.0, 1.0, 0.3, 1.0, 0.01),
    (1.0, 1.0, 0.45, 1.0, 0.02),
    (1.0, 5.0, 0.2, 3.0, 0.0005),
    (1.0, 1.0, 0.3, 1.0, 0.05),
]
# Narrow contacts (b*/R ~ 0.01): hertz.py's 2D figures come from an ODE integrated with
# rtol 1e-11 to its turning point; measured on 2026-12-01 against the closed form above
# (and against it in 40-digit mpmath): max approach -2.1e-10 / -2.2e-10, peak force
# -2.3e-10 / -2.5e-10 relative, the duration 1.1e-11 / 1.2e-11.  Above the 1e-10 asked.
NARROW = [
    (0.01, 1.0, 0.0, 1.0, 1e-4),
    (2.0, 210e3, 0.3, 7.8e-9, 1000.0),  # a steel disc (mm, N, t, s) at 1 m/s
]


def _agree(p, derived) -> None:
    """hertz.py's prediction ``p`` against this file's derivation (approach, force, duration, radius, mass, E*)."""
    d, F, tc, a, m, Es = derived
    assert _close(p.mass, m) and _close(p.E_star, Es)
    for name, mine in (("max_approach", d), ("peak_force", F), ("duration", tc), ("contact_radius", a)):
        assert _close(getattr(p, name), mine), (name, getattr(p, name), mine)


@pytest.mark.parametrize("R, E, nu, rho, v", PARAMS + NARROW)
def test_sphere_on_rigid_plane(R, E, nu, rho, v):
    _agree(hertz_prediction(3, R, E, nu, rho, v), sphere_impact(R, E, nu, rho, v))


def _disc_cases():
    reason = "hertz.py's 2D max approach and peak force are 2.1e-10 to 2.5e-10 off for narrow contacts"
    return [*PARAMS, *(pytest.param(*c, marks=pytest.mark.xfail(strict=True, reason=reason)) for c in NARROW)]


@pytest.mark.parametrize("R, E, nu, rho, v", _disc_cases())
def test_disc_on_rigid_plane_per_unit_thickness(R, E, nu, rho, v):
    _agree(hertz_prediction(2, R, E, nu, rho, v), disc_impact(R, E, nu, rho, v))


@pytest.mark.parametrize("R, E, nu, rho, v", NARROW)
def test_disc_narrow_contacts_within_1e_9(R, E, nu, rho, v):
    """What hertz.py does meet for narrow contacts (measured 2.5e-10): 1e-9."""
    d, F, tc, b, m, Es = disc_impact(R, E, nu, rho, v)
    p = hertz_prediction(2, R, E, nu, rho, v)
    for got, want in ((p.max_approach, d), (p.peak_force, F), (p.duration, tc), (p.contact_radius, b)):
        assert _close(got, want, 1e-9), (got, want)


def test_johnsons_printed_constants():
    """Johnson (1985, 11.4): t_c = 2.94 delta*/v = 2.87 (m^2/(R E*^2 v))^(1/5), to the printed digits.

    The constant 2.9432 goes with delta*/v; with (m^2/(R E*^2 v))^(1/5) it is
    2.9432 (15/16)^(2/5) = 2.868 (not 2.9432: that would be 2.6% long)."""
    R, E, nu, rho, v = PARAMS[0]
    d, F, tc, a, m, Es = sphere_impact(R, E, nu, rho, v)
    c1 = tc * v / d
    c2 = tc / (m * m / (R * Es * Es * v)) ** 0.2
    assert abs(c1 - 2.94) <= 0.005 and abs(c2 - 2.87) <= 0.005, (c1, c2)
    assert abs(c2 - c1 * (15 / 16) ** 0.4) <= 2e-14 * c2  # measured 4.6e-16 relative
    assert abs(2.9432 / c2 - 1) > 0.02


def test_the_reference_solves_its_own_equations():
    """Energy balance and force law of the references, checked from their outputs."""
    R, E, nu, rho, v = PARAMS[0]
    d, F, tc, a, m, Es = sphere_impact(R, E, nu, rho, v)
    assert _close(8 / 15 * Es * math.sqrt(R) * d**2.5, 0.5 * m * v * v, 1e-13)
    assert _close(F, 4 / 3 * Es * math.sqrt(R) * d**1.5, 1e-13)
    d2, P, tc2, b, m2, Es2 = disc_impact(R, E, nu, rho, v)
    # delta(P*) by Johnson's formula as printed, and W(P*) by numerical quadrature of P d delta
    assert _close(d2, P / (math.pi * Es2) * (2 * math.log(4 * R / b) - 1), 1e-13)

    def ddelta(p):
        return (math.log(4 * math.pi * Es2 * R) - 2 - math.log(p)) / (math.pi * Es2)

    W = quad(lambda p: p * ddelta(p), 0, P, epsabs=0, epsrel=1e-12)[0]
    assert _close(W, 0.5 * m2 * v * v, 1e-10)
    assert tc2 > 0 and b / R < 0.1  # a narrow strip: inside the line-contact law's range
