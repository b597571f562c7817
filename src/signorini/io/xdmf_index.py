"""The XDMF index of a field time series as one grid: what ParaView, pyvista and VTK read as one mesh.

meshio's time series writes the mesh once as a grid of its own (``Name="mesh"``) beside the temporal collection,
whose time steps include its geometry and topology by XPointer.  VTK's XDMF reader (ParaView's, pyvista's) then
reads a multiblock of two meshes: the bare mesh and the time series.  :func:`one_grid` rewrites the index so that
each time step holds the mesh's geometry and topology itself (the same HDF5 datasets, referenced again: no data
is copied) and the standalone grid is gone; meshio's reader still reads it (it takes the first uniform grid of the
collection as the mesh).
"""

from __future__ import annotations

import copy
import os
import xml.etree.ElementTree as ET
from pathlib import Path

#: the XInclude element meshio uses for the shared mesh
XINCLUDE = "{http://www.w3.org/2003/XInclude}include"


def one_grid(path: str | Path) -> bool:
    """Rewrite the XDMF index ``path`` in place (atomically) with the mesh in every time step and no standalone
    mesh grid; returns False (file untouched) when it is not a meshio time series of that form."""
    path = Path(path)
    tree = ET.parse(path)
    root = tree.getroot()
    domains = list(root)
    if root.tag != "Xdmf" or len(domains) != 1:
        return False
    domain = domains[0]
    grids = list(domain)
    meshes = [g for g in grids if g.get("GridType") == "Uniform" and g.get("Name") == "mesh"]
    series = [g for g in grids if g.get("GridType") == "Collection"]
    if len(meshes) != 1 or len(series) != 1:
        return False
    parts = [e for e in meshes[0] if e.tag in ("Geometry", "Topology")]
    for step in series[0]:
        for include in [e for e in step if e.tag == XINCLUDE]:
            at = list(step).index(include)
            step.remove(include)
            for k, part in enumerate(parts):
                step.insert(at + k, copy.deepcopy(part))
        step.set("GridType", "Uniform")
        step.set("Name", "mesh")
    domain.remove(meshes[0])
    tmp = path.with_name(path.name + ".tmp")
    try:
        tree.write(tmp, encoding="utf-8", xml_declaration=False)
        os.replace(tmp, path)
    except BaseException:  # a full disk: the index meshio wrote stays, the half-written one goes
        tmp.unlink(missing_ok=True)
        raise
    return True
