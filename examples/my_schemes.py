"""A time scheme of your own, written outside the package through the public contract only.

    signorini run bar2d --scheme examples/my_schemes.py:MyTheta --out out/mine

It is the theta-method written from scratch, without reusing the package's Theta
(docs/schemes.md, "Writing a new scheme"); tests/dynamics/test_schemes.py imports it and checks
that it reproduces the registered ``theta``.  ``MyThetaAnyModel`` states the same step as a
``StepProblem`` (docs/schemes.md, "One step path"): the package's solver then runs it with any
material model, finite strain included (Newton), and with Rayleigh damping left out here.
"""

from signorini.dynamics.model.operator import Operator
from signorini.dynamics.schemes import Scheme, State, StepProblem, solve_step
from signorini.registry import Parameter


class MyTheta(Scheme):
    name = "my-theta"
    description = "theta-method written in a test file"
    parameters = (Parameter("theta", 0.6, "implicitness", float, 0.5, 1.0),)
    energy_definition = "E = 1/2 V.MV + 1/2 U.SU - U.F"

    def operator(self, dt):
        return Operator(1.0 / (self.theta * dt) ** 2, 1.0)

    def step(self, ctx, s):
        dt, th = ctx.dt, self.theta
        t = ctx.next_time(s.t)
        rhs = ctx.M @ ((s.U + dt * s.V) / (th * dt) ** 2 + (1 - th) / th * s.A) + ctx.load(t)
        U, lam, info = ctx.solve(self.operator(dt), rhs, ctx.gaps(t), ctx.dirichlet(t) if ctx.has_fixed else None)
        V = (U - s.U - dt * (1 - th) * s.V) / (th * dt)
        A = (V - s.V - dt * (1 - th) * s.A) / (th * dt)
        V[ctx.massless] = (U - s.U)[ctx.massless] / dt
        A[ctx.massless] = 0.0
        return State(t, U, V, A, lam, info)


class MyThetaAnyModel(MyTheta):
    name = "my-theta-any-model"
    description = "theta-method stated as one step problem: linear or finite strain"
    finite_strain_refusal = None  # the step problem's solver iterates when the internal force is nonlinear

    def step(self, ctx, s):
        dt, th = ctx.dt, self.theta
        t = ctx.next_time(s.t)
        q = s.V / (th * th * dt) + (1 - th) / th * s.A  # M A^{n+1} = M ((U^{n+1} - U^n) / (theta dt)^2 - q)
        U, lam, info = solve_step(ctx, StepProblem(self, s, t, q, ctx.load(t), ctx.rows.friction_law(s.U, s.t, t)))
        V = (U - s.U - dt * (1 - th) * s.V) / (th * dt)
        A = (V - s.V - dt * (1 - th) * s.A) / (th * dt)
        V[ctx.massless] = (U - s.U)[ctx.massless] / dt
        A[ctx.massless] = 0.0
        return State(t, U, V, A, lam, info)
