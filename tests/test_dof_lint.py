"""The dof map is the only place that turns (node, component) into a dof (issue 39, item 3):
``d * node + c`` computed by hand anywhere else fails this test, except the expressions below,
which number other things (each with why)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "scripts"))
from house_metrics import hand_dofs  # noqa: E402

#: (file, expression): not a dof of the mesh
ALLOWED = {
    ("signorini/contact/solver.py", "near[:, None] * d + comp"): "rows of the frame matrix: d per contact node",
    ("signorini/contact/solver.py", "P[:, None] * d + comp"): "rows of the frame matrix: d per contact node",
    ("signorini/dynamics/reactions.py", "k * d + c"): "a row of the (tag, component) sums",
    ("signorini/fem/assembly.py", "d * nn + 1"): "the length of a CSR row pointer",
    ("signorini/fem/assembly.py", "nn * dim + 1"): "the length of a CSR row pointer",
    ("signorini/fem/node_order.py", "b * d + k"): "a bit position of the Morton code",
}


def test_no_dof_is_numbered_by_hand():
    found = {(f, expr) for f, _, expr in hand_dofs()}
    assert found - set(ALLOWED) == set()
