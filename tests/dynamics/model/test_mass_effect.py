"""The rigid-body effect of a mass variant: moments against the consistent mass."""

import numpy as np
import pytest

from signorini.dynamics.model.mass import linear_cell_variants, mass_matrix
from signorini.dynamics.model.mass_effect import consistent_moments, effect_warning, mass_effect, moments
from signorini.fem.assembly import scalar_mass_matrix
from signorini.fem.mesh import box, rectangle


def _dense_moments(M, mesh, k):
    d = mesh.dim
    P = np.hstack([np.ones((mesh.n_nodes, 1)), mesh.points - 0.5 * (mesh.points.min(0) + mesh.points.max(0))])
    Mk = M.toarray()[k::d, k::d]
    return P.T @ Mk @ P


@pytest.mark.parametrize("name", linear_cell_variants())
def test_moments_per_component_match_the_dense_computation(name):
    mesh = rectangle(3, 5, 1.0, 2.0)
    nodes = mesh.nodes_of("ymin")
    normals = np.tile([0.0, -1.0], (nodes.size, 1))
    M = mass_matrix(name, mesh, 2.5, nodes, normals)
    Q = moments(M, mesh)
    for k in range(2):
        assert np.abs(Q[k] - _dense_moments(M, mesh, k)).max() < 1e-14 * np.abs(Q[k]).max()  # measured 1.8e-16


@pytest.mark.parametrize("mesh", [rectangle(3, 4, 1.0, 2.0, "triangle"), box(2, 2, 3)])
def test_consistent_moments_without_assembly(mesh):
    P = np.hstack([np.ones((mesh.n_nodes, 1)), mesh.points - 0.5 * (mesh.points.min(0) + mesh.points.max(0))])
    ref = P.T @ (scalar_mass_matrix(mesh, 3.0) @ P)
    assert np.abs(consistent_moments(mesh, 3.0, chunk=5) - ref).max() < 1e-14 * np.abs(ref).max()


def test_seed_normal_is_judged_by_its_worst_component():
    mesh = rectangle(4, 8, 1.0, 2.0)
    nodes = mesh.nodes_of("ymin")
    normals = np.tile([0.0, -1.0], (nodes.size, 1))
    e = mass_effect(mass_matrix("seed-normal", mesh, 1.0, nodes, normals), mesh, 1.0)
    assert e["mass_ratio"] == pytest.approx(
        7 / 8, rel=1e-14, abs=0
    )  # measured 0; the normal component lost one row of 8


def test_warning_thresholds():
    ok = {"mass_ratio": 1.0 - 5e-4, "centre_shift": 5e-4, "inertia_change": 5e-3}
    assert effect_warning(ok) is None
    assert "mass" in effect_warning({**ok, "mass_ratio": 0.998})
    assert "centre" in effect_warning({**ok, "centre_shift": 2e-3})
    assert "inertia" in effect_warning({**ok, "inertia_change": 0.02})
