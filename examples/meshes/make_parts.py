"""Regenerate the small gmsh parts used by the examples and the tests (needs ``pip install ".[mesh]"``).

* ``cylinder.msh``: a tetrahedral cylinder (radius 0.05 m, height 0.1 m), its whole skin
  in the physical surface ``skin`` (plus ``bottom`` for the lower disc only);
* ``bracket.msh``: a tetrahedral block 0.2 x 0.1 x 0.05 m with two through holes, whole
  skin ``skin``;
* ``plate_hole.msh``: a triangular plate 0.2 x 0.1 m with a hole, whole boundary ``skin``.

Run from the repository root: ``python3 examples/meshes/make_parts.py``.
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
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write(str(where / name))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cylinder-h", type=float, default=None, help="only the cylinder, at this mesh size [m]")
    ap.add_argument("--out", type=Path, default=HERE, help="directory of the .msh files")
    a = ap.parse_args(argv)
    if a.cylinder_h is not None and not 1e-4 <= a.cylinder_h <= 0.05:
        ap.error(f"--cylinder-h must be between 1e-4 and 0.05 m, got {a.cylinder_h}")
    a.out.mkdir(parents=True, exist_ok=True)
    gmsh.initialize(["-noenv"], readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.option.setNumber("Mesh.RandomSeed", 1)
    occ = gmsh.model.occ

    gmsh.model.add("cylinder")
    occ.addCylinder(0, 0, 0, 0, 0, 0.1, 0.05)

    def bottom(skin):
        occ.synchronize()
        lows = [t for t in skin if gmsh.model.getBoundingBox(2, t)[5] < 1e-6]
        gmsh.model.addPhysicalGroup(2, lows, name="bottom")

    if a.cylinder_h is not None:
        _finish("cylinder.msh", 3, a.cylinder_h, bottom, a.out)
        gmsh.finalize()
        return
    _finish("cylinder.msh", 3, 0.015, bottom)

    gmsh.model.add("bracket")
    b = occ.addBox(0, 0, 0, 0.2, 0.1, 0.05)
    h1 = occ.addCylinder(0.05, 0.05, -0.01, 0, 0, 0.07, 0.02)
    h2 = occ.addCylinder(0.15, 0.05, -0.01, 0, 0, 0.07, 0.02)
    occ.cut([(3, b)], [(3, h1), (3, h2)])
    _finish("bracket.msh", 3, 0.012)

    gmsh.model.add("plate_hole")
    r = occ.addRectangle(0, 0, 0, 0.2, 0.1)
    d = occ.addDisk(0.1, 0.05, 0, 0.025, 0.025)
    occ.cut([(2, r)], [(2, d)])
    _finish("plate_hole.msh", 2, 0.01)
    gmsh.finalize()


if __name__ == "__main__":
    main()
