"""Arithmetic expressions of x, y, z and t in case files, evaluated without ``eval``.

An expression is parsed with :mod:`ast` and only these nodes are accepted: numbers,
the names :data:`VARIABLES` and :data:`CONSTANTS`, the operators ``+ - * / ** %`` and
unary ``+ -``, calls of the functions in :data:`FUNCTIONS` with positional
arguments; in a *condition* (``Expression(..., conditions=True)``: ``[contact] where``)
also the comparisons ``< <= > >=`` (chained as in ``0 < x < 1``) and ``and``, ``or``,
``not`` (true is 1.0, false 0.0).  Anything else
(attributes, subscripts, lambdas, comprehensions, strings, keywords, other names) is an
error naming the key, so a case file cannot run code.

Bounds, checked before anything is evaluated: at most :data:`MAX_LENGTH` characters,
:data:`MAX_NODES` tree nodes and :data:`MAX_DEPTH` levels of nesting, and a constant
exponent of ``**`` at most :data:`MAX_EXPONENT` in absolute value.  Every number is a
float64 and every operation a numpy one (an overflow gives inf, never a Python
big-integer computation), so the cost of an evaluation is at most MAX_NODES vectorized
operations over the points: the size bound is the time bound.

The tree is compiled into nested numpy closures; values are computed with numpy's
vectorized functions over all points at once.  A value that is not finite at some
point is an error naming the key, the expression and that point
(:func:`check_finite`).
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable

import numpy as np

from ..errors import InputError

MAX_LENGTH = 2000
MAX_NODES = 400
MAX_DEPTH = 100
MAX_EXPONENT = 64.0

VARIABLES = ("x", "y", "z", "t")
CONSTANTS = {"pi": math.pi, "e": math.e}
FUNCTIONS: dict[str, Callable] = {
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    "exp": np.exp,
    "log": np.log,
    "sqrt": np.sqrt,
    "abs": np.abs,
    "tanh": np.tanh,
    "cosh": np.cosh,
    "sinh": np.sinh,
    "min": np.minimum,
    "max": np.maximum,
}
_BINARY = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
    ast.Mod: operator.mod,
}
_UNARY = {ast.UAdd: operator.pos, ast.USub: operator.neg}
# conditions (``[contact] where``): comparisons and and/or/not give 1.0 (true) or 0.0 (false)
_COMPARE = {ast.Lt: np.less, ast.LtE: np.less_equal, ast.Gt: np.greater, ast.GtE: np.greater_equal}
_BOOL = {ast.And: np.logical_and, ast.Or: np.logical_or}


def allowed_names() -> str:
    return ", ".join([*VARIABLES, *CONSTANTS, *(f"{f}()" for f in FUNCTIONS)])


_MARKERS = (ast.expr_context, ast.operator, ast.unaryop, ast.cmpop, ast.boolop)  # not terms


def _check_size(tree: ast.AST, key: str, text: str) -> None:
    """Reject trees with more than MAX_NODES nodes or deeper than MAX_DEPTH (iteratively)."""
    count, deepest, stack = 0, 0, [(tree, 0)]
    while stack:  # the tree is small: MAX_LENGTH characters bound its size
        node, depth = stack.pop()
        count, deepest = count + 1, max(deepest, depth)
        stack.extend((c, depth + 1) for c in ast.iter_child_nodes(node) if not isinstance(c, _MARKERS))
    if count > MAX_NODES:
        raise InputError(f"'{key}': expression {text[:60]!r}... has more than {MAX_NODES} terms")
    if deepest > MAX_DEPTH:
        raise InputError(f"'{key}': expression {text[:60]!r}... nests deeper than {MAX_DEPTH} levels")


def _constant_value(node: ast.AST) -> float | None:
    """The value of a (possibly signed) numeric literal, else None."""
    sign = 1.0
    while isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        sign = -sign if isinstance(node.op, ast.USub) else sign
        node = node.operand
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
        return sign * float(node.value)
    return None


def _compile(
    node: ast.AST, key: str, text: str, used: set[str], conditions: bool = False
) -> Callable[[dict], np.ndarray]:
    def bad(what: str) -> InputError:
        return InputError(
            f"'{key}': {what} is not allowed in expression {text!r}; allowed: numbers, + - * / ** %, {allowed_names()}"
        )

    if isinstance(node, ast.Expression):
        return _compile(node.body, key, text, used, conditions)
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            raise bad(f"the constant {node.value!r}")
        try:
            value = np.float64(float(node.value))
        except OverflowError:
            value = np.float64(np.inf)
        if not np.isfinite(value):
            raise InputError(f"'{key}': the number {node.value!r} in {text!r} is not finite")
        return lambda env: value
    if isinstance(node, ast.Name):
        if node.id in VARIABLES:
            used.add(node.id)
            name = node.id
            return lambda env: env[name]
        if node.id in CONSTANTS:
            value = np.float64(CONSTANTS[node.id])
            return lambda env: value
        names = f"[{node.id!r}]"
        raise InputError(f"'{key}': unknown name(s) {names} in {text!r}; allowed: {allowed_names()}")
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        if isinstance(node.op, ast.Pow):
            exponent = _constant_value(node.right)
            if exponent is None or abs(exponent) > MAX_EXPONENT:
                raise bad(
                    f"the power '{ast.unparse(node)}' (the exponent must be a number of size <= "
                    f"{MAX_EXPONENT:g}; use exp() and log() for other powers)"
                )
        op, left, right = (
            _BINARY[type(node.op)],
            _compile(node.left, key, text, used, conditions),
            _compile(node.right, key, text, used, conditions),
        )
        return lambda env: op(left(env), right(env))
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        op, arg = _UNARY[type(node.op)], _compile(node.operand, key, text, used, conditions)
        return lambda env: op(arg(env))
    if conditions and isinstance(node, ast.Compare) and all(type(o) in _COMPARE for o in node.ops):
        terms = [_compile(t, key, text, used, conditions) for t in (node.left, *node.comparators)]
        ops = [_COMPARE[type(o)] for o in node.ops]

        def compare(env):
            vals = [t(env) for t in terms]
            for v in vals:
                if not np.all(np.isfinite(v)):
                    raise InputError(f"'{key}': {text!r} compares a value that is not finite (check its domain)")
            out = np.ones(np.broadcast(*vals).shape, dtype=bool)
            for op, a, b in zip(ops, vals[:-1], vals[1:], strict=True):
                out &= op(a, b)
            return out.astype(float)

        return compare
    if conditions and isinstance(node, ast.BoolOp) and type(node.op) in _BOOL:
        fn, parts = _BOOL[type(node.op)], [_compile(v, key, text, used, conditions) for v in node.values]

        def combine(env):
            out = parts[0](env) != 0
            for p in parts[1:]:
                out = fn(out, p(env) != 0)
            return np.asarray(out, dtype=float)

        return combine
    if conditions and isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
        arg = _compile(node.operand, key, text, used, conditions)
        return lambda env: np.asarray(arg(env) == 0, dtype=float)
    if isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS or node.keywords:
            raise bad("this call")
        fn = FUNCTIONS[node.func.id]
        arity = 2 if node.func.id in ("min", "max") else 1
        if len(node.args) != arity or any(isinstance(a, ast.Starred) for a in node.args):
            raise InputError(
                f"'{key}': {node.func.id}() takes {arity} argument{'s' if arity > 1 else ''}, "
                f"got {len(node.args)} in {text!r}"
            )
        args = [_compile(a, key, text, used, conditions) for a in node.args]
        return lambda env: fn(*(a(env) for a in args))
    raise bad(f"'{type(node).__name__}'")


def _is_condition(node: ast.AST) -> bool:
    """A comparison, ``not`` of a condition, or and/or of conditions (a truth value, not a number)."""
    if isinstance(node, ast.Compare):
        return True
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
        return _is_condition(node.operand)
    if isinstance(node, ast.BoolOp):
        return all(_is_condition(v) for v in node.values)
    return False


class Expression:
    """A parsed expression; ``variables`` lists the names of x, y, z, t it uses."""

    def __init__(self, key: str, text: str, conditions: bool = False):
        self.key, self.text = key, text
        if len(text) > MAX_LENGTH:
            raise InputError(f"'{key}': expression longer than {MAX_LENGTH} characters")
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except (SyntaxError, ValueError, RecursionError, MemoryError) as exc:
            raise InputError(f"'{key}': invalid expression {text!r}: {getattr(exc, 'msg', exc)}") from None
        _check_size(tree, key, text)
        used: set[str] = set()
        self._f = _compile(tree, key, text, used, conditions)
        self.variables = used
        #: whether the expression is a condition (a comparison, or and/or/not of them)
        self.is_condition = _is_condition(tree.body)

    @property
    def time_dependent(self) -> bool:
        return "t" in self.variables

    def __call__(self, points: np.ndarray | None = None, t: float = 0.0) -> np.ndarray:
        """Values at points (n, d) (missing coordinates are 0) and time t, shape (n,)."""
        n = 1 if points is None else points.shape[0]
        env = {"t": float(t)}
        for i, name in enumerate("xyz"):
            env[name] = points[:, i] if points is not None and i < points.shape[1] else np.zeros(n)
        with np.errstate(all="ignore"):
            v = np.broadcast_to(np.asarray(self._f(env), dtype=float), (n,))
        return v


def check_finite(key: str, text: str, values: np.ndarray, points: np.ndarray | None, t: float) -> np.ndarray:
    """``values`` (n,) if all finite; else an error naming the key, the expression and one point:
    the first bad point in lexicographic order of its coordinates (x, then y, then z), which
    does not depend on the order of the nodes (a renumbered mesh names the same point)."""
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size == 0:
        return values
    i = int(bad[0])
    where = ""
    if points is not None and len(points):
        pts = np.asarray(points)[bad].reshape(bad.size, -1)
        i = int(bad[np.lexsort(pts.T[::-1])[0]])
        where = " at (" + ", ".join(f"{c}={v:.6g}" for c, v in zip("xyz", points[i], strict=False)) + ")"
    raise InputError(
        f"'{key}': {text!r} is {float(values[i])}{where}, t = {t:g}: not finite "
        "(check the expression's domain and the size of its values)"
    )


def _finite_float(v: int | float) -> bool:
    """Whether ``v`` converts to a finite float (TOML integers may be arbitrarily large)."""
    try:
        return math.isfinite(float(v))
    except OverflowError:
        return False


def _short(v) -> str:
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def vector_field(key: str, items: list, dim: int, allow_space: bool = True):
    """A vector of numbers and/or expressions -> constant list, f(x), or f(x, t).

    With ``allow_space=False`` (positions of an obstacle) only t may appear and the
    result is a list of numbers or a function of t returning a vector.
    """
    if not isinstance(items, list) or len(items) != dim:
        raise InputError(f"'{key}' must be a list of {dim} numbers or expressions, got {_short(items)}")
    comps: list[float | Expression] = []
    for i, c in enumerate(items):
        if isinstance(c, str):
            ex = Expression(f"{key}[{i}]", c)
            if not allow_space and ex.variables - {"t"}:
                raise InputError(f"'{key}[{i}]': only t may appear here, got {sorted(ex.variables)}")
            comps.append(ex)
        elif isinstance(c, bool) or not isinstance(c, (int, float)) or not _finite_float(c):
            raise InputError(f"'{key}[{i}]' must be a finite number or an expression string, got {_short(c)}")
        else:
            comps.append(float(c))
    if all(isinstance(c, float) for c in comps):
        return comps
    timed = any(isinstance(c, Expression) and c.time_dependent for c in comps)

    def column(c, p, t):
        if isinstance(c, Expression):
            return check_finite(c.key, c.text, c(p, t), p if allow_space else None, t)
        return np.full(p.shape[0], c)

    if not allow_space:

        def position(t: float) -> np.ndarray:
            return np.array([column(c, np.zeros((1, dim)), t)[0] for c in comps])

        return position

    if timed:

        def field_xt(p: np.ndarray, t: float) -> np.ndarray:
            return np.column_stack([column(c, p, t) for c in comps])

        field_xt.time_dependent = True  # type: ignore[attr-defined]
        return field_xt

    def field_x(p: np.ndarray) -> np.ndarray:
        return np.column_stack([column(c, p, 0.0) for c in comps])

    field_x.time_dependent = False  # type: ignore[attr-defined]
    return field_x
