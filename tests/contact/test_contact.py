import numpy as np
import pytest

from signorini.contact.contact_set import ContactSet
from signorini.contact.obstacles import PlaneObstacle, SphereObstacle
from signorini.errors import InputError, MeshError
from signorini.fem.mesh import box, rectangle
from signorini.fem.space import Constraints, Dirichlet, VectorSpace


def test_plane_gaps_and_normals():
    ob = PlaneObstacle([0.0, -0.3], [0.0, 2.0])
    g, nu = ob.gaps_and_normals(np.array([[0.1, 0.0], [0.5, 1.0]]))
    # a few flops on O(1) numbers: measured 0 (here and below)
    assert np.allclose(g, [0.3, 1.3], rtol=0, atol=1e-15) and np.allclose(nu, [[0, -1], [0, -1]], rtol=0, atol=1e-15)


def test_sphere_gaps_and_normals():
    ob = SphereObstacle([0.0, 0.0, 0.0], 1.0)
    x = np.array([[0.0, 0.0, 1.5], [2.0, 0.0, 0.0]])
    g, nu = ob.gaps_and_normals(x)
    assert np.allclose(g, [0.5, 1.0], rtol=0, atol=1e-15)
    assert np.allclose(nu, [[0, 0, -1], [-1, 0, 0]], rtol=0, atol=1e-15)  # outward body normal points to the ball
    with pytest.raises(InputError, match="radius"):
        SphereObstacle([0, 0], -1.0)


def test_contact_set_operator_and_weights():
    mesh = box(2, 3, 4, 1.0, 1.5, 2.0)
    space = VectorSpace(mesh)
    cs = ContactSet.from_tag(space, "zmin", PlaneObstacle([0, 0, 0], [0, 0, 1]))
    assert cs.size == 12 and np.isclose(cs.weights.sum(), 1.5, rtol=1e-14, atol=0)  # measured 3e-16 relative
    u = np.zeros(space.n_dofs)
    u[2::3] = -0.1  # every node moves down by 0.1: nu.u = 0.1 > g = 0
    # measured 0
    assert np.allclose(cs.B @ u, 0.1, rtol=0, atol=1e-15) and np.allclose(cs.gap(u), -0.1, rtol=0, atol=1e-15)


def test_contact_errors():
    mesh = rectangle(2, 2)
    space = VectorSpace(mesh)
    with pytest.raises(MeshError, match="unknown boundary tag"):
        ContactSet.from_tag(space, "bottom", PlaneObstacle([0, 0], [0, 1]))
    cons = Constraints(space, [Dirichlet("ymin", 0.0, (1,))])
    with pytest.raises(InputError, match="fixed by a Dirichlet condition in the normal direction"):
        ContactSet.from_tag(space, "ymin", PlaneObstacle([0, 0], [0, 1]), cons)
    # a tangential Dirichlet condition on the contact boundary is allowed
    cons = Constraints(space, [Dirichlet("ymin", 0.0, (0,))])
    assert ContactSet.from_tag(space, "ymin", PlaneObstacle([0, 0], [0, 1]), cons).size == 3


def test_condense_budget_bounds_the_memory_without_changing_results():
    """condense_budget = 0: Z = K^-1 B^T is never allocated (W is built block by block);
    every step costs one more solve and the history is the same to round-off."""
    import numpy as np

    from signorini.dynamics.stepping.simulate import simulate
    from signorini.studies.benchmarks import get_benchmark

    b = get_benchmark("bar2d")
    p = b.problem(2)
    dt = b.h(2) / 2
    a = simulate(p, "cn", dt, 1.0, solver_options={"backend": "superlu"})
    c = simulate(p, "cn", dt, 1.0, solver_options={"backend": "superlu", "condense_budget": 0})
    assert np.abs(a.lam - c.lam).max() <= 5e-13 * np.abs(a.lam).max()  # measured 6.9e-15 relative
    assert c.counters["linear_solves"] > a.counters["linear_solves"]  # the extra solve per contact step
