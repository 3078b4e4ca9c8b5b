"""A small, safe arithmetic language for model-file coefficients: ``"7.24e6 / V"``.

Grammar (Python's precedence; ``**`` is right-associative and binds tighter than unary minus,
so ``-2**2 == -4``)::

    expr   := term (("+" | "-") term)*
    term   := unary (("*" | "/") unary)*
    unary  := ("+" | "-") unary | power
    power  := atom ("**" unary)?
    atom   := NUMBER | NAME | NAME "(" expr ("," expr)* ")" | "(" expr ")"

Names are parameters, coefficients or the constant ``pi``; the functions are listed in
``FUNCTIONS``. Nothing is ever handed to Python's ``eval``: the text is tokenized and parsed
here into a tree of tuples, which :func:`evaluate` walks.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

FUNCTIONS = {
    "sqrt": (math.sqrt, 1),
    "exp": (math.exp, 1),
    "log": (math.log, 1),
    "log10": (math.log10, 1),
    "sin": (math.sin, 1),
    "cos": (math.cos, 1),
    "tan": (math.tan, 1),
    "atan": (math.atan, 1),
    "sinh": (math.sinh, 1),
    "cosh": (math.cosh, 1),
    "tanh": (math.tanh, 1),
    "abs": (abs, 1),
    "min": (min, 2),
    "max": (max, 2),
}
# the same functions on arrays (:func:`evaluate_on_grid`); min and max elementwise
_ARRAY_FUNCTIONS = {
    "sqrt": np.sqrt,
    "exp": np.exp,
    "log": np.log,
    "log10": np.log10,
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    "atan": np.arctan,
    "sinh": np.sinh,
    "cosh": np.cosh,
    "tanh": np.tanh,
    "abs": np.abs,
    "min": np.minimum,
    "max": np.maximum,
}
CONSTANTS = {"pi": math.pi}
RESERVED = frozenset(FUNCTIONS) | frozenset(CONSTANTS)

MAX_NESTING = 100
"""Most levels of parentheses, signs, powers and calls inside one another: the parser is
recursive, and a deeper text (a probe's 1,200 parentheses) would end in Python's RecursionError
instead of a message."""

MAX_DEPTH = 300
"""Most operations in a chain (``a + b + c ...`` is one level per term): evaluation walks the
tree recursively. A coefficient longer than this is better split into named parameters."""

_SHOWN = 60  # characters of an expression quoted in a message: the rest is "..."

_TOKEN = re.compile(
    r"\s*(?:(?P<number>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)"
    r"|(?P<name>[A-Za-z_][A-Za-z_0-9]*)"
    r"|(?P<op>\*\*|[-+*/(),]))"
)


class ExpressionError(ValueError):
    """The text is not a valid expression, or cannot be evaluated (message says why)."""


def _quote(text: str) -> str:
    """``text`` quoted for a message, cut to its first ``_SHOWN`` characters (a hostile file's
    expression can be megabytes long)."""
    if len(text) <= _SHOWN:
        return repr(text)
    return f"{text[:_SHOWN]!r}... ({len(text):,} characters)"


@dataclass(frozen=True)
class Expression:
    """A parsed expression.

    Attributes
    ----------
    text : str
        The source text.
    tree : tuple
        ``("num", value)``, ``("name", id)``, ``("neg", sub)``, ``("call", fn, args)`` or
        ``(op, left, right)`` with op one of ``+ - * / **``.
    """

    text: str
    tree: tuple

    @property
    def names(self) -> frozenset[str]:
        """Every variable name the expression reads (functions and ``pi`` excluded)."""
        found: set[str] = set()
        _collect(self.tree, found)
        return frozenset(found)

    def __call__(self, env: dict[str, float]) -> float:
        return evaluate(self, env)


@dataclass(frozen=True)
class Item:
    """An expression together with where it came from in a model file (for error messages).

    Attributes
    ----------
    key : str
        Dotted key, e.g. ``"nonlinear.flange.abs[1].offset"``.
    expression : Expression
    """

    key: str
    expression: Expression


def _collect(node: tuple, found: set[str]) -> None:
    kind = node[0]
    if kind == "name":
        if node[1] not in CONSTANTS:
            found.add(node[1])
    elif kind == "neg":
        _collect(node[1], found)
    elif kind == "call":
        for arg in node[2]:
            _collect(arg, found)
    elif kind != "num":
        _collect(node[1], found)
        _collect(node[2], found)


def _tokenize(text: str) -> list[tuple[str, str]]:
    tokens = []
    pos = 0
    stripped = text.rstrip()
    while pos < len(stripped):
        match = _TOKEN.match(stripped, pos)
        if match is None or match.end() == pos:
            bad = stripped[pos:].lstrip()[:1]
            hint = " (use ** for powers)" if bad == "^" else ""
            raise ExpressionError(f"unexpected character {bad!r} in {_quote(text)}{hint}")
        kind = match.lastgroup
        tokens.append((kind, match.group(kind)))
        pos = match.end()
    tokens.append(("end", ""))
    return tokens


class _Parser:
    def __init__(self, text: str):
        self.text = text
        self.tokens = _tokenize(text)
        self.pos = 0
        self.nesting = 0  # levels of (, signs, ** and calls open: see MAX_NESTING

    def enter(self) -> None:
        """One level deeper (a parenthesis, sign, power or call): refuse past MAX_NESTING."""
        self.nesting += 1
        if self.nesting > MAX_NESTING:
            raise ExpressionError(
                f"nested too deeply: more than {MAX_NESTING} levels of parentheses, signs, "
                f"powers or calls in {_quote(self.text)}"
            )

    def peek(self) -> tuple[str, str]:
        return self.tokens[self.pos]

    def take(self) -> tuple[str, str]:
        token = self.tokens[self.pos]
        self.pos += 1
        return token

    def expect(self, op: str) -> None:
        kind, value = self.take()
        if (kind, value) != ("op", op):
            found = value or "end of text"
            raise ExpressionError(
                f"expected {op!r} but found {_quote(found)} in {_quote(self.text)}"
            )

    def expr(self) -> tuple:
        node = self.term()
        while self.peek() in (("op", "+"), ("op", "-")):
            op = self.take()[1]
            node = (op, node, self.term())
        return node

    def term(self) -> tuple:
        node = self.unary()
        while self.peek() in (("op", "*"), ("op", "/")):
            op = self.take()[1]
            node = (op, node, self.unary())
        return node

    def unary(self) -> tuple:
        if self.peek() in (("op", "-"), ("op", "+")):
            sign = self.take()[1]
            self.enter()
            operand = self.unary()
            self.nesting -= 1
            return ("neg", operand) if sign == "-" else operand
        return self.power()

    def power(self) -> tuple:
        node = self.atom()
        if self.peek() == ("op", "**"):
            self.take()
            self.enter()
            node = ("**", node, self.unary())
            self.nesting -= 1
        return node

    def atom(self) -> tuple:
        kind, value = self.take()
        if kind == "number":
            return ("num", float(value))
        if kind == "name":
            if self.peek() == ("op", "("):
                return self.call(value)
            if value in FUNCTIONS:
                raise ExpressionError(
                    f"function {_quote(value)} needs arguments in {_quote(self.text)}"
                )
            return ("name", value)
        if (kind, value) == ("op", "("):
            self.enter()
            node = self.expr()
            self.expect(")")
            self.nesting -= 1
            return node
        found = value or "end of text"
        raise ExpressionError(
            f"expected a number, name or '(' but found {_quote(found)} in {_quote(self.text)}"
        )

    def call(self, name: str) -> tuple:
        if name not in FUNCTIONS:
            known = ", ".join(sorted(FUNCTIONS))
            raise ExpressionError(
                f"unknown function {_quote(name)} in {_quote(self.text)} (known: {known})"
            )
        self.expect("(")
        self.enter()
        args = [self.expr()]
        while self.peek() == ("op", ","):
            self.take()
            args.append(self.expr())
        self.expect(")")
        self.nesting -= 1
        arity = FUNCTIONS[name][1]
        if len(args) != arity:
            raise ExpressionError(
                f"function {name!r} takes {arity} argument(s), got {len(args)} in "
                f"{_quote(self.text)}"
            )
        return ("call", name, tuple(args))


def parse(source: str | int | float) -> Expression:
    """Parse a number or expression text.

    Parameters
    ----------
    source : str or float
        ``"7.24e6 / V"``, ``"-k/2"``, or a plain number.

    Raises
    ------
    ExpressionError
        On a syntax error, an unknown function or a wrong argument count.
    """
    if isinstance(source, bool):
        raise ExpressionError(f"expected a number or an expression string, got {source!r}")
    if isinstance(source, int | float):
        try:
            return Expression(repr(source), ("num", float(source)))
        except OverflowError:  # an integer of hundreds of digits
            raise ExpressionError(
                f"number too large: an integer of {len(str(abs(source))):,} digits"
            ) from None
    if not isinstance(source, str):
        raise ExpressionError(
            f"expected a number or an expression string, got {type(source).__name__}"
        )
    if not source.strip():
        raise ExpressionError("empty expression")
    parser = _Parser(source)
    tree = parser.expr()
    kind, value = parser.peek()
    if kind != "end":
        raise ExpressionError(
            f"unexpected {_quote(value)} after a complete expression in {_quote(source)}"
        )
    if _depth(tree) > MAX_DEPTH:
        raise ExpressionError(
            f"too long: more than {MAX_DEPTH} operations in a chain in {_quote(source)}; "
            "split it into named parameters"
        )
    return Expression(source, tree)


def _depth(tree: tuple) -> int:
    """Levels of the tree, counted without recursion (the tree may be thousands deep)."""
    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, level = stack.pop()
        deepest = max(deepest, level)
        if node[0] == "neg":
            stack.append((node[1], level + 1))
        elif node[0] == "call":
            stack.extend((arg, level + 1) for arg in node[2])
        elif node[0] not in ("num", "name"):
            stack.extend(((node[1], level + 1), (node[2], level + 1)))
    return deepest


def evaluate(expression: Expression, env: dict[str, float]) -> float:
    """Value of ``expression`` with the names bound in ``env``.

    Raises
    ------
    ExpressionError
        For an unknown name, a division by zero, a domain error or a non-finite result.
    """
    try:
        value = _eval(expression.tree, env)
    except ZeroDivisionError:
        raise ExpressionError(f"division by zero in {_quote(expression.text)}") from None
    except (OverflowError, ValueError) as exc:
        if isinstance(exc, ExpressionError):
            raise
        raise ExpressionError(f"cannot evaluate {_quote(expression.text)}: {exc}") from None
    if not math.isfinite(value):
        raise ExpressionError(f"{_quote(expression.text)} evaluates to {value}")
    return value


def _eval(node: tuple, env: dict[str, float]) -> float:
    kind = node[0]
    if kind == "num":
        return node[1]
    if kind == "name":
        name = node[1]
        if name in env:
            return float(env[name])
        if name in CONSTANTS:
            return CONSTANTS[name]
        raise ExpressionError(f"unknown name {_quote(name)}")
    if kind == "neg":
        return -_eval(node[1], env)
    if kind == "call":
        function = FUNCTIONS[node[1]][0]
        return float(function(*(_eval(arg, env) for arg in node[2])))
    left = _eval(node[1], env)
    right = _eval(node[2], env)
    if kind == "+":
        return left + right
    if kind == "-":
        return left - right
    if kind == "*":
        return left * right
    if kind == "/":
        return left / right
    result = left**right
    if isinstance(result, complex):
        raise ExpressionError(f"{left} ** {right} is not real")
    return float(result)


def evaluate_on_grid(
    expression: Expression, env: dict[str, float], variable: str, grid: np.ndarray
) -> np.ndarray:
    """Values of ``expression`` of one ``variable`` at every point of ``grid`` (numpy).

    Parameters
    ----------
    expression : Expression
        E.g. ``"Fs * tanh(u / u0)"``.
    env : dict of str to float
        The other names (parameters, coefficients).
    variable : str
        The name that takes the grid's values (``"u"``).
    grid : ndarray, shape (m,)

    Returns
    -------
    ndarray, shape (m,)

    Raises
    ------
    ExpressionError
        An unknown name, or a value that is not a finite real number at some grid point
        (the first such point is named).
    """
    grid = np.asarray(grid, dtype=float)
    with np.errstate(all="ignore"):
        values = np.broadcast_to(_eval_array(expression.tree, env, variable, grid), grid.shape)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        at = grid[bad[0]]
        raise ExpressionError(
            f"{expression.text!r} is not a finite real number at {variable} = {at:.6g}"
        )
    return np.array(values, dtype=float)


def _eval_array(node: tuple, env: dict[str, float], variable: str, grid: np.ndarray):
    kind = node[0]
    if kind == "num":
        return node[1]
    if kind == "name":
        name = node[1]
        if name == variable:
            return grid
        return _eval(node, env)
    if kind == "neg":
        return -_eval_array(node[1], env, variable, grid)
    if kind == "call":
        args = [_eval_array(arg, env, variable, grid) for arg in node[2]]
        return _ARRAY_FUNCTIONS[node[1]](*args)
    left = _eval_array(node[1], env, variable, grid)
    right = _eval_array(node[2], env, variable, grid)
    if kind == "+":
        return np.add(left, right)
    if kind == "-":
        return np.subtract(left, right)
    if kind == "*":
        return np.multiply(left, right)
    if kind == "/":
        return np.divide(left, right)
    # negative bases with fractional exponents give nan, which is refused above
    return np.power(np.asarray(left, dtype=float), right)
