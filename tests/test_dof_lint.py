"""The dof map is the only place that turns (node, component) into a dof and back (issue 39, item 3; issue 53):
``d * node + c``, ``dof // d``, ``dof % d`` or ``x[k::d]`` computed by hand anywhere else fails this test (the
helpers are ``fem.dofmap``'s ``blocked``, ``block_of``, ``component_of``, ``component``, ``n_blocks`` and
``whole_blocks``), except the expressions below, which number other things (each with why)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "scripts"))
from house_metrics import hand_dofs  # noqa: E402

#: (file, expression): not a dof of the mesh (contact-row components and reaction rows go through
#: ``fem.dofmap`` too)
ALLOWED: dict[tuple[str, str], str] = {
    ("signorini/fem/node_order.py", "63 // d"): "the bits of each coordinate in a 63-bit Morton key",
}


def test_no_dof_is_numbered_by_hand():
    found = {(f, expr) for f, _, expr in hand_dofs()}
    assert found - set(ALLOWED) == set()


def test_the_lint_sees_every_form():
    """Each form of a dof by hand is found in a snippet (the scan itself can fail)."""
    import ast

    from house_metrics import _dof_by_hand

    for expr in ("d * node + c", "dof // d", "dof % dim", "x[k::d]", "x[0::components]"):
        assert any(_dof_by_hand(n) for n in ast.walk(ast.parse(expr))), expr
    for expr in ("a * b + c", "n // 2", "x[::2]"):
        assert not any(_dof_by_hand(n) for n in ast.walk(ast.parse(expr))), expr
