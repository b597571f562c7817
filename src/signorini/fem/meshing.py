"""Meshes of a ball (3D) or a disc (2D) refined towards one pole, made with gmsh.

gmsh is an optional dependency (``pip install ".[mesh]"``), imported only when a mesh
is made here.  Its wheel links against a few X/OpenGL libraries even when no window is
opened; on a bare Debian they come with ``apt-get install libglu1-mesa libgl1
libxrender1 libxcursor1 libxfixes3 libxext6 libxft2 libfontconfig1 libxinerama1
libx11-6 libgomp1`` (the NEEDED entries of ``libgmsh.so`` 4.15).

Geometry: the ball (disc) of radius R centred at (0, .., 0, R), so that its pole
(0, .., 0) touches the plane x_d = 0.  The body is cut by the plane x_d = R (1 - cos
theta_c) into a cap and the rest, meshed conformingly; boundary tags:

``cap``      the spherical (circular) boundary of the cap, polar angle <= theta_c
             around the pole: the contact candidates;
``surface``  the rest of the boundary.

Mesh size: ``h_contact`` within a distance ``r_fine`` of the pole, growing linearly with
the distance at rate ``grading`` (size increase per unit distance) up to ``h_far``.
Cells: P1 triangles (2D) or P1 tetrahedra (3D), positively oriented.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError, MeshError
from ..optional import optional_import
from .mesh import Mesh

APT_HINT = (
    "(on a bare Debian gmsh also needs: apt-get install libglu1-mesa libgl1 libxrender1 libxcursor1 "
    "libxfixes3 libxext6 libxft2 libfontconfig1 libxinerama1 libx11-6 libgomp1)"
)


def import_gmsh():
    """The gmsh module, or an :class:`InputError` saying how to install it."""
    return optional_import("gmsh", "the hertz benchmarks' meshes", "mesh", APT_HINT)


def size_at(distance: np.ndarray, h_contact: float, h_far: float, r_fine: float, grading: float) -> np.ndarray:
    """Target element size at a distance from the pole [length]:
    min(h_far, h_contact + grading max(0, distance - r_fine))."""
    return np.minimum(h_far, h_contact + grading * np.maximum(0.0, np.asarray(distance) - r_fine))


def estimate_counts(
    dim: int, R: float, h_contact: float, h_far: float, r_fine: float, grading: float
) -> tuple[int, int, int]:
    """(nodes, cells, contact nodes) expected of :func:`pole_refined_ball`, without gmsh.

    Integrates 1/(cell measure at the local size) over the body, cell measure
    sqrt(3)/4 h^2 (triangle) or h^3/(6 sqrt 2) (regular tetrahedron), nodes = cells/2
    (2D) or cells/5.5 (3D), on the distance from the pole; within a factor 2 of gmsh's
    counts, enough for the run-size estimate.
    """
    r = np.linspace(0.0, 2 * R, 4001)[1:]
    dr = r[1] - r[0]
    h = size_at(r, h_contact, h_far, r_fine, grading)
    # measure of the body at distance r from the pole: arc (2D) or spherical-cap band (3D)
    if dim == 2:
        band = 2 * r * np.arccos(np.clip(r / (2 * R), -1, 1))
        cells = float(np.sum(band / (math.sqrt(3) / 4 * h**2)) * dr)
        nodes = cells / 2
    else:
        band = 2 * np.pi * r**2 * (1 - r / (2 * R))
        cells = float(np.sum(band / (h**3 / (6 * math.sqrt(2)))) * dr)
        nodes = cells / 5.5
    r_cap = r_fine
    contact = 2 * r_cap / h_contact + 1 if dim == 2 else math.pi * r_cap**2 / (math.sqrt(3) / 2 * h_contact**2)
    return int(nodes) + 1, int(cells) + 1, int(contact) + 1


def pole_refined_ball(
    dim: int,
    R: float,
    cap_angle: float,
    h_contact: float,
    h_far: float,
    r_fine: float,
    grading: float = 0.5,
    order: int = 1,
) -> Mesh:
    """A disc (dim 2) or ball (dim 3) of radius R touching x_d = 0 at the origin; ``order`` 2: quadratic cells
    (``triangle6``, ``tetra10``) whose new nodes gmsh places on the circle or sphere (curved facets).

    Parameters
    ----------
    R : radius [length].
    cap_angle : polar half-angle theta_c of the ``cap`` tag around the pole [rad], in (0, pi/2].
    h_contact, h_far : element sizes at the pole and far from it [length].
    r_fine : distance from the pole within which the size is ``h_contact`` [length].
    grading : growth of the size per unit distance beyond ``r_fine`` (dimensionless).
    """
    if dim not in (2, 3):
        raise InputError(f"dim must be 2 or 3, got {dim!r}")
    if not 0 < cap_angle <= math.pi / 2:
        raise InputError(f"cap angle must be in (0, 90] degrees, got {math.degrees(cap_angle):.6g}")
    for name, v in (("R", R), ("h_contact", h_contact), ("h_far", h_far), ("grading", grading)):
        if not (math.isfinite(v) and v > 0):
            raise InputError(f"{name} must be a positive number, got {v!r}")
    gmsh = import_gmsh()
    gmsh.initialize(["-noenv"], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.Verbosity", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.add("ball")
        occ = gmsh.model.occ
        z_cut = R * (1 - math.cos(cap_angle))
        if dim == 3:  # the sphere's parametric poles are vertices: a node sits at the contact pole
            occ.fragment([(3, occ.addSphere(0, 0, R, R))], [(2, occ.addDisk(0, 0, z_cut, 3 * R, 3 * R))])
        else:  # four arcs and the cap's chord, with a vertex at the pole
            _disc_with_cap(occ, R, cap_angle, z_cut)
        occ.synchronize()
        cap, rest = _classify_boundary(gmsh, dim, z_cut)
        dist = "sqrt(x*x+y*y+z*z)" if dim == 3 else "sqrt(x*x+y*y)"
        field = gmsh.model.mesh.field
        f = field.add("MathEval")
        field.setString(f, "F", f"min({h_far!r}, {h_contact!r} + {grading!r}*max(0, {dist} - {r_fine!r}))")
        field.setAsBackgroundMesh(f)
        for opt in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
            gmsh.option.setNumber(f"Mesh.{opt}", 0)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h_far)
        gmsh.model.mesh.generate(dim)
        if order == 2:
            gmsh.model.mesh.setOrder(2)
        return _to_mesh(gmsh, dim, cap, rest, order)
    finally:
        gmsh.finalize()


def _disc_with_cap(occ, R: float, cap_angle: float, z_cut: float) -> None:
    """The disc centred at (0, R) as two surfaces: the cap below the chord y = z_cut, and the rest."""
    half = R * math.sin(cap_angle)
    centre, pole, top = occ.addPoint(0, R, 0), occ.addPoint(0, 0, 0), occ.addPoint(0, 2 * R, 0)
    right, left = occ.addPoint(half, z_cut, 0), occ.addPoint(-half, z_cut, 0)
    chord = occ.addLine(right, left)
    cap = [occ.addCircleArc(pole, centre, right), chord, occ.addCircleArc(left, centre, pole)]
    rest = [occ.addCircleArc(right, centre, top), occ.addCircleArc(top, centre, left), -chord]
    occ.addPlaneSurface([occ.addCurveLoop(cap)])
    occ.addPlaneSurface([occ.addCurveLoop(rest)])


def _classify_boundary(gmsh, dim: int, z_cut: float) -> tuple[list[int], list[int]]:
    """Boundary entities of the body below / above the cut (the cut itself is interior), by the middle of their
    bounding boxes: OpenCASCADE pads a box by its own tolerance (about 1e-7, absolute), so that a cap of a ball of
    a few centimetres reaches above the cut by more than a relative 1e-6 of its radius (a 5 cm ball had no cap)."""
    cap, rest = [], []
    body = gmsh.model.getEntities(dim)
    for d, tag in gmsh.model.getBoundary(body, combined=True, oriented=False):
        lo = gmsh.model.getBoundingBox(d, tag)
        zmin, zmax = (lo[2], lo[5]) if dim == 3 else (lo[1], lo[4])
        (cap if 0.5 * (zmin + zmax) < z_cut else rest).append(tag)
    if not cap:
        raise MeshError("gmsh produced no cap boundary; increase the cap angle")
    return cap, rest


def _elements(gmsh, dim: int, tags: list[int], etype: int) -> np.ndarray:
    out = []
    for tag in tags:
        types, _, nodes = gmsh.model.mesh.getElements(dim, tag)
        for t, n in zip(types, nodes, strict=True):
            if t == etype:
                out.append(np.asarray(n, dtype=np.int64))
    npe = {1: 2, 2: 3, 4: 4, 8: 3, 9: 6, 11: 10}[etype]
    return np.concatenate(out).reshape(-1, npe) if out else np.zeros((0, npe), dtype=np.int64)


#: gmsh's element types of (dim, order): (cell type, cell element, facet element); its tetra10 lists the midpoints
#: of edges (2, 3) and (1, 3) in the other order than VTK's (meshio swaps them alike)
_GMSH_TYPES = {
    (2, 1): ("triangle", 2, 1),
    (3, 1): ("tetra", 4, 2),
    (2, 2): ("triangle6", 9, 8),
    (3, 2): ("tetra10", 11, 9),
}


def _to_mesh(gmsh, dim: int, cap: list[int], rest: list[int], order: int = 1) -> Mesh:
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    pts = np.asarray(coords).reshape(-1, 3)[:, :dim]
    node_tags = np.asarray(node_tags, dtype=np.int64)
    volumes = [t for _, t in gmsh.model.getEntities(dim)]
    cell_type, etype, ftype = _GMSH_TYPES[(dim, order)]
    cells_g = _elements(gmsh, dim, volumes, etype)
    if cell_type == "tetra10":
        cells_g = cells_g[:, [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]]
    used = np.unique(cells_g)
    index = np.full(int(node_tags.max()) + 1, -1, dtype=np.int64)
    index[node_tags] = np.arange(node_tags.size)
    renum = np.full(node_tags.size, -1, dtype=np.int64)
    renum[index[used]] = np.arange(used.size)
    points = pts[index[used]]
    cells = renum[index[cells_g]]
    cells = _orient(points, cells)
    facets = {
        "cap": renum[index[_elements(gmsh, dim - 1, cap, ftype)]],
        "surface": renum[index[_elements(gmsh, dim - 1, rest, ftype)]],
    }
    mesh = Mesh(points, cells, cell_type, facets)
    mesh.check_cells()
    return mesh


#: the node permutation that swaps a simplex's vertices 0 and 1 (with its edges' midpoints), by nodes per cell
_SWAP01 = {3: [1, 0, 2], 4: [1, 0, 2, 3], 6: [1, 0, 2, 3, 5, 4], 10: [1, 0, 2, 3, 4, 6, 5, 8, 7, 9]}


def _orient(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Swap vertices 0 and 1 (and the midpoints of the edges they change) of every simplex whose vertices'
    Jacobian determinant is negative."""
    d = points.shape[1]
    X = points[cells[:, : d + 1]]
    J = X[:, 1:] - X[:, :1]
    neg = np.linalg.det(J) < 0
    cells = cells.copy()
    cells[neg] = cells[neg][:, _SWAP01[cells.shape[1]]]
    return cells
