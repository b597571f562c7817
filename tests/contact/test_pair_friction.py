"""Coulomb and Tresca friction on contact pairs (two deformable bodies, docs/bodies.md).

A pair's tangential rows are the slip of the slave node relative to the master point it
faces, t^T u_s - sum_j N_j(xi) t^T u_j, so that the pair's tangential forces balance too.
Problems: a block resting under gravity on a clamped plate, both pushed along x by a body
force (the loads ramped over 0.3), and two free blocks in an oblique impact.  Measured
numbers are in each test's docstring.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np
import pytest

from signorini.contact.contact_set import ContactSet
from signorini.contact.friction import SLIP, STICK, Friction
from signorini.contact.obstacles import PlaneObstacle
from signorini.contact.pairs import ContactPair
from signorini.dynamics.model.problem import Problem, discretize
from signorini.dynamics.stepping.simulate import simulate
from signorini.errors import InputError
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import Mesh, box, interval, join, rectangle, write_mesh
from signorini.fem.space import Dirichlet, VectorSpace

MATERIAL = IsotropicElastic.from_young(100.0, 0.3, 1.0)
PUSH, RAMP, T_PLATE, DT_PLATE = 0.2, 0.3, 0.5, 0.005
GAP = 0.01


def plate_and_block(layers: int = 2) -> Mesh:
    """A 2 x 0.25 plate (8 x ``layers`` quads) under a 0.5 x 0.25 block (6 x 2 quads) resting on
    it at x in [0.75, 1.25]: non-matching faces, the block's bottom (finer) is the slave side.
    On a rigid floor the plate needs 3 layers: with its top and bottom both contact nodes, the
    default mass extrapolates them from its own inner nodes, which one row cannot span."""
    plate = rectangle(8, layers, 2.0, 0.25)
    blk = rectangle(6, 2, 0.5, 0.25)
    blk.points = blk.points + np.array([0.75, 0.25])
    return join({"plate": plate, "block": blk})


def ramped_load(x: np.ndarray, t: float) -> np.ndarray:
    """Gravity g = 1 and a push PUSH g along x, both ramped from 0 over RAMP."""
    return np.tile(min(t / RAMP, 1.0) * np.array([PUSH, -1.0]), (x.shape[0], 1))


def block_on_plate(friction, floor=None) -> Problem:
    """The block on the plate; the plate clamped at its bottom, or (``floor``: the law of the
    rigid floor) resting free on the rigid floor y = 0."""
    if floor is None:
        return Problem(plate_and_block(), MATERIAL, None, None, dirichlet=[Dirichlet("plate_ymin")],
                       body_force=ramped_load, pairs=[ContactPair("block_ymin", "plate_ymax", friction)])  # fmt: skip
    return Problem(plate_and_block(3), MATERIAL, "plate_ymin", PlaneObstacle([0.0, 0.0], [0.0, 1.0]),
                   body_force=ramped_load, friction=floor,
                   pairs=[ContactPair("block_ymin", "plate_ymax", friction)])  # fmt: skip


def rigid_slide(mu: float) -> float:
    """The slide at T_PLATE of a rigid block on a fixed plane under ramped_load: acceleration
    (PUSH - mu) g min(t / RAMP, 1) from rest."""
    c, r, T = PUSH - mu, RAMP, T_PLATE
    return c * r**2 / 6 + c * r / 2 * (T - r) + c * (T - r) ** 2 / 2


def two_blocks(friction, dim: int = 2) -> Problem:
    """Two free blocks, no load, no Dirichlet: the upper one GAP above the lower one, moving
    obliquely at (0.5, -0.5) ((0.5, 0.3, -0.5) in 3D)."""
    if dim == 2:
        a, b = rectangle(8, 2, 1.0, 0.25), rectangle(6, 2, 0.5, 0.25)
        b.points = b.points + np.array([0.25, 0.25 + GAP])
        v = np.array([0.5, -0.5])
    else:
        a, b = box(4, 4, 2, 1.0, 1.0, 0.25), box(3, 3, 2, 0.5, 0.5, 0.25)  # 2 layers: see plate_and_block
        b.points = b.points + np.array([0.25, 0.25, 0.25 + GAP])
        v = np.array([0.5, 0.3, -0.5])
    ax = "xyz"[dim - 1]
    return Problem(join({"lower": a, "upper": b}), MATERIAL, None, None,
                   v0=lambda x: np.where(x[:, -1:] > 0.25 + GAP / 2, 1.0, 0.0) * v,
                   pairs=[ContactPair(f"upper_{ax}min", f"lower_{ax}max", friction)])  # fmt: skip


@functools.cache
def run_plate(friction: str, scheme: str, floor: str | None = None):
    H = simulate(block_on_plate(friction, floor), scheme, DT_PLATE, T_PLATE, mass="moment-preserving")
    assert H.status == "finished", H.message
    return H


@functools.cache
def run_blocks(friction: str, scheme: str, mass: str = "moment-preserving", dim: int = 2):
    H = simulate(two_blocks(friction, dim), scheme, 0.002, 0.12 if dim == 2 else 0.08, mass=mass)
    assert H.status == "finished", H.message
    return H


# ----------------------------------------------------------------------------- block on a plate
@pytest.mark.parametrize("scheme", ["cn", "be"])
def test_a_large_coefficient_sticks_the_block_to_the_plate(scheme):
    """mu = 1000: every row in contact sticks at every level (the block does not lift), with a
    relative slip of round-off: measured 1.1e-19 (CN) and 1.6e-19 (BE), against the 9.7e-3
    the block slides with mu = 0.05; |lambda_t| <= mu |lambda_n| to round-off (0 measured)."""
    H = run_plate("coulomb:1000", scheme)
    touching = H.lam < 0
    assert touching[1:].all()
    assert np.all(H.contact_status[touching] == STICK)
    assert np.abs(H.slip[touching]).max() <= 1e-15 * rigid_slide(0.05)
    scale = np.abs(H.lam).max()
    assert np.abs(H.lam_t).max() >= 0.05 * scale  # friction holds the block
    assert np.all(np.abs(H.lam_t[..., 0]) <= 1000 * np.abs(H.lam) + 5e-16 * scale)


@pytest.mark.parametrize("scheme", ["cn", "be"])
def test_a_small_coefficient_lets_the_block_slide(scheme):
    """mu = 0.05 < PUSH: the rows slide, the mean relative slip matching the rigid block's
    (PUSH - mu) g ramped: measured -0.3% (CN), +1.9% (BE), 5% enforced (the elastic bodies'
    own motion); the tangential force never exceeds mu |lambda_n| and is -mu |lambda_n| along
    the slip where a row slides, to round-off (measured 8.2e-18 of max |lambda_n|; 98% of the
    rows in contact slide)."""
    mu = 0.05
    H = run_plate(f"coulomb:{mu}", scheme)
    touching = H.lam < 0
    slip = H.contact_status == SLIP
    assert slip.sum() >= 0.9 * touching.sum()
    forward = H.slip[1:, :, 0].sum(axis=0) * H.tangents[:, 0, 0]  # global x of each row's total slip
    assert abs(forward.mean() / rigid_slide(mu) - 1) <= 0.05
    scale = np.abs(H.lam).max()
    lt = H.lam_t[..., 0]
    assert np.all(np.abs(lt) <= mu * np.abs(H.lam) + 5e-16 * scale)
    expected = -mu * np.abs(H.lam[slip]) * np.sign(H.slip[slip][:, 0])
    assert np.abs(lt[slip] - expected).max() <= 5e-16 * scale
    assert np.all(H.lam_t[H.lam == 0] == 0)


def test_each_pair_and_the_obstacle_keep_their_own_coefficient():
    """The plate free on a rigid floor (section law coulomb:0.05: the stack slides, measured
    0.13% below the rigid slide) under the block (its pair coulomb:1000: it sticks to the plate,
    relative slip 1.7e-18); a frictionless pair in the same Coulomb run carries exactly no
    tangential force.  summary.json reports the run's law and each pair's."""
    H = run_plate("coulomb:1000", "cn", floor="coulomb:0.05")
    s = H.summary()
    assert s["friction"] == {"law": "coulomb", "coefficient": 0.05, "pairs": ["coulomb:1000"]}
    assert s["pairs"][0]["friction"] == {"law": "coulomb", "coefficient": 1000.0}
    rows = s["pairs"][0]["rows"]
    floor, pair = slice(0, H.lam.shape[1] - rows), slice(H.lam.shape[1] - rows, None)
    assert np.all(H.contact_status[:, pair][H.lam[:, pair] < 0] == STICK)
    assert np.abs(H.slip[:, pair]).max() <= 1e-15 * rigid_slide(0.05)  # measured 1.7e-18
    forward = H.slip[1:, floor, 0].sum(axis=0) * H.tangents[floor, 0, 0]
    assert abs(forward.mean() / rigid_slide(0.05) - 1) <= 0.05
    scale = np.abs(H.lam).max()
    assert np.all(np.abs(H.lam_t[:, floor, 0]) <= 0.05 * np.abs(H.lam[:, floor]) + 5e-16 * scale)  # measured 1.3e-17
    assert np.abs(H.lam_t[:, floor]).max() >= 0.04 * np.abs(H.lam[:, floor]).max()
    F = run_plate("frictionless", "cn", floor="coulomb:0.05")
    assert F.summary()["friction"] == {"law": "coulomb", "coefficient": 0.05, "pairs": ["frictionless"]}
    assert np.all(F.lam_t[:, pair] == 0) and np.abs(F.slip[:, pair]).max() > 1e-5  # the block slides freely
    G = run_plate("coulomb:1000", "cn", floor="frictionless")
    assert G.summary()["friction"] == {
        "law": "coulomb",
        "coefficient": 1000.0,
        "pairs": ["coulomb:1000"],
        "obstacle": "frictionless",
    }
    assert np.all(G.lam_t[:, floor] == 0)


# ----------------------------------------------------------------------------- two free bodies
@pytest.mark.parametrize(
    "friction, scheme, mass, dim",
    [("coulomb:0.3", "cn", "moment-preserving", 2), ("coulomb:0.3", "be", "moment-preserving", 2),
     ("coulomb:0.3", "cn", "standard", 2), ("tresca:0.5", "cn", "moment-preserving", 2),
     ("tresca:0.5", "be", "standard", 2), ("coulomb:0.3", "cn", "moment-preserving", 3)],
)  # fmt: skip
def test_the_pair_keeps_the_total_momentum(friction, scheme, mass, dim):
    """No Dirichlet condition, no load: the normal and tangential forces of the pair balance,
    so 1^T M V is the same at every level in every component.  Measured at most 6.6e-13 of
    |P0| (2D) and 1.8e-13 (3D hexahedra); single-node tangential rows (the slave's slip, not
    relative) lose 32% of the x momentum.  Tresca: |lambda_t| <= s w_i on the rows (measured
    1.7e-16 of the largest s w_i above it)."""
    H = run_blocks(friction, scheme, mass, dim)
    assert H.friction_work[-1] < 0 and (H.contact_status == SLIP).any()
    P = H.momentum
    assert np.abs(P - P[0]).max() <= 1e-11 * np.abs(P[0]).max()
    if friction.startswith("tresca"):
        bound = 0.5 * H.weights
        assert np.all(np.linalg.norm(H.lam_t, axis=2) <= bound + 1e-14 * bound.max())


@pytest.mark.parametrize("scheme", ["cn", "be"])
def test_the_energy_identity_closes_with_friction_on_a_pair(scheme):
    """E^{n+1} - E^n = contact + frictional work at every step (measured 2.5e-14 (CN) and
    1.3e-14 (BE) of max |E|); friction dissipated 22% (CN) and 20% (BE) of E0, and backward
    Euler's frictional work never produces energy (largest step work measured 0)."""
    H = run_blocks("coulomb:0.3", scheme)
    dE = H.energy_increment[1:] - H.predicted_increment[1:]
    assert np.abs(dE).max() <= 5e-13 * np.abs(H.energy).max()
    assert H.friction_work[-1] < -1e-2 * H.energy[0]
    if scheme == "be":
        assert np.diff(H.friction_work).max() <= 1e-14 * np.abs(H.energy).max()


# ----------------------------------------------------------------------------- the rows
def _old_frame_rows(dofs: np.ndarray, vectors: np.ndarray, n_dofs: int):
    """The single-node construction of T and H before pairs carried friction (a frozen copy)."""
    import scipy.sparse as sp

    nc, k, d = vectors.shape
    rows = np.repeat(np.arange(nc * k), d)
    cols = np.repeat(dofs, k, axis=0).ravel()
    return sp.csr_matrix((vectors.ravel(), (rows, cols)), shape=(nc * k, n_dofs))


def _same(A, B) -> bool:
    """Bit-equal sparse matrices: the same stored entries (explicit zeros too) in the same order."""
    return (
        A.shape == B.shape and np.array_equal(A.indptr, B.indptr) and np.array_equal(A.indices, B.indices)
        and np.array_equal(A.data, B.data)
    )  # fmt: skip


def test_obstacle_rows_are_the_single_node_rows_and_pair_rows_are_relative():
    """Bit for bit: T and H of a rigid obstacle's set are the old single-node matrices, alone
    and beside a pair's rows; a pair's normal row of H is B's row, and its tangential row is
    t^T u_s - sum_j N_j t^T u_j (zero sum per component: the tangential forces balance)."""
    mesh = plate_and_block()
    space = VectorSpace(mesh)
    n = space.n_dofs
    rigid = ContactSet.from_tag(space, "plate_ymin", PlaneObstacle([0.0, 0.0], [0.0, 1.0]))
    frame = np.concatenate([rigid.normals[:, None, :], rigid.tangents], axis=1)
    assert _same(rigid.tangential_matrix(n), _old_frame_rows(rigid.dofs, rigid.tangents, n))
    assert _same(rigid.frame_matrix(n), _old_frame_rows(rigid.dofs, frame, n))
    both = rigid.with_pairs(space, [ContactPair("block_ymin", "plate_ymax")])
    r = rigid.size
    T, Hm = both.tangential_matrix(n), both.frame_matrix(n)
    assert _same(T[:r], _old_frame_rows(rigid.dofs, rigid.tangents, n))
    assert _same(Hm[: 2 * r], _old_frame_rows(rigid.dofs, frame, n))
    assert _same(Hm[2 * r :: 2], both.B[r:])
    # the block moved by e, the plate kept: the relative slip t.e; the plate moved: -t.e; both: 0
    e = np.array([0.3, -0.2])
    on_block = (mesh.points[:, 1] > 0.25 + 1e-9) | np.isin(np.arange(mesh.n_nodes), mesh.nodes_of("block_ymin"))
    U_block = (on_block[:, None] * e).ravel()
    U_plate = (~on_block[:, None] * e).ravel()
    t_e = both.tangents[r:, 0] @ e
    assert np.abs(T[r:] @ U_block - t_e).max() <= 1e-15
    assert np.abs(T[r:] @ U_plate + t_e).max() <= 1e-15
    assert np.abs(T[r:] @ (U_block + U_plate)).max() <= 1e-15
    assert np.all(np.diff(T[r:].indptr) >= 4)  # the slave's 2 dofs and at least a master node's


def test_a_moving_obstacle_does_not_drag_the_pairs():
    """obstacle_slip: the obstacle's translation along the tangents on its own rows, zero on a pair's."""
    mesh = plate_and_block()
    space = VectorSpace(mesh)
    ob = PlaneObstacle(lambda t: [0.7 * t, 0.0], [0.0, 1.0])
    both = ContactSet.from_tag(space, "plate_ymin", ob).with_pairs(space, [ContactPair("block_ymin", "plate_ymax")])
    slip = both.obstacle_slip(0.0, 0.1)
    rigid = both.pair < 0
    assert np.allclose(slip[rigid, 0] * both.tangents[rigid, 0, 0], 0.07, rtol=1e-14, atol=0)
    assert np.all(slip[~rigid] == 0) and (~rigid).sum() == 7


def test_the_cone_solve_takes_one_coefficient_per_node():
    """solve_cone with mu per node: equal values give the scalar's solution bit for bit; mixed
    values (0, 0.1, 0.5, 1000) keep each node in its own cone (measured 1.4e-17), and the
    Gauss-Seidel fallback with the same array reaches the Newton solution (measured 6.6e-14)."""
    from signorini.contact.friction import _gauss_seidel, solve_cone

    rng = np.random.default_rng(1)
    m, d = 4, 2
    A = rng.normal(size=(m * d, m * d))
    W = A @ A.T / (m * d) + np.eye(m * d)
    v = np.column_stack([rng.uniform(0.2, 1.0, m), rng.normal(size=m)])  # every node pushed in
    assert np.array_equal(solve_cone(W, v, 0.3).lam, solve_cone(W, v, np.full(m, 0.3)).lam)
    mu = np.array([0.0, 0.1, 0.5, 1e3])
    res = solve_cone(W, v, mu)
    assert np.all(res.lam[:, 0] < 0) and res.lam[0, 1] == 0.0
    assert np.all(np.abs(res.lam[:, 1]) <= mu * np.abs(res.lam[:, 0]) + 1e-15)
    assert res.status.tolist() == [SLIP, SLIP, SLIP, STICK]
    rho = 1.0 / float(np.mean(np.diag(W)))
    lam, _ = _gauss_seidel(W, v.ravel(), np.zeros((m, d)), rho, mu, None, False, 1e-13, 1.0, 5000, d)
    assert np.abs(lam - res.lam).max() <= 1e-12


# ----------------------------------------------------------------------------- input
def test_mixed_law_kinds_and_1d_friction_are_refused():
    with pytest.raises(InputError, match=r"share one law.*") as err:
        block_on_plate("coulomb:0.3", floor="tresca:0.01")
    assert "'block_ymin' / 'plate_ymax' coulomb:0.3" in str(err.value) and "\n" not in str(err.value)
    a, b = interval(4, 1.0), interval(4, 1.0)
    b.points = b.points + 1.1
    with pytest.raises(InputError, match="needs a 2D or 3D problem"):
        Problem(join({"a": a, "b": b}), MATERIAL, None, None, pairs=[ContactPair("b_xmin", "a_xmax", "coulomb:0.3")])
    with pytest.raises(InputError, match="contact pair 'b' / 'a' friction"):
        ContactPair("b", "a", {"law": "coulomb"})
    p = ContactPair("b", "a", {"law": "tresca", "threshold": 0.01})
    assert p.friction == Friction("tresca", 0.0, 0.01) and ContactPair("b", "a").friction is None


def _pair_case(tmp_path: Path, pair: str) -> Path:
    write_mesh(plate_and_block(), tmp_path / "m.msh")
    text = (
        '[mesh]\ngenerator = "file"\nfile = "m.msh"\n[material]\nrho = 1.0\nE = 100.0\nnu = 0.3\n'
        '[[dirichlet]]\ntag = "plate_ymin"\nvalue = [0.0, 0.0]\n'
        '[loads]\nbody_force = [0.0, "-min(t / 0.3, 1)"]\n'
        f'[contact]\nfriction = {{ law = "coulomb", coefficient = 0.1 }}\npairs = [{pair}]\n'
        '[time]\nscheme = "be"\ndt = 0.01\nT = 0.05\n'
    )
    path = tmp_path / "c.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    "friction, message",
    [("3", "must be a table"), ('{ law = "coulomb" }', "needs 'coefficient'"),
     ('{ law = "coulomb", coefficient = -1.0 }', "coefficient"), ('{ law = "stick" }', "stick"),
     ('{ law = "tresca", threshold = 0.1, coefficient = 0.3 }', "unknown option 'coefficient'"),
     ('"coulomb"', "needs a value")],
)  # fmt: skip
def test_a_pairs_friction_in_the_case_file_is_checked(tmp_path, friction, message):
    from signorini.io.config import load_case

    path = _pair_case(tmp_path, f'{{ slave = "block_ymin", master = "plate_ymax", friction = {friction} }}')
    with pytest.raises(InputError, match=message) as err:
        load_case(path)
    assert "contact.pairs[0].friction" in str(err.value) and "\n" not in str(err.value)


def test_a_pairs_friction_in_the_case_file_runs_and_is_reported(tmp_path):
    """The key parses (and a misspelt key is refused); the run's summary.json has the pair's law."""
    from signorini.io.cli import main
    from signorini.io.config import load_case

    path = _pair_case(tmp_path, '{ slave = "block_ymin", master = "plate_ymax", frction = 0.3 }')
    with pytest.raises(InputError, match=r"contact.pairs\[0\]' needs the keys slave and master .* friction"):
        load_case(path)
    path = _pair_case(
        tmp_path,
        '{ slave = "block_ymin", master = "plate_ymax", friction = { law = "coulomb", coefficient = 0.6 } }',
    )
    case = load_case(path)
    assert case.problem.pairs[0].friction == Friction("coulomb", 0.6)
    assert discretize(case.problem).friction == Friction("coulomb", 0.6)  # the section's 0.1 applies to no row
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["friction"] == {"law": "coulomb", "coefficient": 0.6}
    assert s["pairs"][0]["friction"] == {"law": "coulomb", "coefficient": 0.6} and s["pairs"][0]["rows"] == 7
