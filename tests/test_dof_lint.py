"""The dof map is the only place that turns (node, component) into a dof (issue 39, item 3):
``d * node + c`` computed by hand anywhere else fails this test, except the expressions below,
which number other things (each with why; none today)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "scripts"))
from house_metrics import hand_dofs  # noqa: E402

#: (file, expression): not a dof of the mesh (none left: contact-row components and reaction rows
#: go through ``fem.dofmap.blocked`` too)
ALLOWED: dict[tuple[str, str], str] = {}


def test_no_dof_is_numbered_by_hand():
    found = {(f, expr) for f, _, expr in hand_dofs()}
    assert found - set(ALLOWED) == set()
