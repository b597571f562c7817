"""Arithmetic expressions of x, y, z and t in case files, evaluated without ``eval``.

An expression is parsed with :mod:`ast` and only these nodes are accepted: numbers,
the names :data:`VARIABLES` and :data:`CONSTANTS`, the operators ``+ - * / ** %`` and
unary ``+ -``, and calls of the functions in :data:`FUNCTIONS` with positional
arguments.  Anything else (attributes, subscripts, lambdas, comprehensions, strings,
keywords, other names) is an error naming the key, so a case file cannot run code.
The tree is compiled into nested numpy closures; values are computed with numpy's
vectorized functions over all points at once.
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable

import numpy as np

from ..errors import InputError

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


def allowed_names() -> str:
    return ", ".join([*VARIABLES, *CONSTANTS, *(f"{f}()" for f in FUNCTIONS)])


def _compile(node: ast.AST, key: str, text: str, used: set[str]) -> Callable[[dict], np.ndarray]:
    def bad(what: str) -> InputError:
        return InputError(f"'{key}': {what} is not allowed in expression {text!r}; allowed: numbers, + - * / ** %, "
                          f"{allowed_names()}")  # fmt: skip

    if isinstance(node, ast.Expression):
        return _compile(node.body, key, text, used)
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            raise bad(f"the constant {node.value!r}")
        value = float(node.value)
        return lambda env: value
    if isinstance(node, ast.Name):
        if node.id in VARIABLES:
            used.add(node.id)
            name = node.id
            return lambda env: env[name]
        if node.id in CONSTANTS:
            value = CONSTANTS[node.id]
            return lambda env: value
        names = f"[{node.id!r}]"
        raise InputError(f"'{key}': unknown name(s) {names} in {text!r}; allowed: {allowed_names()}")
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        op, left, right = (
            _BINARY[type(node.op)],
            _compile(node.left, key, text, used),
            _compile(node.right, key, text, used),
        )
        return lambda env: op(left(env), right(env))
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        op, arg = _UNARY[type(node.op)], _compile(node.operand, key, text, used)
        return lambda env: op(arg(env))
    if isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS or node.keywords:
            raise bad("this call")
        fn = FUNCTIONS[node.func.id]
        args = [_compile(a, key, text, used) for a in node.args]
        if not args:
            raise bad("a call without arguments")
        return lambda env: fn(*(a(env) for a in args))
    raise bad(f"'{type(node).__name__}'")


class Expression:
    """A parsed expression; ``variables`` lists the names of x, y, z, t it uses."""

    def __init__(self, key: str, text: str):
        self.key, self.text = key, text
        if len(text) > 2000:
            raise InputError(f"'{key}': expression longer than 2000 characters")
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except SyntaxError as exc:
            raise InputError(f"'{key}': invalid expression {text!r}: {exc.msg}") from None
        used: set[str] = set()
        self._f = _compile(tree, key, text, used)
        self.variables = used

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


def vector_field(key: str, items: list, dim: int, allow_space: bool = True):
    """A vector of numbers and/or expressions -> constant list, f(x), or f(x, t).

    With ``allow_space=False`` (positions of an obstacle) only t may appear and the
    result is a list of numbers or a function of t returning a vector.
    """
    if not isinstance(items, list) or len(items) != dim:
        raise InputError(f"'{key}' must be a list of {dim} numbers or expressions, got {items!r}")
    comps: list[float | Expression] = []
    for i, c in enumerate(items):
        if isinstance(c, str):
            ex = Expression(f"{key}[{i}]", c)
            if not allow_space and ex.variables - {"t"}:
                raise InputError(f"'{key}[{i}]': only t may appear here, got {sorted(ex.variables)}")
            comps.append(ex)
        elif isinstance(c, bool) or not isinstance(c, (int, float)) or not math.isfinite(c):
            raise InputError(f"'{key}[{i}]' must be a finite number or an expression string, got {c!r}")
        else:
            comps.append(float(c))
    if all(isinstance(c, float) for c in comps):
        return comps
    timed = any(isinstance(c, Expression) and c.time_dependent for c in comps)

    def column(c, p, t):
        return c(p, t) if isinstance(c, Expression) else np.full(p.shape[0], c)

    def check(v: np.ndarray, t: float) -> np.ndarray:
        if not np.all(np.isfinite(v)):
            raise InputError(f"'{key}' is not finite at t = {t:g} (check the expression's domain)")
        return v

    if not allow_space:

        def position(t: float) -> np.ndarray:
            return check(np.array([column(c, np.zeros((1, dim)), t)[0] for c in comps]), t)

        return position

    if timed:

        def field_xt(p: np.ndarray, t: float) -> np.ndarray:
            return check(np.column_stack([column(c, p, t) for c in comps]), t)

        field_xt.time_dependent = True  # type: ignore[attr-defined]
        return field_xt

    def field_x(p: np.ndarray) -> np.ndarray:
        return check(np.column_stack([column(c, p, 0.0) for c in comps]), 0.0)

    field_x.time_dependent = False  # type: ignore[attr-defined]
    return field_x
