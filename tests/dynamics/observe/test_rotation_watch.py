"""The linear model's rotation watch: the operator on rigid rotations, the warning of a spinning linear
disc at the level it first exceeds the limit, silence on the paper's bar and under finite strain, a resume
that continues the watch, a forged checkpoint refused."""

import numpy as np
import pytest

from signorini.dynamics.observe.rotation_watch import ROTATION_LIMIT, RotationWatch, cell_rotations, rotation_operator
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.fem.mesh import box, join, rectangle
from signorini.studies.benchmarks import get_benchmark


def _rotation(d: int, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    Q2 = np.array([[c, -s], [s, c]])
    if d == 2:
        return Q2
    Q = np.eye(3)
    Q[np.ix_([0, 2], [0, 2])] = Q2  # about y
    return Q


def _mixed(dim: int):
    """Quadrilaterals beside triangles, hexahedra beside tetrahedra (two blocks)."""
    if dim == 2:
        return join({"a": rectangle(4, 3, 1.0, 0.5), "b": rectangle(2, 2, 0.5, 0.5, cell="triangle")})
    return join({"a": box(3, 2, 2, 1.0, 0.5, 0.4), "b": box(2, 2, 2, 0.5, 0.5, 0.5, cell="tetra")})


MESHES = {"quad": rectangle(4, 3, 1.0, 0.5), "triangle": rectangle(4, 3, 1.0, 0.5, cell="triangle"),
          "hexahedron": box(3, 2, 2, 1.0, 0.5, 0.4), "tetra": box(3, 2, 2, 1.0, 0.5, 0.4, cell="tetra"),
          "mixed 2D": _mixed(2), "mixed 3D": _mixed(3)}  # fmt: skip


@pytest.mark.parametrize("mesh", MESHES.values(), ids=MESHES.keys())
def test_a_rigid_rotation_is_its_angle_in_every_cell(mesh):
    """u = (Q - I) X: skew(grad u) = skew(Q), whose axial vector has length sin a, in every cell; a
    translation and a pure stretch have none."""
    X = mesh.points
    R = rotation_operator(mesh)
    for a in (1e-3, 0.3):
        theta = cell_rotations(R, (X @ _rotation(mesh.dim, a).T - X).ravel(), mesh.n_cells)
        assert np.allclose(theta, np.sin(a), rtol=1e-12, atol=0.0)
    stretch = X * np.linspace(0.01, 0.03, mesh.dim) + 0.5
    assert np.allclose(cell_rotations(R, stretch.ravel(), mesh.n_cells), 0.0, rtol=0.0, atol=1e-15)


def _spin(model: float, steps: int, **kw):
    """spin2d (n = 2) for ``steps`` of its default step, crank-nicolson."""
    b = get_benchmark("spin2d")
    dt, _ = b.run_times(2, {"model": model})
    return simulate(b.problem(2, {"model": model}), "crank-nicolson", dt, steps * dt, **kw), dt


def test_a_spinning_linear_disc_warns_at_the_first_level_above_the_limit():
    """The linear model carries a spinning disc along its tangents, x = X + t omega x X: every cell's
    rotation is omega t, so the warning names the first level with omega t > 0.05 rad."""
    H, dt = _spin(0.0, 60)
    t, M = H.t, H.meta
    omega = M["rotation_max"] / M["rotation_time"]
    first = t[np.argmax(omega * t > ROTATION_LIMIT * (1 + 1e-9))]
    (warning,) = [w for w in M["warnings"] if "small strains" in w]
    assert f"at t = {first:.6g}" in warning and 'model = "neo-hookean"' in warning
    assert M["rotation_time"] == t[-1]
    assert np.isclose(M["rotation_max"], omega * t[-1], rtol=1e-12, atol=0.0)


def test_a_slow_bar_is_silent_and_its_rotation_scales_with_its_speed():
    """The paper's 2D bar at its own speed (strain about 0.45) turns its cells by 0.16 rad and warns; at a tenth
    of its speed and gap (the same linear solution x 0.1) the largest rotation is a tenth, below the limit: silent,
    the same cell, the same time."""
    b = get_benchmark("bar2d")
    dt, T = b.run_times(4, {})
    runs = [simulate(b.problem(4, p), "crank-nicolson", dt, T) for p in ({}, {"velocity": 0.05, "gap": 0.02})]
    fast, slow = (H.meta for H in runs)
    assert [w for w in fast["warnings"] if "small strains" in w]
    assert np.isclose(slow["rotation_max"], 0.1 * fast["rotation_max"], rtol=1e-9, atol=0.0)
    assert (slow["rotation_cell"], slow["rotation_time"]) == (fast["rotation_cell"], fast["rotation_time"])
    assert 0 < slow["rotation_max"] < ROTATION_LIMIT and not [w for w in slow["warnings"] if "small strains" in w]
    H = simulate(b.problem(4, {}), "crank-nicolson", dt, T, solver_options={"rotation_limit": 0.2})
    assert H.meta["rotation_max"] == fast["rotation_max"] and not [w for w in H.meta["warnings"] if "small" in w]


def test_finite_strain_is_not_watched():
    H, _ = _spin(2.0, 20)
    assert "rotation_max" not in H.meta and not [w for w in H.meta["warnings"] if "small strains" in w]


def test_a_resumed_run_continues_the_watch(tmp_path):
    """T/2 from a checkpoint, then resumed to T: the same warning and the same largest rotation as one run."""
    full, dt = _spin(0.0, 40)
    _spin(0.0, 20, checkpoint=tmp_path / "c.h5")
    r, _ = _spin(0.0, 40, resume=tmp_path / "c.h5")
    for k in ("rotation_max", "rotation_cell", "rotation_time"):
        assert r.meta[k] == full.meta[k], k
    assert [w for w in r.meta["warnings"] if "small strains" in w] == [
        w for w in full.meta["warnings"] if "small strains" in w]  # fmt: skip


@pytest.mark.parametrize("forged", [[0.1, 2, "t"], [-1.0, 2, 0.0], [0.1, 10**6, 0.0], [0.1, True, 0.0], "x",
                                    [float("nan"), 0, 0.0]])  # fmt: skip
def test_a_forged_watch_in_a_checkpoint_is_refused(forged):
    w = RotationWatch()
    w.n_cells = 10
    with pytest.raises(InputError, match="rotation watch's largest rotation"):
        w.resume(None, 0, None, {"worst": forged})
