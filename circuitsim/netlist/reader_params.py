"""``.param`` lines: ``name = expression`` pairs where the expression may hold blanks.

``.param a=1k b = {a*2} c=sqrt(a) + 1 d='a/2'`` is four parameters: a value runs until the
next ``name =`` at the top level (outside parentheses, braces and quotes) or the line's end.
"""

from __future__ import annotations

import re

from circuitsim.netlist.circuit import Expression, Value
from circuitsim.netlist.expressions import check_parameter_name, check_syntax
from circuitsim.netlist.names import fold
from circuitsim.netlist.reader_elements import Line
from circuitsim.netlist.values import looks_numeric, parse_value

__all__ = ["split_assignments"]

_NAME_EQUALS = re.compile(r"[,\s]*([A-Za-z_][A-Za-z0-9_.]*)\s*=(?!=)\s*")
_NEXT_NAME = re.compile(r"[,\s]+[A-Za-z_][A-Za-z0-9_.]*\s*=(?!=)")


def _value_end(text: str, start: int, line: Line) -> int:
    """Index where the value starting at ``start`` ends."""
    depth = 0
    quote = False
    i = start
    while i < len(text):
        ch = text[i]
        if ch == "'":
            quote = not quote
        elif not quote and ch in "({":
            depth += 1
        elif not quote and ch in ")}":
            depth -= 1
            if depth < 0:
                raise line.error(f"unbalanced {ch!r} at column {i + 1} of the .param values")
        elif (
            not quote
            and depth == 0
            and ch in " \t,"
            and text[i - 1] not in " \t,"  # only where a blank run starts: linear time
            and _NEXT_NAME.match(text, i)
        ):
            return i
        i += 1
    if quote:
        raise line.error("unbalanced quote in .param")
    if depth:
        raise line.error("unbalanced parentheses or braces in .param")
    return i


def param_value(raw: str, line: Line, name: str) -> Value:
    """A ``.param`` right-hand side as a float or an Expression (checked for syntax)."""
    text = raw.strip()
    if not text:
        raise line.error(f"missing value for parameter {name!r} (expected: .param name=value)")
    if len(text) >= 2 and (text[0], text[-1]) in (("{", "}"), ("'", "'")):
        text = text[1:-1].strip()
    elif looks_numeric(text):
        try:
            return parse_value(text)
        except ValueError:
            pass  # an expression that starts with a number, such as 2*a
    if not text:
        raise line.error(f"empty expression for parameter {name!r}")
    try:
        check_syntax(text)
    except ValueError as exc:
        raise line.error(f"bad expression for parameter {name!r}: {exc}") from None
    return Expression(text)


def split_assignments(line: Line, rest: str) -> dict[str, Value]:
    """The ``name=value`` pairs after ``.param``; names lower case, in written order."""
    out: dict[str, Value] = {}
    pos = 0
    rest = rest.rstrip()
    if not rest.strip():
        raise line.error("missing name=value (expected: .param name=value ...)")
    while pos < len(rest):
        match = _NAME_EQUALS.match(rest, pos)
        if match is None:
            found = rest[pos:].strip().split()[0] if rest[pos:].strip() else rest[pos:]
            raise line.error(f"expected name=value, found {found!r} (expected: .param name=value)")
        name = match.group(1)
        try:
            check_parameter_name(name)
        except ValueError as exc:
            raise line.error(str(exc)) from None
        end = _value_end(rest, match.end(), line)
        out[fold(name)] = param_value(rest[match.end() : end], line, name)
        pos = end
        if not rest[pos:].strip(" \t,"):
            break
    return out
