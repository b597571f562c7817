"""The mixed velocity mass (issue 54, spec section 16): M = W^T C^-1 W with the P1/Q1 velocity space of the vertices
off the contact boundary.  Symmetric positive semi-definite with the kernel ker W (not a set of dofs), the kernel's
projection, a free part falling at g, and its refusals by name."""

import numpy as np
import pytest
import scipy.linalg as sla
from test_quadratic_masses import SKIN, _part

from signorini.contact.obstacles import PlaneObstacle
from signorini.dynamics.model.mass import mass_matrix
from signorini.dynamics.model.mixed_velocity import (
    MAX_NODES,
    VelocitySpace,
    velocity_nodes,
    velocity_pairings,
)
from signorini.dynamics.model.problem import Problem
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.fem.assembly import vectorize
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import box, elevate, rectangle

RHO = 7800.0


@pytest.mark.parametrize("cell", ["tetra", "hexahedron"])
def test_mixed_velocity_mass_is_psd_with_the_kernel_of_its_pairing(cell):
    """M symmetric PSD; M z = 0 exactly on ker W and rank M = d n_v; no row of M is zero (the kernel is not a set
    of dofs); the mass kept is the velocity space's projection of the constant (less than the body's)."""
    mesh = _part(cell)
    contact = mesh.nodes_of("zmin")
    M = mass_matrix("mixed-velocity", mesh, RHO, contact).toarray()
    scale = np.abs(M).max()
    assert np.abs(M - M.T).max() <= 1e-14 * scale
    ev = np.linalg.eigvalsh(M)
    W = vectorize(velocity_pairings(mesh, RHO, contact)[0], 3).toarray()
    n_v = velocity_nodes(mesh, contact).size
    assert W.shape == (3 * n_v, 3 * mesh.n_nodes)
    assert ev.min() >= -1e-12 * scale
    assert int((ev > 1e-10 * scale).sum()) == 3 * n_v
    Z = sla.null_space(W)
    assert Z.shape[1] == M.shape[0] - 3 * n_v
    assert np.abs(M @ Z).max() <= 1e-12 * scale
    assert np.abs(M).sum(axis=1).min() > 0  # no massless dof
    W1, C = velocity_pairings(mesh, RHO, contact)
    ones = np.ones(mesh.n_nodes)
    kept = (W1 @ ones) @ np.linalg.solve(C.toarray(), W1 @ ones)
    assert ones @ M[::3, ::3] @ ones == pytest.approx(kept, rel=1e-12, abs=0)
    assert kept < RHO * 0.2 * 0.15 * 0.1


def test_the_kernel_projection():
    """kernel_part is a projector on ker W_f: idempotent, W_f of it zero, zero on the fixed dofs."""
    mesh = elevate(rectangle(4, 3, 1.0, 0.75, "triangle"))
    contact = mesh.nodes_of("ymin")
    W = vectorize(velocity_pairings(mesh, 1.0, contact)[0], 2)
    fixed = np.arange(2 * mesh.n_nodes)[2 * mesh.nodes_of("ymax")]
    free = np.setdiff1d(np.arange(2 * mesh.n_nodes), fixed)
    P = VelocitySpace(W, free)
    x = np.random.default_rng(0).standard_normal(2 * mesh.n_nodes)
    k = P.kernel_part(x)
    assert np.abs(k[fixed]).max() == 0.0
    assert np.abs(W[:, free] @ k[free]).max() <= 1e-13 * np.abs(x).max()
    assert np.abs(P.kernel_part(k) - k).max() <= 1e-13 * np.abs(x).max()


@pytest.mark.parametrize("cell", ["tetra", "hexahedron"])
@pytest.mark.parametrize("skin", [["zmin"], SKIN])
def test_a_free_part_falls_at_g_with_the_mixed_velocity_mass(skin, cell):
    """Every node moves by -g T^2 / 2 (the load follows the mass, M g; CN's velocity on the kernel projected),
    on tetra10 and hexahedron27, with one contact side or the whole skin (6 of 60 vertices left in the velocity
    space); the mass kept is reported."""
    mesh = _part(cell)
    g, T = 9.81, 4e-4
    mat = IsotropicElastic.from_young(2e11, 0.3, RHO)
    prob = Problem(mesh, mat, skin, PlaneObstacle([0.0, 0.0, -1.0], [0.0, 0.0, 1.0]), body_force=[0.0, 0.0, -RHO * g])
    H = simulate(prob, "cn", T / 40, T, mass="mixed-velocity", snapshot_every=40)
    assert H.status == "finished"
    U = H.snapshots["u"][-1].reshape(-1, 3)
    exact = 0.5 * g * T**2
    assert np.abs(U[:, 2] + exact).max() < 1e-9 * exact
    assert np.abs(U[:, :2]).max() < 1e-9 * exact
    effect = H.meta["mass_effect"]
    assert 0.0 < effect["mass_ratio"] < 1.0
    assert any("mixed-velocity" in w and "mass" in w for w in H.meta["warnings"])


def test_mixed_velocity_refusals_name_the_variant():
    lin = box(2, 2, 2, 1.0, 1.0, 1.0, "hexahedron")
    with pytest.raises(InputError, match="mixed-velocity.*quadratic cells only"):
        mass_matrix("mixed-velocity", lin, RHO, lin.nodes_of("zmin"))
    quad = elevate(lin)
    with pytest.raises(InputError, match="mixed-velocity.*contact nodes"):
        mass_matrix("mixed-velocity", quad, RHO, np.array([], dtype=int))
    big = elevate(rectangle(20, 20, 1.0, 1.0, "quad"))  # 41 x 41 nodes
    assert big.n_nodes > MAX_NODES
    with pytest.raises(InputError, match=f"more than {MAX_NODES}"):
        mass_matrix("mixed-velocity", big, RHO, big.nodes_of("ymin"))


@pytest.mark.parametrize("damping", [None, (0.5, 0.01)])
def test_a_start_out_of_equilibrium_keeps_the_identity(damping):
    """A quad9 block stretched at t = 0 (u0 = 0.02 y: its ends out of equilibrium), dropped on a plane, CN, with
    and without Rayleigh damping (beta > 0: C V0 has a part along the kernel): the initial imbalance's part along
    ker W is the level's R0, not an acceleration (MINRES on the whole imbalance grew A0 there to 9e13 and the
    identity to 1.6e-7; measured now 3e-14).  A0 has no part along the kernel."""
    from signorini.dynamics.model.damping import Rayleigh

    mesh = elevate(rectangle(4, 4, 1.0, 1.0, "quad"))
    mesh.points = mesh.points + [0.0, 0.01]
    mat = IsotropicElastic.from_young(1e3, 0.3, 1.0)
    prob = Problem(mesh, mat, "ymin", PlaneObstacle([0.0, 0.0], [0.0, 1.0]), u0=lambda x: np.column_stack(
        [np.zeros(len(x)), 0.02 * x[:, 1]]), v0=[0.0, -1.0],
        damping=None if damping is None else Rayleigh(*damping))  # fmt: skip
    H = simulate(prob, "cn", 0.01, 0.4, mass="mixed-velocity")
    assert H.status == "finished" and H.impacts >= 1
    assert H.summary()["energy_identity_residual"] < 1e-11
