"""Arithmetic expressions of a case (an initial displacement field u(x, y, z)), read and
evaluated without Python's ``eval``.

The text is parsed by :mod:`ast` and only a small grammar is accepted: numbers, the
coordinates and named constants, ``+ - * / **``, unary ``+ -``, parentheses and calls of the
functions in :data:`FUNCTIONS` with positional arguments. Anything else (attributes,
subscripts, comparisons, keywords, lambdas, strings, ...) is refused when the case is read,
naming what was found. Evaluation walks the same tree on numpy arrays, so nothing in the
text can reach Python: the worst an expression can do is overflow, which the caller checks
(the result must be finite).
"""

from __future__ import annotations

import ast
from collections.abc import Mapping

import numpy as np

# The longest expression text and the deepest nesting accepted (a formula for a field is
# a line, not a program; the depth bound keeps the tree walk far from Python's recursion
# limit).
MAX_LENGTH = 1000
MAX_DEPTH = 50

FUNCTIONS = {
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "arcsin": np.arcsin, "arccos": np.arccos,
    "arctan": np.arctan, "arctan2": np.arctan2, "sinh": np.sinh, "cosh": np.cosh,
    "tanh": np.tanh, "exp": np.exp, "log": np.log, "sqrt": np.sqrt, "abs": np.abs,
    "minimum": np.minimum, "maximum": np.maximum, "hypot": np.hypot,
}
# arguments each function takes
_ARITY = {name: 2 if name in ("arctan2", "minimum", "maximum", "hypot") else 1
          for name in FUNCTIONS}
CONSTANTS = {"pi": float(np.pi), "e": float(np.e)}
_BINARY = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply,
           ast.Div: np.true_divide, ast.Pow: np.power}
_UNARY = {ast.UAdd: np.positive, ast.USub: np.negative}


def parse(text: str, names: set[str]) -> ast.Expression:
    """The tree of ``text``, an expression of ``names`` (and ``pi``, ``e``); a ValueError
    says what in it is refused."""
    if len(text) > MAX_LENGTH:
        raise ValueError(f"an expression is at most {MAX_LENGTH} characters, got {len(text)}")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except (SyntaxError, RecursionError, MemoryError) as exc:
        raise ValueError(f"not an expression: {getattr(exc, 'msg', type(exc).__name__)} "
                         f"in {text!r}") from None
    _check(tree.body, names | set(CONSTANTS), 0)
    return tree


def _check(node: ast.AST, names: set[str], depth: int) -> None:
    if depth > MAX_DEPTH:
        raise ValueError(f"an expression nests at most {MAX_DEPTH} levels")
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, int | float):
            raise ValueError(f"{node.value!r} is not a number")
        if isinstance(node.value, int) and abs(node.value) > 1e300:
            raise ValueError("a number in an expression must be a finite float, "
                             f"got an integer of {len(str(node.value))} digits")
    elif isinstance(node, ast.Name):
        if node.id not in names:
            raise ValueError(f"unknown name '{node.id}' (known: "
                             f"{', '.join(sorted(names))}, and the functions "
                             f"{', '.join(FUNCTIONS)})")
    elif isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        _check(node.left, names, depth + 1)
        _check(node.right, names, depth + 1)
    elif isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        _check(node.operand, names, depth + 1)
    elif isinstance(node, ast.Call):
        func = node.func.id if isinstance(node.func, ast.Name) else None
        if func not in FUNCTIONS:
            raise ValueError(f"'{ast.unparse(node.func)}' is not a function of expressions "
                             f"(known: {', '.join(FUNCTIONS)})")
        if node.keywords or len(node.args) != _ARITY[func] or any(
                isinstance(a, ast.Starred) for a in node.args):
            raise ValueError(f"{func} takes {_ARITY[func]} plain argument(s)")
        for arg in node.args:
            _check(arg, names, depth + 1)
    else:
        raise ValueError(f"'{ast.unparse(node)}' is not allowed in an expression (numbers, "
                         "names, + - * / **, parentheses and functions only)")


def evaluate(tree: ast.Expression, values: Mapping[str, np.ndarray | float]) -> np.ndarray:
    """The value of a tree of :func:`parse` for the ``values`` of its names (arrays
    broadcast against each other); overflow and invalid operations give inf / nan, which
    the caller checks."""
    with np.errstate(all="ignore"):
        return np.asarray(_value(tree.body, {**CONSTANTS, **values}), dtype=float)


def _value(node: ast.AST, values: Mapping):
    if isinstance(node, ast.Constant):
        return float(node.value)
    if isinstance(node, ast.Name):
        return values[node.id]
    if isinstance(node, ast.BinOp):
        return _BINARY[type(node.op)](np.asarray(_value(node.left, values), dtype=float),
                                      _value(node.right, values))
    if isinstance(node, ast.UnaryOp):
        return _UNARY[type(node.op)](_value(node.operand, values))
    return FUNCTIONS[node.func.id](*(_value(a, values) for a in node.args))
