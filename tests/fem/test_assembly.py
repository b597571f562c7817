import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from signorini.fem import assembly
from signorini.fem.material import IsotropicElastic
from signorini.fem.mesh import box, interval, rectangle
from signorini.fem.space import Constraints, Dirichlet, VectorSpace

MAT = IsotropicElastic(0.25, 0.5, 1.0)
MESHES = {
    "line": lambda: interval(5, 2.0),
    "quad": lambda: rectangle(3, 4, 0.5, 2.0),
    "triangle": lambda: rectangle(3, 4, 0.5, 2.0, "triangle"),
    "hexahedron": lambda: box(2, 3, 2, 1.0, 2.0, 0.5),
    "tetra": lambda: box(2, 2, 3, 1.0, 1.0, 1.5, "tetra"),
}


@pytest.mark.parametrize("kind", MESHES)
def test_mass_totals_and_lumping(kind):
    mesh = MESHES[kind]()
    rho = 2.5
    M = assembly.mass_matrix(mesh, rho)
    vol = assembly.cell_volumes(mesh).sum()
    d = mesh.dim
    for k in range(d):
        one = np.zeros(M.shape[0])
        one[k::d] = 1.0
        assert np.isclose(one @ M @ one, rho * vol, rtol=1e-14, atol=0)  # measured 1.8e-16 relative
    L = assembly.lumped_mass_matrix(M)
    assert np.allclose(L.diagonal(), np.asarray(M.sum(axis=1)).ravel(), rtol=1e-15, atol=0)  # measured 0


@pytest.mark.parametrize("kind", MESHES)
def test_stiffness_symmetric_psd_rigid_kernel(kind):
    mesh = MESHES[kind]()
    S = assembly.stiffness_matrix(mesh, MAT).toarray()
    assert np.allclose(S, S.T, rtol=0, atol=1e-14)  # a few ulps of the largest entry (7.8); measured 2.8e-17
    ev = np.linalg.eigvalsh(S)
    assert ev.min() > -1e-12 * ev.max()
    n_zero = int(np.sum(ev < 1e-9 * ev.max()))
    assert n_zero == {1: 1, 2: 3, 3: 6}[mesh.dim]


def _distorted(mesh, rng, amount=0.2):
    interior = np.ones(mesh.n_nodes, bool)
    for t in mesh.tags:
        interior[mesh.nodes_of(t)] = False
    h = np.min(np.ptp(mesh.points, axis=0)) / 4
    mesh.points[interior] += amount * h * rng.uniform(-1, 1, (interior.sum(), mesh.dim))
    mesh._cache.clear()
    return mesh


@pytest.mark.parametrize("kind", ["quad", "triangle", "hexahedron", "tetra"])
def test_patch_test_linear_field_exact(kind, rng):
    mesh = _distorted(MESHES[kind](), rng)
    mesh.check_cells()
    d = mesh.dim
    G = rng.normal(size=(d, d))
    c = rng.normal(size=d)

    def exact(x):
        return x @ G.T + c

    space = VectorSpace(mesh)
    cons = Constraints(space, [Dirichlet(t, exact) for t in mesh.tags])
    S = assembly.stiffness_matrix(mesh, MAT)
    u = _static_solve(S, np.zeros(S.shape[0]), cons)
    # docs/verification.md: linear fields and constant stresses exact to round-off (measured 1.8e-15 and
    # 4.9e-15 on values up to 6.1 and 2.3; bounds about 100x that)
    assert np.allclose(u, space.interpolate(exact), rtol=0, atol=2e-13)
    sig = assembly.stress(mesh, MAT, u, nodal=False)
    eps = 0.5 * (G + G.T)
    assert np.allclose(sig, MAT.stress(eps)[None], rtol=0, atol=5e-13)


def _manufactured(dim):
    lam, mu, pi = MAT.lam, MAT.mu, np.pi

    def u(x):
        out = np.zeros_like(x)
        out[..., 0] = np.prod(np.sin(pi * x), axis=-1)
        return out

    def f(x):
        s, c = np.sin(pi * x), np.cos(pi * x)
        out = np.zeros_like(x)
        out[..., 0] = (lam + mu + dim * mu) * pi**2 * np.prod(s, axis=-1) if dim == 3 else 0
        if dim == 2:
            out[..., 0] = (lam + 3 * mu) * pi**2 * s[..., 0] * s[..., 1]
            out[..., 1] = -(lam + mu) * pi**2 * c[..., 0] * c[..., 1]
        else:
            out[..., 1] = -(lam + mu) * pi**2 * c[..., 0] * c[..., 1] * s[..., 2]
            out[..., 2] = -(lam + mu) * pi**2 * c[..., 0] * s[..., 1] * c[..., 2]
        return out

    def grad(x):
        s, c = np.sin(pi * x), np.cos(pi * x)
        g = np.zeros(x.shape + (x.shape[-1],))
        for j in range(x.shape[-1]):
            g[..., 0, j] = pi * c[..., j] * np.prod(np.delete(s, j, axis=-1), axis=-1)
        return g

    return u, f, grad


def _static_errors(mesh):
    from signorini.fem.elements import reference_element

    u_ex, f, grad = _manufactured(mesh.dim)
    space = VectorSpace(mesh)
    cons = Constraints(space, [Dirichlet(t, 0.0) for t in mesh.tags])
    S = assembly.stiffness_matrix(mesh, MAT)
    F = assembly.body_load(mesh, f)
    u = _static_solve(S, F, cons)
    ref = reference_element(mesh.cell_type)
    wdet, G = assembly.geometry(mesh)
    xq = assembly.quadrature_points(mesh)
    ue = u.reshape(-1, mesh.dim)[mesh.cells]
    uh = np.einsum("qa,eai->eqi", ref.N, ue)
    guh = np.einsum("eqaj,eai->eqij", G, ue)
    l2 = np.sqrt(np.sum(wdet * np.sum((uh - u_ex(xq)) ** 2, -1)))
    h1 = np.sqrt(np.sum(wdet * np.sum((guh - grad(xq)) ** 2, axis=(-1, -2))))
    return l2, h1


@pytest.mark.parametrize(
    "make, levels, finest",
    [
        (lambda n: rectangle(n, n), (4, 8, 16), (1.8e-3, 0.14)),
        (lambda n: rectangle(n, n, cell="triangle"), (4, 8, 16), (6.1e-3, 0.24)),
        (lambda n: box(n, n, n), (2, 4, 8), (5.2e-3, 0.24)),
        (lambda n: box(n, n, n, cell="tetra"), (2, 4, 8), (2.7e-2, 0.53)),
    ],
    ids=["quad", "triangle", "hexahedron", "tetra"],
)
def test_manufactured_static_convergence_rates(make, levels, finest):
    """Static P1/Q1 solves against the exact manufactured solution u = (prod_i sin(pi x_i), 0[, 0])
    on the unit square/cube, clamped all round (no reference run: the errors are against the
    closed form, at the quadrature points).  The rate of the last pair (h -> h/2) is checked
    two-sided around the theory (L2 ~ 2, H1 ~ 1), and the finest level's errors are bounded
    (10% above the measured ones).

    Measured (L2, H1): rates quad (1.99, 1.00), triangle (1.95, 0.99), hexahedron (1.98,
    0.99), tetra (1.78, 0.93, still pre-asymptotic at n = 8); finest errors quad (1.66e-3,
    0.126), triangle (5.58e-3, 0.218), hexahedron (4.74e-3, 0.218), tetra (2.49e-2, 0.480).
    """
    errs = np.array([_static_errors(make(n)) for n in levels])
    rates = np.log2(errs[:-1] / errs[1:])
    assert 1.7 <= rates[-1, 0] <= 2.3, rates  # L2 ~ 2
    assert 0.85 <= rates[-1, 1] <= 1.15, rates  # H1 ~ 1
    assert errs[-1, 0] <= finest[0] and errs[-1, 1] <= finest[1], errs[-1]


def test_bar_1d_static_exact():
    # -E u'' = f on (0, L), u(0) = u(L) = 0: P1 is nodally exact, u = f x (L - x) / (2E)
    E, f, L = 3.0, 2.0, 2.0
    mesh = interval(8, L)
    mat = IsotropicElastic.from_young(E, 0.0)
    space = VectorSpace(mesh)
    cons = Constraints(space, [Dirichlet("xmin", 0.0), Dirichlet("xmax", 0.0)])
    S = assembly.stiffness_matrix(mesh, mat)
    F = assembly.body_load(mesh, [f])
    u = _static_solve(S, F, cons)
    x = mesh.points[:, 0]
    assert np.allclose(u, f * x * (L - x) / (2 * E), rtol=0, atol=1e-14)  # nodally exact: measured 5.6e-17 (u <= 0.33)


def test_surface_load_and_weights():
    mesh = box(2, 3, 4, 1.0, 2.0, 3.0)
    w = assembly.facet_weights(mesh, "zmin")
    assert np.isclose(w.sum(), 2.0, rtol=1e-14, atol=0)  # measured 2.2e-16 relative
    F = assembly.surface_load(mesh, "xmax", [0.0, 0.0, -1.5])
    assert np.isclose(F[2::3].sum(), -1.5 * 6.0, rtol=1e-14, atol=0)  # measured 3.9e-16 relative


@pytest.mark.parametrize("cell", ["hexahedron", "tetra"])
def test_strain_of_an_affine_displacement_is_exact(cell, rng):
    mesh = box(2, 3, 2, 1.0, 0.7, 1.3, cell=cell)
    A = rng.normal(size=(3, 3))
    u = mesh.points @ A.T  # u_i = A_ij x_j
    eps = assembly.strain(mesh, u.ravel())
    assert np.allclose(eps, 0.5 * (A + A.T), rtol=0, atol=1e-13)  # measured 4.4e-15 (|eps| <= 1.9)


@pytest.mark.parametrize("kind", ["triangle", "hexahedron", "tetra"])
def test_vector_assembly_equals_the_block_route(kind, rng):
    """Entries written straight into CSR equal the BSR assembly converted by scipy."""
    mesh = MESHES[kind]()
    d = mesh.dim
    Ke = rng.standard_normal((mesh.n_cells, mesh.cells.shape[1], mesh.cells.shape[1], d, d))
    indptr, indices, slot = assembly.node_pattern(mesh)
    blocks = np.zeros((indices.size, d, d))
    np.add.at(blocks, slot.ravel(), Ke.reshape(-1, d, d))
    n = d * mesh.n_nodes
    expected = sp.bsr_matrix((blocks, indices, indptr), shape=(n, n)).tocsr()
    got = assembly.assemble_vector(mesh, Ke)
    same_row = np.diff(np.repeat(np.arange(n), np.diff(got.indptr))) == 0
    assert got.has_sorted_indices and np.all(np.diff(got.indices)[same_row] > 0)
    assert np.array_equal(got.indptr, expected.indptr) and np.array_equal(got.indices, expected.indices)
    assert np.allclose(got.data, expected.data, rtol=0, atol=1e-13)  # measured 0 (|entries| <= 11)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_vectorize_is_the_kronecker_product_with_the_identity(dim):
    """m (x) I_d with node-major dofs, for a matrix with empty rows and unsorted indices."""
    rng = np.random.default_rng(dim)
    m = sp.random(9, 9, density=0.3, format="csr", random_state=rng)
    order = np.lexsort((-np.arange(m.nnz), np.repeat(np.arange(9), np.diff(m.indptr))))  # each row reversed
    m = sp.csr_matrix((m.data[order], m.indices[order], m.indptr), shape=m.shape)
    assert np.diff(np.diff(m.indptr)).any() and not m.has_sorted_indices
    V = assembly.vectorize(m, dim)
    ref = sp.kron(m, sp.identity(dim), format="csr")
    assert V.shape == ref.shape and abs(V - ref).max() == 0 and V.nnz == dim * m.nnz


def _static_solve(S, F, cons):
    """u with u_D prescribed and S_ff u_f = F_f - S_fD u_D (a static solve for the patch tests)."""
    import scipy.sparse as sp

    S = sp.csr_matrix(S)
    u = np.zeros(S.shape[0])
    u[cons.fixed] = cons.values
    f, D = cons.free, cons.fixed
    rhs = F[f] - S[f][:, D] @ u[D]
    u[f] = spla.spsolve(sp.csc_matrix(S[f][:, f]), rhs)
    return u


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_cell_tensors_of_a_homogeneous_strain_are_the_laws_stress_everywhere(dim):
    """u = G x (G symmetric): every cell's mean strain is G and its stress C G as 3 x 3 tensors (plane strain's
    sigma_zz = lam tr G in 2D, the bar's E G_xx alone in 1D), to round-off; the von Mises stress of the same cells
    agrees with the tensor's."""
    from signorini.fem.assembly import cell_tensors, von_mises
    from signorini.fem.material import IsotropicElastic
    from signorini.fem.mesh import box, interval, rectangle

    mesh = interval(5) if dim == 1 else rectangle(3, 2, cell="triangle") if dim == 2 else box(2, 2, 2, cell="tetra")
    mat = IsotropicElastic.from_young(2.0e11, 0.3, 7800.0)
    G = np.array([[1.0, 0.4, -0.2], [0.4, -0.5, 0.3], [-0.2, 0.3, 0.7]])[:dim, :dim] * 1e-3
    u = (mesh.points @ G.T).ravel()
    eps, sig = cell_tensors(mesh, mat, u)
    E3 = np.zeros((3, 3))
    E3[:dim, :dim] = G
    if dim == 1:
        S3 = np.zeros((3, 3))
        S3[0, 0] = mat.young * G[0, 0]
    else:
        S3 = mat.lam * np.trace(G) * np.eye(3) + 2 * mat.mu * E3
        if dim == 2:
            S3[2, 2] = mat.lam * np.trace(G)  # plane strain: eps_zz = 0
    assert eps.shape == sig.shape == (mesh.n_cells, 3, 3)
    assert np.allclose(eps, E3, rtol=0, atol=1e-15)
    assert np.allclose(sig, S3, rtol=1e-12, atol=1e-12 * np.abs(S3).max())
    dev = S3 - np.trace(S3) / 3 * np.eye(3)
    vm = abs(S3[0, 0]) if dim == 1 else np.sqrt(1.5 * np.sum(dev * dev))
    assert np.allclose(von_mises(mesh, mat, u, nodal=False), vm, rtol=1e-12, atol=0)
