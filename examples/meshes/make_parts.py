"""Regenerate the small gmsh parts used by the examples and the tests (needs ``pip install ".[mesh]"``).

* ``cylinder.msh``: a tetrahedral cylinder (radius 0.05 m, height 0.1 m), its whole skin
  in the physical surface ``skin`` (plus ``bottom`` for the lower disc only);
* ``bracket.msh``: a tetrahedral block 0.2 x 0.1 x 0.05 m with two through holes, whole
  skin ``skin``;
* ``plate_hole.msh``: a triangular plate 0.2 x 0.1 m with a hole, whole boundary ``skin``;
* ``ball_on_plate.msh``: two tetrahedral bodies (``examples/ball_on_plate.toml``): a ball of
  radius 1 cm (region ``ball``, skin ``ball_skin``) 0.05 mm above the centre of a plate
  8 x 8 x 0.5 cm (region ``plate``, top face ``plate_top`` at z = 0, the disc of radius
  1.5 cm at its centre ``plate_centre``, lateral faces ``plate_sides``), both refined
  towards the point where they meet;
* ``block_on_block.msh``: two quadrilateral bodies in 2D (``examples/block_on_block.toml``):
  a block 0.1 x 0.05 m (region ``upper``, bottom ``upper_bottom``) lying on a block
  0.5 x 0.1 m (region ``lower``, top ``lower_top``, base ``lower_base``), their facing
  sides touching along y = 0 with nodes of their own (two bodies, not one).

Run from the repository root: ``python3 examples/meshes/make_parts.py`` (every part) or
``python3 examples/meshes/make_parts.py ball_on_plate block_on_block`` (only those).
``--cylinder-h H --out DIR`` writes only the cylinder, meshed at size H [m], into DIR
(h = 0.002 gives the 232k-dof part of docs/performance.md's node-order table).
"""

import argparse
from pathlib import Path

import gmsh

HERE = Path(__file__).parent


def _finish(name: str, dim: int, h: float, extra=None, where: Path = HERE) -> None:
    occ = gmsh.model.occ
    occ.synchronize()
    body = gmsh.model.getEntities(dim)
    skin = [t for _, t in gmsh.model.getBoundary(body, combined=True, oriented=False)]
    gmsh.model.addPhysicalGroup(dim, [t for _, t in body], name="body")
    gmsh.model.addPhysicalGroup(dim - 1, skin, name="skin")
    if extra:
        extra(skin)
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeMin", h / 2)
    gmsh.model.mesh.generate(dim)
    _write(name, where)


def _write(name: str, where: Path) -> None:
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write(str(where / name))


def _faces(dim: int, tag: int, test) -> list[int]:
    """The boundary faces of the entity (dim, tag) whose bounding box passes ``test``."""
    faces = gmsh.model.getBoundary([(dim, tag)], oriented=False)
    return [t for _, t in faces if test(gmsh.model.getBoundingBox(dim - 1, t))]


def cylinder(h: float = 0.015, where: Path = HERE) -> None:
    gmsh.model.add("cylinder")
    gmsh.model.occ.addCylinder(0, 0, 0, 0, 0, 0.1, 0.05)

    def bottom(skin):
        gmsh.model.occ.synchronize()
        lows = [t for t in skin if gmsh.model.getBoundingBox(2, t)[5] < 1e-6]
        gmsh.model.addPhysicalGroup(2, lows, name="bottom")

    _finish("cylinder.msh", 3, h, bottom, where)


def bracket(where: Path = HERE) -> None:
    occ = gmsh.model.occ
    gmsh.model.add("bracket")
    b = occ.addBox(0, 0, 0, 0.2, 0.1, 0.05)
    h1 = occ.addCylinder(0.05, 0.05, -0.01, 0, 0, 0.07, 0.02)
    h2 = occ.addCylinder(0.15, 0.05, -0.01, 0, 0, 0.07, 0.02)
    occ.cut([(3, b)], [(3, h1), (3, h2)])
    _finish("bracket.msh", 3, 0.012, where=where)


def plate_hole(where: Path = HERE) -> None:
    occ = gmsh.model.occ
    gmsh.model.add("plate_hole")
    r = occ.addRectangle(0, 0, 0, 0.2, 0.1)
    d = occ.addDisk(0.1, 0.05, 0, 0.025, 0.025)
    occ.cut([(2, r)], [(2, d)])
    _finish("plate_hole.msh", 2, 0.01, where=where)


def ball_on_plate(where: Path = HERE) -> None:
    """A ball (R = 1 cm) 0.05 mm above a plate 8 x 8 x 0.5 cm, tetrahedra sized
    0.3 mm at the point where they meet, growing by 0.25 per unit distance up to 2 mm in
    the ball and 5 mm in the plate (2,032 nodes)."""
    R, gap, side, thick = 0.01, 5e-5, 0.08, 0.005
    occ = gmsh.model.occ
    gmsh.model.add("ball_on_plate")
    plate = occ.addBox(-side / 2, -side / 2, -thick, side, side, thick)
    centre = occ.addDisk(0.0, 0.0, 0.0, 0.015, 0.015)
    occ.fragment([(3, plate)], [(2, centre)])  # the top face split: a disc at its centre and the rest
    ball = occ.addSphere(0.0, 0.0, R + gap, R)
    occ.synchronize()  # two volumes that do not touch: two bodies, each with its own nodes
    gmsh.model.addPhysicalGroup(3, [ball], name="ball")
    gmsh.model.addPhysicalGroup(3, [plate], name="plate")
    gmsh.model.addPhysicalGroup(
        2, [t for _, t in gmsh.model.getBoundary([(3, ball)], oriented=False)], name="ball_skin"
    )
    gmsh.model.addPhysicalGroup(2, _faces(3, plate, lambda b: b[2] > -thick / 2), name="plate_top")
    gmsh.model.addPhysicalGroup(2, [centre], name="plate_centre")
    sides = _faces(3, plate, lambda b: b[5] - b[2] > thick / 2)  # the four lateral faces span the thickness
    gmsh.model.addPhysicalGroup(2, sides, name="plate_sides")
    f = gmsh.model.mesh.field
    r = f"Sqrt(x*x + y*y + (z - {gap / 2})^2)"  # distance to the point between the two bodies
    fields = []
    for volume, h_far in ((ball, 0.002), (plate, 0.005)):
        graded = f.add("MathEval")
        f.setString(graded, "F", f"Min(0.0003 + 0.25 * {r}, {h_far})")
        only = f.add("Restrict")
        f.setNumber(only, "InField", graded)
        f.setNumbers(only, "VolumesList", [volume])
        f.setNumbers(only, "SurfacesList", [t for _, t in gmsh.model.getBoundary([(3, volume)], oriented=False)])
        fields.append(only)
    size = f.add("Min")
    f.setNumbers(size, "FieldsList", fields)
    f.setAsBackgroundMesh(size)
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.0)  # the field alone sets the size (the other parts set these)
    gmsh.option.setNumber("Mesh.MeshSizeMax", 1e22)
    defaults = {k: gmsh.option.getNumber(f"Mesh.{k}") for k in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints")}
    for key in defaults:
        gmsh.option.setNumber(f"Mesh.{key}", 0)
    gmsh.model.mesh.generate(3)
    _write("ball_on_plate.msh", where)
    for key, value in defaults.items():  # back to gmsh's defaults, for the parts made after this one
        gmsh.option.setNumber(f"Mesh.{key}", value)


def block_on_block(where: Path = HERE) -> None:
    """Two structured quadrilateral blocks: the upper one 0.1 x 0.05 m (20 x 10 cells of 5 mm),
    the lower one 0.5 x 0.1 m (50 x 10 cells of 1 cm), the upper one's bottom on the
    lower one's top around x = 0.15 (two surfaces that only touch: separate nodes)."""
    occ = gmsh.model.occ
    gmsh.model.add("block_on_block")
    blocks = {"upper": (0.1, 0.0, 0.1, 0.05, 20, 10), "lower": (0.0, -0.1, 0.5, 0.1, 50, 10)}
    made = {}
    for name, (x0, y0, lx, ly, nx, ny) in blocks.items():
        s = occ.addRectangle(x0, y0, 0.0, lx, ly)
        occ.synchronize()
        for _, c in gmsh.model.getBoundary([(2, s)], oriented=False):
            b = gmsh.model.getBoundingBox(1, c)
            horizontal = abs(b[4] - b[1]) < 1e-6
            gmsh.model.mesh.setTransfiniteCurve(c, (nx if horizontal else ny) + 1)
        gmsh.model.mesh.setTransfiniteSurface(s)
        gmsh.model.mesh.setRecombine(2, s)
        made[name] = s
        gmsh.model.addPhysicalGroup(2, [s], name=name)
    gmsh.model.addPhysicalGroup(1, _faces(2, made["upper"], lambda b: abs(b[1]) < 1e-6 and abs(b[4]) < 1e-6),
                                name="upper_bottom")  # fmt: skip
    gmsh.model.addPhysicalGroup(1, _faces(2, made["lower"], lambda b: abs(b[1]) < 1e-6 and abs(b[4]) < 1e-6),
                                name="lower_top")  # fmt: skip
    gmsh.model.addPhysicalGroup(1, _faces(2, made["lower"], lambda b: b[4] < -0.1 + 1e-6), name="lower_base")
    gmsh.model.mesh.generate(2)
    _write("block_on_block.msh", where)


def ball_on_hex_plate(where: Path = HERE) -> None:
    """Two cell types in one file: a tetrahedral ball (R = 1 cm, 1.5 mm cells, 0.05 mm above
    the plate) on a structured hexahedral plate 6 x 6 x 0.6 cm (30 x 30 x 3 cells of 2 mm)."""
    R, gap, side, thick = 0.01, 5e-5, 0.06, 0.006
    occ = gmsh.model.occ
    gmsh.model.add("ball_on_hex_plate")
    plate = occ.addBox(-side / 2, -side / 2, -thick, side, side, thick)
    ball = occ.addSphere(0.0, 0.0, R + gap, R)
    occ.synchronize()
    for _, c in gmsh.model.getEntities(1):
        b = gmsh.model.getBoundingBox(1, c)
        if b[5] < R / 2:  # the plate's edges (the ball's are above z = R / 2)
            vertical = b[5] - b[2] > thick / 2
            gmsh.model.mesh.setTransfiniteCurve(c, 4 if vertical else 31)
    for _, s in gmsh.model.getBoundary([(3, plate)], oriented=False):
        gmsh.model.mesh.setTransfiniteSurface(s)
        gmsh.model.mesh.setRecombine(2, s)
    gmsh.model.mesh.setTransfiniteVolume(plate)
    gmsh.model.mesh.setRecombine(3, plate)
    gmsh.model.addPhysicalGroup(3, [ball], name="ball")
    gmsh.model.addPhysicalGroup(3, [plate], name="plate")
    gmsh.model.addPhysicalGroup(2, [t for _, t in gmsh.model.getBoundary([(3, ball)], oriented=False)],
                                name="ball_skin")  # fmt: skip
    gmsh.model.addPhysicalGroup(2, _faces(3, plate, lambda b: b[2] > -thick / 2), name="plate_top")
    gmsh.model.addPhysicalGroup(2, _faces(3, plate, lambda b: b[5] - b[2] > thick / 2), name="plate_sides")
    gmsh.model.mesh.setSize(gmsh.model.getBoundary([(3, ball)], oriented=False, recursive=True), 0.0015)
    gmsh.model.mesh.generate(3)
    _write("ball_on_hex_plate.msh", where)


PARTS = {"cylinder": cylinder, "bracket": bracket, "plate_hole": plate_hole, "ball_on_plate": ball_on_plate,
         "block_on_block": block_on_block, "ball_on_hex_plate": ball_on_hex_plate}  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("parts", nargs="*", metavar="PART", help=f"parts to write (default all: {', '.join(PARTS)})")
    ap.add_argument("--cylinder-h", type=float, default=None, help="only the cylinder, at this mesh size [m]")
    ap.add_argument("--out", type=Path, default=HERE, help="directory of the .msh files")
    a = ap.parse_args(argv)
    unknown = [p for p in a.parts if p not in PARTS]
    if unknown:
        ap.error(f"unknown part(s) {', '.join(unknown)}; choose from {', '.join(PARTS)}")
    if a.cylinder_h is not None and not 1e-4 <= a.cylinder_h <= 0.05:
        ap.error(f"--cylinder-h must be between 1e-4 and 0.05 m, got {a.cylinder_h}")
    a.out.mkdir(parents=True, exist_ok=True)
    gmsh.initialize(["-noenv"], readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.option.setNumber("Mesh.RandomSeed", 1)
    try:
        if a.cylinder_h is not None:
            cylinder(a.cylinder_h, a.out)
            return
        for name in a.parts or PARTS:
            PARTS[name](where=a.out)
    finally:
        gmsh.finalize()


if __name__ == "__main__":
    main()
