"""SPICE netlist text to a :class:`~circuitsim.netlist.circuit.Circuit`.

What is read (ngspice 39 conventions, checked with ``ngspice -b``):

- The first line is always the title, whatever it holds. ``.title text`` replaces it.
- ``+`` at the start of a line continues the previous logical line (comment lines may sit in
  between); errors report the first physical line. ``*`` starts a comment line; ``;``
  anywhere and ``$`` at the start of a word start an inline comment.
- Keywords and node names are case-insensitive; node names are stored lower case, and
  ``gnd`` is stored as ``"0"`` (ngspice 39 treats ``gnd`` as ground: a test proves it).
  Element names keep their case. Model and subcircuit references (``Diode.model``,
  ``Switch.model``, ``SubcircuitCall.subcircuit``) are stored lower case, as are the keys
  of ``models``/``subcircuits``/``params``; ``Model.name`` and ``Subcircuit.name`` keep the
  case they were written with. F/H control names keep their case (element lookup is
  case-insensitive).
- Elements R C L V I E F G H D S X (see :mod:`circuitsim.netlist.reader_elements`).
- Values: numbers with suffixes (:mod:`circuitsim.netlist.values`), ``{expr}`` or ``'expr'``
  or a bare parameter name, stored as :class:`~circuitsim.netlist.circuit.Expression` and
  checked for syntax at read time.
- Directives: ``.title .tran .op .ac .ic .options/.option/.opt .param .model .subckt/.ends
  .include/.inc .lib/.endl .control/.endc .end``.
- ``.include file`` and ``.lib file [section]``: paths relative to the including file's
  folder (``base_dir`` for text, else the working directory); if absent there, the package
  part library ``circuitsim/netlist/library/``. Included text has no title line. A ``.lib
  name`` with one word followed later in the same file by ``.endl`` is a section; sections
  are read only when asked for by ``.lib file name``. Include cycles are errors.
- ``.options`` values: numbers are floats, ``{...}`` evaluated (with the global ``.param``
  values read so far) or else kept as Expressions, flags ``True`` and other
  words (``method=gear``) the word as a ``str`` (lower case).

Ignored with a :class:`NetlistWarning` (``warnings`` module), because they only choose what a
simulator prints or saves and carry no circuit meaning: ``.save .print .plot .probe .meas
.measure .four``. Everything else is a :class:`~circuitsim.netlist.errors.NetlistError`:
unknown directives, unsupported element letters (Q M J K T B ...), ``.global`` (only ground is
global here; pass nodes through subcircuit ports instead), ``.endl``/``.ends`` without their
opening line (and ``.endc``), a ``.subckt`` without ``.ends``, a ``.control`` without
``.endc``, duplicate element, ``.model`` or ``.subckt`` names in one scope (the top level with
its included files, or one ``.subckt`` body; names compared ignoring case). Lines after
``.end`` are not read (``.end`` in an included file ends that file only).
"""

from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from circuitsim.netlist.circuit import (
    AcSweep,
    Circuit,
    Element,
    Expression,
    Model,
    OperatingPoint,
    Subcircuit,
    Transient,
    Value,
)
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.expressions import evaluate
from circuitsim.netlist.included import expressions, mark_included
from circuitsim.netlist.names import fold
from circuitsim.netlist.reader_elements import (
    Cursor,
    Line,
    node_name,
    parse_element,
    split_header,
    to_value,
    tokenize,
)
from circuitsim.netlist.reader_lines import (
    Control,
    include_target,
    logical_lines,
    read_file,
    select_sections,
)
from circuitsim.netlist.reader_params import split_assignments
from circuitsim.netlist.values import looks_numeric

__all__ = ["parse_netlist", "read_netlist", "NetlistWarning", "LIBRARY_DIR"]

LIBRARY_DIR = Path(__file__).resolve().parent / "library"

_IGNORED = (".save", ".print", ".plot", ".probe", ".meas", ".measure", ".four")
_MAX_INCLUDE_DEPTH = 32
_KEYWORD = re.compile(r"([^ \t\r\n\f\v]*)[ \t\r\n\f\v]*(.*)", re.DOTALL)


class NetlistWarning(UserWarning):
    """A netlist line was read but not kept (e.g. ``.print``), so nothing is lost silently."""


# --- include files -----------------------------------------------------------------------


def _resolve(line: Line, path: str, base_dir: Path) -> Path:
    candidate = Path(path)
    tried = [candidate] if candidate.is_absolute() else [base_dir / candidate, LIBRARY_DIR / path]
    for option in tried:
        try:
            if option.is_file():
                return option.resolve()
        except (OSError, ValueError):  # a name too long, or with a NUL: not a file we can read
            continue
    where = " or ".join(str(t) for t in tried)
    raise line.error(f"include file {path!r} not found (looked for {where})")


# --- the reader ---------------------------------------------------------------------------


@dataclass
class _Scope:
    """A place elements go: the top level or an open ``.subckt``."""

    opened: Line | None
    elements: list[Element]
    models: dict
    subcircuits: dict
    params: dict
    subcircuit: Subcircuit | None = None
    names: dict[str, Line] = field(default_factory=dict)  # element name, lower case -> line


@dataclass
class _Reader:
    circuit: Circuit
    scopes: list[_Scope] = field(default_factory=list)
    include_stack: list[str] = field(default_factory=list)
    known: dict[str, float] = field(default_factory=dict)  # global params evaluable so far

    def run(self, lines: list[Line | Control], base_dir: Path) -> None:
        for entry in lines:
            if isinstance(entry, Control):
                if len(self.scopes) > 1:
                    raise entry.line.error(".control is not allowed inside a .subckt")
                self.circuit.control.append(entry.text)
                continue
            if entry.text.startswith("."):
                self.directive(entry, base_dir)
            else:
                self.add_element(entry)

    def add_element(self, line: Line) -> None:
        """Parse an element line into the open scope; names are unique per scope, any case.

        ngspice refuses a second ``R1`` (or ``r1``) in one scope ("device already exists"),
        also inside a ``.subckt`` body once it is instantiated; instances of one body, and a
        body and the top level, do not clash because instance elements get prefixed names.
        """
        element = parse_element(line)
        scope = self.scopes[-1]
        key = fold(element.name)
        first = scope.names.get(key)
        if first is not None:
            where = f"{first.file}:{first.number}"
            inside = f" in .subckt {scope.subcircuit.name}" if scope.subcircuit else ""
            raise line.error(f"element {element.name} defined twice{inside} (first at {where})")
        scope.names[key] = line
        scope.elements.append(element)

    # --- directives ---
    def directive(self, line: Line, base_dir: Path) -> None:
        # any blank ends the keyword (".tran\t1u 1m" is read by ngspice): ASCII blanks only
        word, rest = _KEYWORD.match(line.text).groups()
        keyword = fold(word)
        handler = _DIRECTIVES.get(keyword)
        if handler is not None:
            handler(self, line, rest, base_dir)
            return
        if keyword in _IGNORED:
            warnings.warn(
                f"{line.file}:{line.number}: {word} ignored (output requests carry no circuit "
                "meaning; use the runner's outputs instead)",
                NetlistWarning,
                stacklevel=4,
            )
            return
        if keyword == ".endc":
            raise line.error(".endc without a .control before it")
        if keyword == ".global":
            raise line.error(
                ".global is not supported: only ground 0 (alias gnd) is global; pass the node "
                "through the subcircuit's ports instead"
            )
        known = " ".join(sorted(_DIRECTIVES))
        raise line.error(f"unsupported directive {word!r} (supported: {known})")

    def top_only(self, line: Line, what: str) -> None:
        if len(self.scopes) > 1:
            raise line.error(f"{what} is not allowed inside a .subckt")

    def include(self, line: Line, rest: str, base_dir: Path) -> None:
        what = fold(line.text.split()[0])
        what = ".include" if what.startswith(".inc") else ".lib"
        path_text, section = include_target(line, rest, what)
        path = _resolve(line, path_text, base_dir)
        key = f"{path}#{section or ''}"
        if key in self.include_stack or len(self.include_stack) >= _MAX_INCLUDE_DEPTH:
            chain = " -> ".join(k.split("#")[0] for k in [*self.include_stack, key])
            raise line.error(f"include cycle: {chain}")
        _, lines = logical_lines(read_file(line, path, str(path)), str(path), has_title=False)
        lines = select_sections(lines, section, line, path)
        self.include_stack.append(key)
        hide = LIBRARY_DIR not in path.resolve().parents  # our part library is no secret
        before = expressions((self.circuit, self.scopes)) if hide else []
        try:
            self.run(lines, path.parent)
        finally:
            self.include_stack.pop()
        if hide:
            mark_included((self.circuit, self.scopes), before, str(path))

    def lib(self, line: Line, rest: str, base_dir: Path) -> None:
        self.include(line, rest, base_dir)

    def endl(self, line: Line, rest: str, base_dir: Path) -> None:
        raise line.error(".endl without a .lib section before it")

    def title(self, line: Line, rest: str, base_dir: Path) -> None:
        self.circuit.title = rest.strip()

    def end_subckt(self, line: Line, rest: str, base_dir: Path) -> None:
        if len(self.scopes) == 1:
            raise line.error(".ends without a .subckt before it")
        scope = self.scopes.pop()
        assert scope.subcircuit is not None
        words = rest.split()
        if len(words) > 1:
            raise line.error(f"unexpected {words[1]!r} after .ends name")
        if words and fold(words[0]) != fold(scope.subcircuit.name):
            raise line.error(
                f".ends {words[0]} does not match the open .subckt {scope.subcircuit.name}"
            )

    def subckt(self, line: Line, rest: str, base_dir: Path) -> None:
        c = Cursor(tokenize(line), line, ".subckt name port ... [params: name=default ...]")
        c.pos = 1
        words, params = split_header(c, "subcircuit name or port")
        if not words:
            raise c.error("missing subcircuit name")
        name, ports = words[0], tuple(node_name(w) for w in words[1:])
        seen: set[str] = set()
        for port in ports:  # linear: a fuzzed header had 50,000 ports
            if port in seen:
                raise c.error(f"port {port!r} listed twice")
            seen.add(port)
        if "0" in ports:
            raise c.error("ground (0) cannot be a subcircuit port")
        scope = self.scopes[-1]
        if fold(name) in scope.subcircuits:
            raise line.error(f"subcircuit {name!r} defined twice")
        sub = Subcircuit(name, ports, params=params)
        scope.subcircuits[fold(name)] = sub
        self.scopes.append(_Scope(line, sub.elements, sub.models, sub.subcircuits, sub.params, sub))

    def model(self, line: Line, rest: str, base_dir: Path) -> None:
        c = Cursor(tokenize(line), line, ".model name kind(param=value ...)")
        c.pos = 1
        name = c.word("model name")
        kind = c.word("model kind (D, SW ...)").upper()
        token = c.peek()
        if token is not None and token.kind == "(":
            c.take("(")
            close = next((i for i in range(c.pos, len(c.tokens)) if c.tokens[i].kind == ")"), None)
            if close is None or close != len(c.tokens) - 1:
                raise c.error("unbalanced parentheses in the parameter list")
            inner = Cursor(c.tokens[c.pos : close], line, c.usage)
            params = inner.assignments("model parameter")
        else:
            params = c.assignments("model parameter")
        scope = self.scopes[-1]
        if fold(name) in scope.models:
            raise line.error(f"model {name!r} defined twice")
        scope.models[fold(name)] = Model(name, kind, params)
        # topology (and networkx with it, a third of a second) only for a model that sets VH
        vh = params.get("vh")
        problem = None
        if isinstance(vh, float | int) and vh < 0:
            from circuitsim.netlist.topology import negative_hysteresis

            problem = negative_hysteresis(scope.models[fold(name)])
        if problem:
            warnings.warn(f"{line.file}:{line.number}: {problem}", NetlistWarning, stacklevel=4)

    def param(self, line: Line, rest: str, base_dir: Path) -> None:
        pairs = split_assignments(line, rest)
        scope = self.scopes[-1]
        for name, value in pairs.items():
            scope.params[name] = value
            if len(self.scopes) == 1:
                self.learn(name, value)

    def learn(self, name: str, value: Value) -> None:
        """Keep the evaluated global params, for .tran/.ac values given as expressions."""
        try:
            self.known[name] = (
                value if isinstance(value, float) else evaluate(value.text, self.known)
            )
        except ValueError:
            self.known.pop(name, None)

    def number(self, c: Cursor, what: str) -> float:
        value = c.value(what)
        if isinstance(value, Expression):
            try:
                return evaluate(value.text, self.known)
            except ValueError as exc:
                raise c.error(f"cannot evaluate {what}: {exc}") from None
        return value

    def tran(self, line: Line, rest: str, base_dir: Path) -> None:
        self.top_only(line, ".tran")
        c = Cursor(tokenize(line), line, ".tran tstep tstop [tstart [tmax]] [uic]")
        c.pos = 1
        values: list[float] = []
        uic = False
        while not c.at_end():
            token = c.peek()
            assert token is not None
            if token.kind == "word" and fold(token.text) == "uic":
                c.take("uic")
                uic = True
                c.finish()
                break
            if len(values) == 4:
                raise c.error(f"unexpected {token.text!r}")
            values.append(self.number(c, ("tstep", "tstop", "tstart", "tmax")[len(values)]))
        if len(values) < 2:
            raise c.error(f"missing {('tstep', 'tstop')[len(values)]}")
        tstep, tstop = values[:2]
        tstart = values[2] if len(values) > 2 else 0.0
        tmax = values[3] if len(values) > 3 else None
        if tstep <= 0 or tstop <= 0:
            raise c.error("tstep and tstop must be positive")
        if not 0 <= tstart < tstop:
            raise c.error("tstart must be at least 0 and less than tstop")
        if tmax is not None and tmax <= 0:
            raise c.error("tmax must be positive")
        self.circuit.analyses.append(Transient(tstep, tstop, tstart, tmax, uic))

    def op(self, line: Line, rest: str, base_dir: Path) -> None:
        self.top_only(line, ".op")
        if rest.strip():
            raise line.error(f"unexpected {rest.strip()!r} after .op")
        self.circuit.analyses.append(OperatingPoint())

    def ac(self, line: Line, rest: str, base_dir: Path) -> None:
        self.top_only(line, ".ac")
        c = Cursor(tokenize(line), line, ".ac dec|oct|lin points fstart fstop")
        c.pos = 1
        variation = fold(c.word("dec, oct or lin"))
        if variation not in ("dec", "oct", "lin"):
            raise c.error(f"expected dec, oct or lin, found {variation!r}")
        points = self.number(c, "number of points")
        if points != int(points) or points < 1:
            raise c.error(f"number of points must be a positive integer, got {points!r}")
        fstart = self.number(c, "fstart")
        fstop = self.number(c, "fstop")
        c.finish()
        if not 0 < fstart <= fstop:
            raise c.error("frequencies must satisfy 0 < fstart <= fstop")
        self.circuit.analyses.append(AcSweep(variation, int(points), fstart, fstop))

    def ic(self, line: Line, rest: str, base_dir: Path) -> None:
        self.top_only(line, ".ic")
        c = Cursor(tokenize(line), line, ".ic v(node)=value ...")
        c.pos = 1
        if c.at_end():
            raise c.error("missing v(node)=value")
        while not c.at_end():
            v = c.word("v(node)")
            if fold(v) != "v":
                raise c.error(f"expected v(node), found {v!r}")
            c.expect("(", "'(' after v")
            node = c.node("node name")
            c.expect(")", "')' after the node name")
            c.expect("=", "'=' after v(node)")
            self.circuit.initial_conditions[node] = c.value(f"initial voltage of {node}")

    def options(self, line: Line, rest: str, base_dir: Path) -> None:
        self.top_only(line, ".options")
        c = Cursor(tokenize(line), line, ".options name=value ... flag ...")
        c.pos = 1
        while not c.at_end():
            name = fold(c.word("option name"))
            token = c.peek()
            if token is not None and token.kind == "=":
                c.take("=")
                value_token = c.take(f"value of option {name}")
                if value_token.kind == "word" and not looks_numeric(value_token.text):
                    if any(ch.isdigit() and not ch.isascii() for ch in value_token.text):
                        raise c.error(
                            f"option {name}: {value_token.text!r} is not a number (only the "
                            "ASCII digits 0-9 are digits, as in ngspice)"
                        )
                    self.circuit.options[name] = fold(value_token.text)
                else:
                    value = to_value(value_token, line, f"option {name}")
                    if isinstance(value, Expression):
                        # evaluated now when the global .param values allow, as .tran's are
                        # (ngspice evaluates {1e-6*10} for reltol; the engines take numbers)
                        try:
                            value = evaluate(value.text, self.known)
                        except ValueError:
                            pass
                    self.circuit.options[name] = value
            else:
                self.circuit.options[name] = True


_DIRECTIVES = {
    ".title": _Reader.title,
    ".tran": _Reader.tran,
    ".op": _Reader.op,
    ".ac": _Reader.ac,
    ".ic": _Reader.ic,
    ".options": _Reader.options,
    ".option": _Reader.options,
    ".opt": _Reader.options,
    ".param": _Reader.param,
    ".model": _Reader.model,
    ".subckt": _Reader.subckt,
    ".ends": _Reader.end_subckt,
    ".include": _Reader.include,
    ".inc": _Reader.include,
    ".lib": _Reader.lib,
    ".endl": _Reader.endl,
}


def parse_netlist(text: str, source: str = "<string>", base_dir: str | None = None) -> Circuit:
    """Read SPICE netlist text.

    Parameters
    ----------
    text : str
        The whole netlist; its first line is the title.
    source : str
        Name used in error messages and stored as ``Circuit.source``.
    base_dir : str, optional
        Folder for relative ``.include``/``.lib`` paths; default the working directory.

    Returns
    -------
    Circuit

    Raises
    ------
    NetlistError
        With file, 1-based line number, the offending text and what was expected.
    """
    if not isinstance(text, str):
        raise NetlistError(f"netlist text must be str, got {type(text).__name__}", file=source)
    folder = Path(base_dir) if base_dir is not None else Path(os.getcwd())
    title, lines = logical_lines(text, source, has_title=True)
    lines = select_sections(lines, None, None, Path(source))
    circuit = Circuit(title=title, source=source)
    top = _Scope(None, circuit.elements, circuit.models, circuit.subcircuits, circuit.params)
    reader = _Reader(circuit, [top])
    try:
        reader.run(lines, folder)
    except NetlistError as error:
        if error.file not in (None, source) and error.text:
            raise error.without_source_text() from None
        raise
    if len(reader.scopes) > 1:
        opened = reader.scopes[-1].opened
        assert opened is not None
        raise opened.error(f".subckt {reader.scopes[-1].subcircuit.name} has no .ends")
    return circuit


def read_netlist(path: str | os.PathLike[str]) -> Circuit:
    """Read a netlist file; relative includes are looked up next to it. See parse_netlist."""
    file = Path(path)
    text = read_file(None, file, str(path))
    return parse_netlist(text, source=str(path), base_dir=str(file.resolve().parent))
