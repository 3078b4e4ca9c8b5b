"""SPICE parameter expressions, ``{2*rbase + sqrt(c1/c2)}``, evaluated without ``eval``.

Grammar (a hand-written tokenizer and recursive-descent parser, lowest precedence first)::

    expression := term (("+" | "-") term)*
    term       := unary (("*" | "/") unary)*
    unary      := ("-" | "+") unary | power
    power      := primary (("**" | "^") unary)?        right-associative, binds tighter
    primary    := number | name | name "(" [expression ("," expression)*] ")"
                | "(" expression ")"

so ``-2^2`` is -4 and ``2^3^2`` is 512, as in ngspice. Numbers take SPICE suffixes
(``2*1k``, ``10u/3``). Names are case-insensitive parameter names or the constant ``pi``
(a parameter called ``pi`` wins). Functions: sqrt exp ln log10 log (natural log, as ngspice:
LTspice's ``log`` is also natural) sin cos tan atan abs min max pow. Comparisons and the
ternary operator are not supported.

Every failure (bad token, unknown name, wrong number of arguments, division by zero, a result
outside the float range, nesting deeper than 100) is a ValueError that names the culprit; an
unknown name is the subclass :class:`UndefinedParameterError`, which also carries the name.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping

from circuitsim.netlist.names import fold
from circuitsim.netlist.values import parse_value

__all__ = [
    "evaluate",
    "check_syntax",
    "check_parameter_name",
    "FUNCTIONS",
    "NGSPICE_FUNCTIONS",
    "names_in",
    "UndefinedParameterError",
]

_MAX_DEPTH = 100


class UndefinedParameterError(ValueError):
    """An expression names a parameter that is not defined.

    Parameters
    ----------
    message : str
        The whole message (``"undefined parameter 'rx' in '2*rx'"``).
    name : str
        The parameter name as written in the expression.
    """

    def __init__(self, message: str, name: str):
        super().__init__(message)
        self.name = name


def _ln(x: float) -> float:
    if x <= 0.0:
        raise ValueError(f"logarithm of a non-positive number ({x!r})")
    return math.log(x)


def _log10(x: float) -> float:
    if x <= 0.0:
        raise ValueError(f"logarithm of a non-positive number ({x!r})")
    return math.log10(x)


def _sqrt(x: float) -> float:
    if x < 0.0:
        raise ValueError(f"square root of a negative number ({x!r})")
    return math.sqrt(x)


def _pow(x: float, y: float) -> float:
    if x == 0.0 and y < 0.0:
        raise ValueError("zero raised to a negative power")
    if x < 0.0 and not float(y).is_integer():
        raise ValueError(f"negative number {x!r} raised to the non-integer power {y!r}")
    try:
        return math.pow(x, y)
    except OverflowError:
        raise ValueError(f"{x!r} ** {y!r} is beyond the float range") from None


def _exp(x: float) -> float:
    try:
        return math.exp(x)
    except OverflowError:
        raise ValueError(f"exp({x!r}) is beyond the float range") from None


# name -> (function, smallest and largest number of arguments)
FUNCTIONS: dict[str, tuple[Callable[..., float], int, int]] = {
    "sqrt": (_sqrt, 1, 1),
    "exp": (_exp, 1, 1),
    "ln": (_ln, 1, 1),
    "log": (_ln, 1, 1),
    "log10": (_log10, 1, 1),
    "sin": (math.sin, 1, 1),
    "cos": (math.cos, 1, 1),
    "tan": (math.tan, 1, 1),
    "atan": (math.atan, 1, 1),
    "abs": (abs, 1, 1),
    # min(x) and max(x) of one argument are x, as in ngspice (Python's min(x) would iterate x)
    "min": (lambda *args: min(args), 1, 64),
    "max": (lambda *args: max(args), 1, 64),
    "pow": (_pow, 2, 2),
    "pi": (lambda: math.pi, 0, 0),
}

# ngspice's function names (numparam's list): a parameter named like one of them is fatal or
# silently wrong there ({sqrt} is an error, {sqrt+1} evaluates to 1), so the reader refuses it.
NGSPICE_FUNCTIONS = frozenset(
    "sqr sqrt sin cos exp ln arctan abs pow pwr max min int log log10 sinh cosh tanh "
    "ternary_fcn agauss sgn gauss unif aunif limit ceil floor asin acos atan asinh acosh "
    "atanh tan nint".split()
)


def check_parameter_name(name: str) -> None:
    """Raise ValueError if ``name`` cannot name a parameter because it names a function."""
    if fold(name) in NGSPICE_FUNCTIONS:
        raise ValueError(
            f"parameter name {name!r} is the name of a function; ngspice cannot use it as a "
            "parameter (an expression using it fails or evaluates wrongly): rename it"
        )


_TOKEN = re.compile(
    r"""
    (?P<space>\s+)
  | (?P<number>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?(?:[a-zA-Z][a-zA-Z0-9_]*)?)
  | (?P<name>[a-zA-Z_][a-zA-Z0-9_.]*)
  | (?P<op>\*\*|[-+*/^(),])
    """,
    re.VERBOSE | re.ASCII,  # digits and blanks as ngspice reads them: '１０' is no number
)


def _tokenize(text: str) -> list[tuple[str, str, int]]:
    """(kind, text, column) triples; kind is number, name, op or end."""
    tokens: list[tuple[str, str, int]] = []
    pos = 0
    while pos < len(text):
        match = _TOKEN.match(text, pos)
        if match is None:
            raise ValueError(f"unexpected character {text[pos]!r} at column {pos + 1} in {text!r}")
        kind = match.lastgroup or ""
        if kind != "space":
            tokens.append((kind, match.group(), pos))
        pos = match.end()
    tokens.append(("end", "", len(text)))
    return tokens


class _Parser:
    def __init__(self, text: str, params: Mapping[str, float], dry: bool = False):
        # dry: check the grammar, names and arities only; every value is 1.0 (no arithmetic)
        self.dry = dry
        self.text = text
        self.tokens = _tokenize(text)
        self.index = 0
        self.depth = 0
        # Looked up as written first (the reader and flatten hand over folded names); a folded
        # copy is made only on a miss, not per call: a chain of n .param lines stays O(n).
        self.params = params
        self.folded: dict[str, float] | None = None

    # --- helpers ---
    def lookup(self, key: str) -> float | None:
        """The value of parameter ``key`` (folded), or None."""
        value = self.params.get(key)
        if value is None:
            if self.folded is None:
                self.folded = {fold(str(k)): v for k, v in self.params.items()}
            value = self.folded.get(key)
        return value

    def peek(self) -> tuple[str, str, int]:
        return self.tokens[self.index]

    def take(self) -> tuple[str, str, int]:
        token = self.tokens[self.index]
        self.index += 1
        return token

    def expect(self, op: str) -> None:
        kind, text, column = self.take()
        if not (kind == "op" and text == op):
            found = repr(text) if kind != "end" else "the end"
            raise ValueError(
                f"expected {op!r} but found {found} at column {column + 1} in {self.text!r}"
            )

    def enter(self) -> None:
        self.depth += 1
        if self.depth > _MAX_DEPTH:
            raise ValueError(
                f"expression nested deeper than {_MAX_DEPTH} levels: {self.text[:60]!r}"
            )

    # --- grammar ---
    def parse(self) -> float:
        if self.peek()[0] == "end":
            raise ValueError("empty expression")
        value = self.expression()
        kind, text, column = self.peek()
        if kind != "end":
            raise ValueError(f"unexpected {text!r} at column {column + 1} in {self.text!r}")
        return value

    def expression(self) -> float:
        self.enter()
        value = self.term()
        while self.peek()[0] == "op" and self.peek()[1] in "+-":
            op = self.take()[1]
            right = self.term()
            value = value + right if op == "+" else value - right
        self.depth -= 1
        return value if self.dry else _finite(value, self.text)

    def term(self) -> float:
        value = self.unary()
        while self.peek()[0] == "op" and self.peek()[1] in ("*", "/"):
            op = self.take()[1]
            right = self.unary()
            if self.dry:
                continue
            if op == "*":
                value = value * right
            else:
                if right == 0.0:
                    raise ValueError(f"division by zero in {self.text!r}")
                value = value / right
            value = _finite(value, self.text)
        return value

    def unary(self) -> float:
        kind, text, _ = self.peek()
        if kind == "op" and text in "+-" and text:
            self.take()
            self.enter()
            value = self.unary()
            self.depth -= 1
            return -value if text == "-" else value
        return self.power()

    def power(self) -> float:
        base = self.primary()
        kind, text, _ = self.peek()
        if kind == "op" and text in ("**", "^"):
            self.take()
            self.enter()
            exponent = self.unary()
            self.depth -= 1
            return 1.0 if self.dry else _pow(base, exponent)
        return base

    def primary(self) -> float:
        kind, text, column = self.take()
        if kind == "number":
            try:
                return parse_value(text)
            except ValueError as exc:
                raise ValueError(f"bad number {text!r} in {self.text!r}: {exc}") from None
        if kind == "name":
            key = fold(text)
            if self.peek()[:2] == ("op", "("):
                return self.call(key, text)
            if self.dry:
                return 1.0
            value = self.lookup(key)
            if value is not None:
                return float(value)
            if key == "pi":
                return math.pi
            if key in FUNCTIONS:
                raise ValueError(f"function {text!r} needs its arguments in parentheses")
            raise UndefinedParameterError(f"undefined parameter {text!r} in {self.text!r}", text)
        if kind == "op" and text == "(":
            value = self.expression()
            self.expect(")")
            return value
        found = repr(text) if kind != "end" else "end of the expression"
        raise ValueError(f"unexpected {found} at column {column + 1} in {self.text!r}")

    def call(self, key: str, name: str) -> float:
        if key not in FUNCTIONS:
            raise ValueError(f"unknown function {name!r} in {self.text!r}")
        function, least, most = FUNCTIONS[key]
        self.expect("(")
        args: list[float] = []
        if self.peek()[:2] != ("op", ")"):
            args.append(self.expression())
            while self.peek()[:2] == ("op", ","):
                self.take()
                args.append(self.expression())
        self.expect(")")
        if not least <= len(args) <= most:
            wanted = str(least) if least == most else f"{least} to {most}"
            raise ValueError(
                f"{name}() takes {wanted} argument(s), got {len(args)} in {self.text!r}"
            )
        if self.dry:
            return 1.0
        try:
            value = function(*args)
        except (OverflowError, ArithmeticError) as exc:
            raise ValueError(f"{name}{tuple(args)} failed: {exc}") from None
        return _finite(value, self.text)


def _finite(value: float, text: str) -> float:
    if not math.isfinite(value):
        raise ValueError(f"expression {text!r} is beyond the float range")
    return value


def evaluate(text: str, params: Mapping[str, float]) -> float:
    """Evaluate a SPICE expression.

    Parameters
    ----------
    text : str
        The expression without braces, e.g. ``"2*rbase + 1k"``.
    params : mapping of str to float
        Parameter values; names are matched case-insensitively.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        Naming the bad token, unknown parameter or function, or the arithmetic failure.
    """
    if not isinstance(text, str):
        raise ValueError(f"expected an expression as text, got {type(text).__name__}")
    return _Parser(text, params).parse()


def check_syntax(text: str) -> None:
    """Raise ValueError if ``text`` is not a well-formed expression (names are not looked up).

    Used by the reader so that a malformed ``{...}`` is reported with its line number at read
    time rather than later in :func:`circuitsim.netlist.flatten.flatten`.
    """
    if not isinstance(text, str):
        raise ValueError(f"expected an expression as text, got {type(text).__name__}")
    _Parser(text, {}, dry=True).parse()


def names_in(text: str) -> list[str]:
    """Parameter names an expression refers to (lower case, functions and ``pi()`` excluded).

    Raises ValueError for text that does not tokenize.
    """
    tokens = _tokenize(text)
    names: list[str] = []
    for i, (kind, token, _) in enumerate(tokens):
        if kind != "name":
            continue
        following = tokens[i + 1]
        if following[:2] == ("op", "(") and fold(token) in FUNCTIONS:
            continue
        if fold(token) not in names:
            names.append(fold(token))
    return names
