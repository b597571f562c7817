import numpy as np
import pytest

from signorini.dynamics.model.mass import linear_cell_variants, mass_matrix, moment_preserving_1d
from signorini.errors import InputError
from signorini.fem.mesh import box, interval, rectangle

CASES = {
    "line": (lambda: interval(6, 1.5), "xmin"),
    "quad": (lambda: rectangle(3, 6, 0.3, 1.0), "ymin"),
    "hexahedron": (lambda: box(2, 2, 5, 0.2, 0.2, 1.0), "zmin"),
    "triangle": (lambda: rectangle(3, 6, 0.3, 1.0, "triangle"), "ymin"),
    "tetra": (lambda: box(2, 2, 4, 0.2, 0.2, 1.0, "tetra"), "zmin"),
}
EXPECTED_KERNEL = {
    "standard": 0,
    "lumped": 0,
    "seed": "d",
    "seed-normal": 1,
    "moment-preserving": "d",
    "moment-preserving-tensor": "d",
    "neighbour": "d",
    "mass-free-surface": "d",
}


def _moments(M, x, d, k):
    """int 1, int x_j, int x_i x_j for component k, from the matrix."""
    n = x.shape[0]
    basis = [np.ones(n)] + [x[:, j] for j in range(x.shape[1])]
    out = []
    for a in range(len(basis)):
        for b in range(a, len(basis)):
            pa = np.zeros(M.shape[0])
            pb = np.zeros(M.shape[0])
            pa[k::d] = basis[a]
            pb[k::d] = basis[b]
            out.append(pa @ M @ pb)
    return np.array(out)


@pytest.mark.parametrize("kind, name", [(k, n) for k in CASES for n in linear_cell_variants()])
def test_kernel_psd_and_moments(kind, name):
    make, tag = CASES[kind]
    mesh = make()
    nodes = mesh.nodes_of(tag)
    normals = np.tile(-np.eye(mesh.dim)[-1], (nodes.size, 1))
    if name == "moment-preserving-tensor" and kind in ("triangle", "tetra"):
        with pytest.raises(InputError, match="use 'moment-preserving' on other meshes"):
            mass_matrix(name, mesh, 2.0, nodes, normals)
        return
    M = mass_matrix(name, mesh, 2.0, nodes, normals).toarray()
    d = mesh.dim
    assert np.allclose(M, M.T, rtol=0, atol=1e-14)  # entries <= 1.3: measured 5.6e-17
    ev = np.linalg.eigvalsh(M)
    assert ev.min() > -1e-12 * ev.max()
    kern = int(np.sum(np.abs(ev) < 1e-12 * ev.max()))
    expected = EXPECTED_KERNEL[name]
    expected = nodes.size * (d if expected == "d" else expected)
    assert kern == expected
    std = mass_matrix("standard", mesh, 2.0).toarray()
    for k in range(d):
        ref = _moments(std, mesh.points, d, k)
        got = _moments(M, mesh.points, d, k)
        if name in ("standard", "moment-preserving", "moment-preserving-tensor"):
            assert np.allclose(got, ref, rtol=0, atol=4e-14)  # measured 4.4e-16 (entries <= 3)
        elif name == "lumped":
            # mass and first moments: measured 3.5e-16 relative
            assert np.allclose(got[: 1 + mesh.dim], ref[: 1 + mesh.dim], rtol=1e-14, atol=0)
        elif name == "seed" or (name == "seed-normal" and k == d - 1):
            assert got[0] < ref[0]  # the seed mass loses the contact layer's mass
        elif name == "seed-normal":
            assert np.allclose(got, ref, rtol=1e-14, atol=0)  # tangential components keep the standard mass: 0
        else:  # neighbour, mass-free-surface: total mass kept, centre of gravity moves
            assert np.isclose(got[0], ref[0], rtol=1e-14, atol=0)  # measured 1.7e-16


def test_moment_preserving_1d_closed_form():
    h = 0.25
    M = moment_preserving_1d(np.linspace(0, 1, 5), 1.0).toarray()
    assert not M[0].any() and not M[:, 0].any()  # the contact node is massless: exact zeros
    assert np.allclose([M[1, 1], M[1, 2], M[2, 2]], [8 * h / 3, -2 * h / 3, h], rtol=1e-14, atol=0)  # measured 3.3e-16
    Mmax = moment_preserving_1d(np.linspace(0, 1, 5), 1.0, end="max").toarray()
    assert np.allclose(Mmax, M[::-1, ::-1], rtol=0, atol=1e-15)  # entries <= 0.67: measured 0


def test_moment_preserving_on_a_distorted_unstructured_mesh(rng):
    from signorini.dynamics.model.mass import extrapolation_operator

    mesh = rectangle(6, 8, 1.0, 1.0, "triangle")
    interior = np.ones(mesh.n_nodes, bool)
    for t in mesh.tags:
        interior[mesh.nodes_of(t)] = False
    mesh.points[interior] += 0.03 * rng.uniform(-1, 1, (interior.sum(), 2))
    mesh._cache.clear()
    nodes = mesh.nodes_of("ymin")
    T = extrapolation_operator(mesh, nodes)
    affine = 0.3 + mesh.points @ np.array([1.2, -0.7])
    assert np.allclose(T @ affine, affine, rtol=0, atol=1e-13)  # affine fields are reproduced exactly: 1.8e-15
    M = mass_matrix("moment-preserving", mesh, 1.5, nodes).toarray()
    std = mass_matrix("standard", mesh, 1.5).toarray()
    ev = np.linalg.eigvalsh(M)
    assert ev.min() > -1e-14 * ev.max() and int(np.sum(ev < 1e-12 * ev.max())) == 2 * nodes.size  # measured min 0
    for k in range(2):
        # measured 1.7e-16 (moments <= 1.5)
        assert np.allclose(_moments(M, mesh.points, 2, k), _moments(std, mesh.points, 2, k), rtol=0, atol=1.5e-14)


def test_errors():
    mesh = interval(3)
    with pytest.raises(InputError, match="unknown mass 'heavy'; allowed"):
        mass_matrix("heavy", mesh, 1.0)
    with pytest.raises(InputError, match="contact nodes"):
        mass_matrix("seed", mesh, 1.0, np.array([], dtype=int))
    with pytest.raises(InputError, match="normals"):
        mass_matrix("seed-normal", rectangle(2, 2), 1.0, rectangle(2, 2).nodes_of("ymin"), None)


@pytest.mark.parametrize("normal", [[0.6, -0.8], [0.0, -1.0]])
def test_seed_normal_any_direction(normal):
    """seed-normal through the nodal frames: the normal component of every contact node is
    massless, M stays symmetric positive semi-definite, and a translation along the
    (flat) boundary's tangent keeps the whole standard mass."""
    mesh = rectangle(3, 3)
    nodes = mesh.nodes_of("ymin")
    nu = np.tile(np.asarray(normal) / np.linalg.norm(normal), (nodes.size, 1))
    M = mass_matrix("seed-normal", mesh, 1.0, nodes, nu).toarray()
    e = np.zeros(M.shape[0])
    for i, node in enumerate(nodes):
        e[:] = 0.0
        e[2 * node : 2 * node + 2] = nu[i]
        assert np.abs(M @ e).max() <= 1e-15 * np.abs(M).max()
    assert np.abs(M - M.T).max() <= 1e-15 * np.abs(M).max()  # the assembly's summation order
    assert np.linalg.eigvalsh(M).min() >= -1e-15 * np.abs(M).max()
    t = np.array([-nu[0, 1], nu[0, 0]])  # the tangent: a translation along it keeps the whole mass
    E = np.tile(t, mesh.n_nodes)
    std = mass_matrix("standard", mesh, 1.0).toarray()
    assert abs(E @ M @ E - E @ std @ E) <= 1e-14 * (E @ std @ E)


# --------------------------------------------------------------------- one meaning per name
ROTATION_INVARIANT = ["standard", "lumped", "seed", "moment-preserving", "neighbour", "mass-free-surface"]


@pytest.mark.parametrize("name", linear_cell_variants())
@pytest.mark.parametrize("cell", ["quad", "triangle"])
def test_generated_mesh_and_the_same_mesh_from_a_file_give_one_matrix(tmp_path, name, cell):
    import meshio

    from signorini.fem.mesh import read_mesh

    gen = rectangle(3, 6, 0.3, 1.0, cell)
    meshio.write(tmp_path / "bar.vtu", meshio.Mesh(gen.points, [(gen.cell_type, gen.cells)]))
    read = read_mesh(tmp_path / "bar.vtu")
    assert read.grid is None and np.array_equal(read.points, gen.points)
    nodes = np.flatnonzero(np.isclose(gen.points[:, 1], 0.0, rtol=0, atol=1e-12))  # the row y = 0 (next: 1/6)
    normals = np.tile([0.0, -1.0], (nodes.size, 1))
    if name == "moment-preserving-tensor":  # defined on generated grids only, by name
        with pytest.raises(InputError, match="moment-preserving-tensor"):
            mass_matrix(name, read, 2.0, nodes, normals)
        return
    a = mass_matrix(name, gen, 2.0, nodes, normals)
    b = mass_matrix(name, read, 2.0, nodes, normals)
    assert abs(a - b).max() <= 1e-14 * abs(a).max()


@pytest.mark.parametrize("name", ROTATION_INVARIANT)
def test_rotating_the_problem_rotates_the_solution(name):
    """The 2D bar and the same bar rotated by 0.7 rad: contact forces equal to 1e-10."""
    from signorini.contact.obstacles import PlaneObstacle
    from signorini.dynamics.model.problem import Problem
    from signorini.dynamics.stepping.simulate import simulate
    from signorini.fem.mesh import Mesh
    from signorini.studies.benchmarks import get_benchmark

    p = get_benchmark("bar2d").problem(2)
    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[c, -s], [s, c]])
    m = p.mesh
    mesh = Mesh(m.points @ R.T, m.cells, m.cell_type, dict(m.facets))
    e = R @ np.array([0.0, 1.0])
    from signorini.fem.space import Dirichlet

    rotated = Problem(
        mesh, p.material, "ymin", PlaneObstacle(R @ np.zeros(2), e), [Dirichlet("ymax", tuple(0.2 * e))],
        u0=0.2 * e, v0=-0.5 * e, name="rotated",
    )  # fmt: skip
    a = simulate(p, "cn", 0.025, 0.6, mass=name)
    b = simulate(rotated, "cn", 0.025, 0.6, mass=name)
    scale = np.abs(a.lam).max()
    assert scale > 0  # there is contact
    assert np.abs(a.lam - b.lam).max() <= 1e-10 * scale
    assert np.allclose(a.energy, b.energy, rtol=4e-11, atol=0)  # energies ~0.01: measured 4.9e-13 relative
