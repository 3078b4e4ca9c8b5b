"""Element lines of a SPICE netlist: the tokenizer and one parser per element letter.

Used by :mod:`circuitsim.netlist.reader`; see there for the whole-file rules. Each parser gets
the tokens of one logical line and returns an :class:`~circuitsim.netlist.circuit.Element`,
or raises :class:`~circuitsim.netlist.errors.NetlistError` naming the line and the usage.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass

from circuitsim.netlist.circuit import (
    Bjt,
    Capacitor,
    Cccs,
    Ccvs,
    CurrentSource,
    Diode,
    Element,
    Expression,
    Inductor,
    Jfet,
    PolyCccs,
    PolyCcvs,
    PolyVccs,
    PolyVcvs,
    Pulse,
    Pwl,
    Resistor,
    Sin,
    SubcircuitCall,
    Switch,
    Value,
    Vccs,
    Vcvs,
    VoltageSource,
    Waveform,
)
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.expressions import check_parameter_name, check_syntax
from circuitsim.netlist.names import fold
from circuitsim.netlist.values import looks_numeric, parse_value

__all__ = ["Line", "Token", "Cursor", "tokenize", "parse_element", "ELEMENT_PARSERS"]


@dataclass(frozen=True)
class Line:
    """One logical line: continuations joined, comments removed.

    ``number`` is the 1-based number of its first physical line in ``file``.
    """

    file: str
    number: int
    text: str

    def error(self, message: str) -> NetlistError:
        return NetlistError(message, file=self.file, line=self.number, text=self.text)


@dataclass(frozen=True)
class Token:
    """``kind`` is ``word``, ``expr`` (a ``{...}`` or ``'...'`` body), ``(``, ``)`` or ``=``."""

    kind: str
    text: str


_SEPARATORS = " \t\r\n\f\v,"
_SINGLE = "()="
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_.]*")


def tokenize(line: Line) -> list[Token]:
    """Split a logical line into tokens; commas count as blanks outside braces and quotes."""
    text = line.text
    tokens: list[Token] = []
    pos = 0
    n = len(text)
    while pos < n:
        ch = text[pos]
        if ch in _SEPARATORS:
            pos += 1
        elif ch in _SINGLE:
            tokens.append(Token(ch, ch))
            pos += 1
        elif ch == "{":
            depth = 0
            end = pos
            while end < n:
                if text[end] == "{":
                    depth += 1
                elif text[end] == "}":
                    depth -= 1
                    if depth == 0:
                        break
                end += 1
            if end >= n:
                raise line.error(f"unbalanced '{{' at column {pos + 1}: no matching '}}'")
            tokens.append(Token("expr", text[pos + 1 : end].strip()))
            pos = end + 1
        elif ch == "}":
            raise line.error(f"unbalanced '}}' at column {pos + 1}: no '{{' before it")
        elif ch == "'":
            end = text.find("'", pos + 1)
            if end < 0:
                raise line.error(f'unbalanced quote at column {pos + 1}: no closing "\'"')
            tokens.append(Token("expr", text[pos + 1 : end].strip()))
            pos = end + 1
        else:
            end = pos
            while end < n and text[end] not in _SEPARATORS + _SINGLE + "{}'":
                end += 1
            tokens.append(Token("word", text[pos:end]))
            pos = end
    return tokens


def node_name(text: str) -> str:
    """Node names are case-insensitive; ``gnd`` is ground, as ngspice 39 reads it."""
    key = fold(text)
    return "0" if key == "gnd" else key


class Cursor:
    """Walks the tokens of one line; every failure becomes a NetlistError with the usage."""

    def __init__(self, tokens: list[Token], line: Line, usage: str):
        self.tokens = tokens
        self.line = line
        self.usage = usage
        self.pos = 0

    def error(self, message: str) -> NetlistError:
        return self.line.error(f"{message} (expected: {self.usage})")

    def at_end(self) -> bool:
        return self.pos >= len(self.tokens)

    def peek(self) -> Token | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def take(self, what: str) -> Token:
        token = self.peek()
        if token is None:
            raise self.error(f"missing {what}")
        self.pos += 1
        return token

    def word(self, what: str) -> str:
        token = self.take(what)
        if token.kind != "word":
            raise self.error(f"expected {what}, found {_show(token)}")
        return token.text

    def node(self, what: str) -> str:
        return node_name(self.word(what))

    def value(self, what: str) -> Value:
        return to_value(self.take(what), self.line, what, self.usage)

    def is_value(self, keywords: tuple[str, ...] = ()) -> bool:
        token = self.peek()
        if token is None:
            return False
        if token.kind == "expr":
            return True
        return token.kind == "word" and fold(token.text) not in keywords

    def expect(self, kind: str, what: str) -> None:
        token = self.take(what)
        if token.kind != kind:
            raise self.error(f"expected {what}, found {_show(token)}")

    def finish(self) -> None:
        if not self.at_end():
            raise self.error(f"unexpected {_show(self.tokens[self.pos])}")

    def assignments(self, what: str) -> dict[str, Value]:
        """``name=value`` pairs to the end of the line (names lower case, order kept)."""
        out: dict[str, Value] = {}
        while not self.at_end():
            name = self.word(f"{what} name")
            if not _IDENTIFIER.fullmatch(name):
                raise self.error(f"bad {what} name {name!r}")
            self.expect("=", f"'=' after {name}")
            out[fold(name)] = self.value(f"value of {name}")
        return out


def _show(token: Token) -> str:
    return repr("{" + token.text + "}") if token.kind == "expr" else repr(token.text)


def to_value(token: Token, line: Line, what: str, usage: str | None = None) -> Value:
    """A number, ``{expression}``, ``'expression'`` or bare parameter name as a Value."""
    hint = f" (expected: {usage})" if usage else ""
    if token.kind == "expr":
        if not token.text:
            raise line.error(f"empty expression for {what}{hint}")
        try:
            check_syntax(token.text)
        except ValueError as exc:
            raise line.error(f"bad expression for {what}: {exc}") from None
        return Expression(token.text)
    if token.kind != "word":
        raise line.error(f"expected {what}, found {_show(token)}{hint}")
    text = token.text
    if looks_numeric(text):
        try:
            return parse_value(text)
        except ValueError as exc:
            raise line.error(f"bad number for {what}: {exc}") from None
    if _IDENTIFIER.fullmatch(text):
        return Expression(text)
    try:
        check_syntax(text)
    except ValueError:
        raise line.error(
            f"expected {what} (a number, {{expression}} or parameter name), found {text!r}{hint}"
        ) from None
    return Expression(text)


# --- per-letter parsers -----------------------------------------------------------------


def _passive(cls: type, usage: str, with_ic: bool) -> Callable[[Cursor, str], Element]:
    def parse(c: Cursor, name: str) -> Element:
        positive = c.node("node n+")
        negative = c.node("node n-")
        value = c.value("value")
        ic: Value | None = None
        if with_ic and not c.at_end():
            params = c.assignments("parameter")
            for key in params:
                if key != "ic":
                    raise c.error(f"unsupported parameter {key!r}")
            ic = params.get("ic")
        c.finish()
        return (
            cls(name, positive, negative, value, ic)
            if with_ic
            else cls(name, positive, negative, value)
        )

    parse.usage = usage  # type: ignore[attr-defined]
    return parse


_SOURCE_KEYWORDS = ("dc", "ac", "sin", "pulse", "pwl")
_WAVEFORM_ARITY = {"sin": (3, 6), "pulse": (2, 7)}


def _waveform(c: Cursor, kind: str) -> Waveform:
    args: list[Value] = []
    what = f"{kind.upper()} value"
    token = c.peek()
    if token is not None and token.kind == "(":
        c.take("'('")
        while True:
            token = c.peek()
            if token is None:
                raise c.error(f"missing ')' to close {kind.upper()}(")
            if token.kind == ")":
                c.take("')'")
                break
            args.append(c.value(what))
    else:
        while c.is_value(_SOURCE_KEYWORDS):
            args.append(c.value(what))
    if kind == "pwl":
        if len(args) < 2 or len(args) % 2:
            raise c.error(f"PWL needs time-value pairs, got {len(args)} value(s)")
        points = tuple((args[i], args[i + 1]) for i in range(0, len(args), 2))
        times = [t for t, _ in points]
        if all(isinstance(t, float) for t in times) and any(
            b < a for a, b in zip(times, times[1:], strict=False)
        ):
            raise c.error("PWL times must not decrease")
        return Pwl(points)
    least, most = _WAVEFORM_ARITY[kind]
    if not least <= len(args) <= most:
        raise c.error(f"{kind.upper()} takes {least} to {most} values, got {len(args)}")
    return Sin(*args) if kind == "sin" else Pulse(*args)


def _source(cls: type, usage: str) -> Callable[[Cursor, str], Element]:
    def parse(c: Cursor, name: str) -> Element:
        positive = c.node("node n+")
        negative = c.node("node n-")
        fields: dict[str, object] = {}
        while not c.at_end():
            token = c.peek()
            assert token is not None
            key = fold(token.text) if token.kind == "word" else ""
            if key == "dc":
                c.take("DC")
                _once(c, fields, "dc", c.value("DC value"))
            elif key == "ac":
                c.take("AC")
                magnitude: Value = 1.0  # SPICE: AC without a magnitude means 1
                phase: Value = 0.0
                if c.is_value(_SOURCE_KEYWORDS):
                    magnitude = c.value("AC magnitude")
                    if c.is_value(_SOURCE_KEYWORDS):
                        phase = c.value("AC phase")
                _once(c, fields, "ac_magnitude", magnitude)
                fields["ac_phase"] = phase
            elif key in ("sin", "pulse", "pwl"):
                c.take(key)
                _once(c, fields, "waveform", _waveform(c, key))
            elif c.is_value(_SOURCE_KEYWORDS) and not fields:
                fields["dc"] = c.value("DC value")
            else:
                raise c.error(f"unexpected {_show(token)}")
        return cls(name, positive, negative, **fields)

    parse.usage = usage  # type: ignore[attr-defined]
    return parse


def _once(c: Cursor, fields: dict[str, object], key: str, value: object) -> None:
    if key in fields:
        raise c.error(f"{key.split('_')[0].upper()} given twice")
    fields[key] = value


_NONLINEAR = ("poly", "value", "table", "vol", "cur", "laplace")


def _is_poly(c: Cursor) -> bool:
    token = c.peek()
    following = c.tokens[c.pos + 1] if c.pos + 1 < len(c.tokens) else None
    return (
        token is not None
        and token.kind == "word"
        and fold(token.text) == "poly"
        and following is not None
        and following.kind == "("
    )


def _poly_dimension(c: Cursor) -> int:
    """``POLY(n)``: the number of controlling quantities n (1 to 20)."""
    c.take("POLY")
    c.expect("(", "'(' after POLY")
    text = c.word("POLY dimension")
    c.expect(")", "')' after the POLY dimension")
    if not text.isdigit() or not 1 <= int(text) <= 20:
        raise c.error(f"POLY dimension must be a whole number from 1 to 20, found {text!r}")
    return int(text)


def _poly_coefficients(c: Cursor) -> tuple[Value, ...]:
    coefficients = []
    while not c.at_end():
        coefficients.append(c.value("POLY coefficient"))
    if not coefficients:
        raise c.error("POLY needs at least one coefficient")
    return tuple(coefficients)


def _skip_parentheses(c: Cursor) -> None:
    """PSpice writes a POLY's node pairs as ``(nc+, nc-)``; the parentheses mean nothing."""
    while (token := c.peek()) is not None and token.kind in ("(", ")"):
        c.pos += 1


def _voltage_controlled(
    cls: type, poly: type, usage: str, value_name: str
) -> Callable[..., Element]:
    def parse(c: Cursor, name: str) -> Element:
        nodes = [c.node("node n+"), c.node("node n-")]
        if _is_poly(c):
            count = _poly_dimension(c)
            controls = []
            for k in range(1, count + 1):
                _skip_parentheses(c)
                pair = (c.node(f"node nc{k}+"), c.node(f"node nc{k}-"))
                _skip_parentheses(c)
                controls.append(pair)
            return poly(name, *nodes, tuple(controls), _poly_coefficients(c))
        token = c.peek()
        following = c.tokens[c.pos + 1] if c.pos + 1 < len(c.tokens) else None
        if (
            token is not None
            and token.kind == "word"
            and fold(token.text) in _NONLINEAR
            and following is not None
            and following.kind in ("(", "=")
        ):
            raise c.error(
                f"nonlinear form {token.text.upper()} is not supported, only linear and POLY(n)"
            )
        nodes += [c.node("node nc+"), c.node("node nc-")]
        gain = c.value(value_name)
        c.finish()
        return cls(name, *nodes, gain)

    parse.usage = usage  # type: ignore[attr-defined]
    return parse


def _current_controlled(
    cls: type, poly: type, usage: str, value_name: str
) -> Callable[..., Element]:
    def parse(c: Cursor, name: str) -> Element:
        positive = c.node("node n+")
        negative = c.node("node n-")
        if _is_poly(c):
            count = _poly_dimension(c)
            controls = []
            for k in range(1, count + 1):
                control = c.word(f"controlling voltage source {k}")
                if not control[:1].isalpha():
                    raise c.error(f"expected the name of a voltage source, found {control!r}")
                controls.append(control)
            return poly(name, positive, negative, tuple(controls), _poly_coefficients(c))
        control = c.word("controlling voltage source name")
        if fold(control) == "poly" or not control[:1].isalpha():
            raise c.error(f"expected the name of a voltage source, found {control!r}")
        gain = c.value(value_name)
        c.finish()
        return cls(name, positive, negative, control, gain)

    parse.usage = usage  # type: ignore[attr-defined]
    return parse


def _area_and_params(c: Cursor, allowed: tuple[str, ...]) -> tuple[Value, dict[str, Value]]:
    """An optional positional area, then ``name=value`` pairs among ``allowed``."""
    area: Value = 1.0
    params: dict[str, Value] = {}
    if not c.at_end():
        following = c.tokens[c.pos + 1] if c.pos + 1 < len(c.tokens) else None
        if not (following is not None and following.kind == "="):
            area = c.value("area")
        params = c.assignments("parameter")
        unknown = sorted(set(params) - set(allowed))
        if unknown:
            raise c.error(f"unsupported parameter {unknown[0]!r}")
        area = params.pop("area", area)
    c.finish()
    return area, params


def _diode(c: Cursor, name: str) -> Element:
    anode = c.node("anode node")
    cathode = c.node("cathode node")
    model = fold(c.word("model name"))
    area, _ = _area_and_params(c, ("area",))
    return Diode(name, anode, cathode, model, area)


def _jfet(c: Cursor, name: str) -> Element:
    nodes = [c.node(w) for w in ("drain node", "gate node", "source node")]
    model = fold(c.word("model name"))
    area, _ = _area_and_params(c, ("area",))
    return Jfet(name, *nodes, model, area)


_jfet.usage = "Jname drain gate source model [area]"  # type: ignore[attr-defined]


def _bjt(c: Cursor, name: str) -> Element:
    nodes = [c.node(w) for w in ("collector node", "base node", "emitter node")]
    words = []
    while (token := c.peek()) is not None and token.kind == "word":
        following = c.tokens[c.pos + 1] if c.pos + 1 < len(c.tokens) else None
        if (following is not None and following.kind == "=") or looks_numeric(token.text):
            break
        words.append(c.word("model name"))
    if not words or len(words) > 2:
        raise c.error("expected [substrate node] and a model name after the three nodes")
    substrate = node_name(words[0]) if len(words) == 2 else None
    area, _ = _area_and_params(c, ("area",))
    return Bjt(name, *nodes, fold(words[-1]), area, substrate)


_bjt.usage = "Qname collector base emitter [substrate] model [area]"  # type: ignore[attr-defined]


_diode.usage = "Dname anode cathode model [area]"  # type: ignore[attr-defined]


def _switch(c: Cursor, name: str) -> Element:
    nodes = [c.node(w) for w in ("node n+", "node n-", "node nc+", "node nc-")]
    model = fold(c.word("model name"))
    initial = None
    if not c.at_end():
        flag = fold(c.word("ON or OFF"))
        if flag not in ("on", "off"):
            raise c.error(f"expected ON or OFF, found {flag!r}")
        initial = flag
    c.finish()
    return Switch(name, *nodes, model=model, initial=initial)


_switch.usage = "Sname n+ n- nc+ nc- model [ON|OFF]"  # type: ignore[attr-defined]


def split_header(c: Cursor, what: str) -> tuple[list[str], dict[str, Value]]:
    """Words up to ``params:`` or the first ``name=`` pair, then the assignments."""
    words: list[str] = []
    while not c.at_end():
        token = c.peek()
        assert token is not None
        following = c.tokens[c.pos + 1] if c.pos + 1 < len(c.tokens) else None
        if token.kind == "word" and fold(token.text) == "params:":
            c.take("params:")
            break
        if token.kind == "word" and following is not None and following.kind == "=":
            break
        words.append(c.word(what))
    params = c.assignments("parameter")
    for name in params:
        try:
            check_parameter_name(name)
        except ValueError as exc:
            raise c.error(str(exc)) from None
    return words, params


def _call(c: Cursor, name: str) -> Element:
    words, params = split_header(c, "node or subcircuit name")
    if not words:
        raise c.error("missing subcircuit name")
    connections = tuple(node_name(w) for w in words[:-1])
    return SubcircuitCall(name, connections, fold(words[-1]), params)


_call.usage = "Xname node ... subckt [params: name=value ...]"  # type: ignore[attr-defined]


ELEMENT_PARSERS: dict[str, Callable[[Cursor, str], Element]] = {
    "R": _passive(Resistor, "Rname n+ n- value", with_ic=False),
    "C": _passive(Capacitor, "Cname n+ n- value [IC=v]", with_ic=True),
    "L": _passive(Inductor, "Lname n+ n- value [IC=i]", with_ic=True),
    "V": _source(VoltageSource, "Vname n+ n- [[DC] v] [AC mag [phase]] [SIN|PULSE|PWL(...)]"),
    "I": _source(CurrentSource, "Iname n+ n- [[DC] i] [AC mag [phase]] [SIN|PULSE|PWL(...)]"),
    "E": _voltage_controlled(
        Vcvs, PolyVcvs, "Ename n+ n- nc+ nc- gain | POLY(n) nc1+ nc1- ... p0 p1 ...", "gain"
    ),
    "G": _voltage_controlled(
        Vccs,
        PolyVccs,
        "Gname n+ n- nc+ nc- transconductance | POLY(n) nc1+ nc1- ... p0 p1 ...",
        "transconductance",
    ),
    "F": _current_controlled(
        Cccs, PolyCccs, "Fname n+ n- vcontrol gain | POLY(n) v1 ... p0 p1 ...", "gain"
    ),
    "H": _current_controlled(
        Ccvs,
        PolyCcvs,
        "Hname n+ n- vcontrol transresistance | POLY(n) v1 ... p0 p1 ...",
        "transresistance",
    ),
    "D": _diode,
    "J": _jfet,
    "Q": _bjt,
    "S": _switch,
    "X": _call,
}


def parse_element(line: Line) -> Element:
    """Parse one element line (its first character is the element letter)."""
    tokens = tokenize(line)
    if not tokens or tokens[0].kind != "word":
        raise line.error("expected an element name")
    name = tokens[0].text
    letter = name[:1].upper()
    parser = ELEMENT_PARSERS.get(letter)
    if parser is None:
        known = " ".join(sorted(ELEMENT_PARSERS))
        raise line.error(f"unsupported element type {letter!r} in {name!r} (supported: {known})")
    cursor = Cursor(tokens, line, parser.usage)  # type: ignore[attr-defined]
    cursor.pos = 1
    return parser(cursor, name)
