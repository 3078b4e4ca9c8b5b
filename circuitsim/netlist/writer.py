"""Circuit -> SPICE text, in the ngspice, LTspice or Multisim dialect.

The writer is the reader's inverse: ``parse_netlist(write_netlist(c))`` has the same meaning as
``c``, values bit for bit (numbers are written with the shortest text that reads back to the
same float). Lines are broken onto ``+`` continuation lines before ``dialect.width``
characters; a token (a number, ``{expression}``) is never split.

Order of the output: title (a ``*`` comment line, see :func:`title_line`), notes
(``* circuitsim: ...`` comments about what a dialect could not take), ``.param``, ``.model``,
``.subckt`` definitions, elements, ``.ic``, ``.options`` (with the dialect's own, such as
LTspice's ``plotwinsize=0``), ``.print tran`` of the outputs asked for (ngspice), analyses,
``.save`` of the outputs, ``.control`` blocks (ngspice only), ``.end``. The mega suffix is
written ``Meg`` (spicelib reads ``meg`` as milli).
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from collections.abc import Iterator, Sequence

from circuitsim.atomic import write_text_atomic
from circuitsim.netlist.circuit import (
    AcSweep,
    Bjt,
    Capacitor,
    Cccs,
    Ccvs,
    Circuit,
    CurrentSource,
    Diode,
    Element,
    Expression,
    Inductor,
    Jfet,
    Model,
    OperatingPoint,
    PolyCccs,
    PolyCcvs,
    PolyCurrentControlled,
    PolyVccs,
    PolyVcvs,
    PolyVoltageControlled,
    Pulse,
    Pwl,
    Resistor,
    Sin,
    Subcircuit,
    SubcircuitCall,
    Switch,
    Transient,
    Value,
    Vccs,
    Vcvs,
    VoltageSource,
    Waveform,
)
from circuitsim.netlist.dialects import (
    Dialect,
    get_dialect,
    model_param_name,
    rewrite_expression,
)
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.expressions import evaluate
from circuitsim.netlist.names import fold
from circuitsim.netlist.values import format_value

NOTE = "* circuitsim: "


def write_netlist(
    circuit: Circuit,
    dialect: str = "ngspice",
    outputs: Sequence[str] = (),
    drop_implied_ic: bool = False,
    fold_subcircuit_defaults: bool = False,
) -> str:
    """The SPICE text of ``circuit`` in ``dialect`` (``ngspice``, ``ltspice``, ``multisim``).

    Parameters
    ----------
    circuit : Circuit
        What to write.
    dialect : str
        ``ngspice``, ``ltspice`` or ``multisim``.
    outputs : sequence of str
        Top-level nodes whose voltages a batch run should save: written as ``.save v(node)
        ...`` after the analyses and, where the dialect needs it for batch output (ngspice:
        ``ngspice -b FILE`` runs nothing without it; gnucap reads it too), ``.print tran
        v(node) ...`` before them. Our reader passes over both lines (with a NetlistWarning
        each), so they are not part of the Circuit read back.
    drop_implied_ic : bool
        Leave out a top-level capacitor's ``IC=`` where the ``.ic`` line already says it: the
        ``.tran`` has ``uic`` and the ``IC=`` value equals ``.ic``'s voltage of its first node
        minus that of its second (0 V for ground or a node ``.ic`` leaves out, as ``uic``
        starts every such node at 0 V). SPICE then starts the capacitor at the same voltage
        (ngspice's manual: with ``uic``, the ``.ic`` voltages give the device initial
        conditions, "equivalent to specifying the IC= parameter on each device line"), and
        tools that refuse a capacitor's ``IC=`` (PySpice 1.5) read the netlist.
    fold_subcircuit_defaults : bool
        Write a top-level ``.subckt`` whose parameters no instance sets with its defaults
        folded in: each ``{expression}`` of its body evaluated with the global ``.param``
        values and its defaults, and no ``params:`` (a subcircuit with nested definitions, or
        an expression that does not evaluate, is written as it is). Every instance then gets
        the values its defaults gave; tools that drop a ``.subckt`` line's parameters
        (PySpice 1.5's parser: "Undefined parameter [gain]" in ngspice) run it.

    Raises
    ------
    NetlistError
        Unknown dialect, an output that is not a node of the circuit, or a value no SPICE can
        read (NaN, an infinite value other than a one-shot pulse's width).
    """
    writer = _Writer(circuit, get_dialect(dialect))
    writer.outputs = list(outputs)
    writer.drop_implied_ic = drop_implied_ic
    if fold_subcircuit_defaults:
        writer.folded = _foldable_subcircuits(circuit)
    return writer.text()


def save_netlist(
    circuit: Circuit,
    path: str | os.PathLike,
    dialect: str = "ngspice",
    outputs: Sequence[str] = (),
    drop_implied_ic: bool = False,
    fold_subcircuit_defaults: bool = False,
) -> None:
    """Write ``circuit`` to ``path`` in ``dialect``, atomically (no half-written file); the
    other arguments as :func:`write_netlist`'s."""
    text = write_netlist(circuit, dialect, outputs, drop_implied_ic, fold_subcircuit_defaults)
    write_text_atomic(path, text)


def title_line(title: str) -> str:
    """The first line written for ``title``: a ``*`` comment line.

    Every SPICE takes the first line as the title whatever it holds, but tools that edit
    netlists (spicelib's SpiceEditor) read a bare first line as a component; a comment line
    is a title to both. A title that already starts with ``*`` (one read back from our own
    file) is kept as it is, so writing what was read gives the same text.
    """
    title = " ".join(title.splitlines()).strip()
    return title if title.startswith("*") else f"* {title}".rstrip()


class _Writer:
    """One writing pass: the dialect, the node renames, the lines written so far."""

    def __init__(self, circuit: Circuit, dialect: Dialect):
        self.circuit = circuit
        self.dialect = dialect
        self.notes: list[str] = []
        self.renames = _node_renames(circuit, dialect)
        for old, new in self.renames.items():
            self.notes.append(f"node {old!r} renamed {new!r} ({dialect.name} node names)")
        self.lines: list[str] = []
        self.outputs: list[str] = []
        self.drop_implied_ic = False
        self.top_level = {id(element) for element in circuit.elements}
        self.folded: dict[str, dict[str, float]] = {}  # subcircuit (lower case) -> its values
        self.scope_values: dict[str, float] | None = None  # while writing a folded one

    # --- the whole file ---

    def text(self) -> str:
        circuit = self.circuit
        body: list[str] = []
        self.lines = body
        for name, value in circuit.params.items():
            self.emit([f".param {name}={self.value(value)}"])
        for model in circuit.models.values():
            self.model(model)
        for sub in circuit.subcircuits.values():
            self.subcircuit(sub)
        for element in circuit.elements:
            self.element(element)
        if circuit.initial_conditions:
            self.emit(
                [".ic"]
                + [
                    f"v({self.node(node)})={self.value(value)}"
                    for node, value in circuit.initial_conditions.items()
                ]
            )
        options = [self.option(k, v) for k, v in circuit.options.items()]
        given = {fold(k) for k in circuit.options}
        options += [f"{k}={v}" for k, v in self.dialect.options if fold(k) not in given]
        if any(options):
            self.emit([".options"] + [o for o in options if o])
        vectors = self.output_vectors()
        if vectors and self.dialect.print_card and circuit.transient is not None:
            self.emit([".print", "tran", *vectors])
        for analysis in circuit.analyses:
            self.emit(self.analysis(analysis))
        if vectors:
            # after the analyses: gnucap stops reading a deck at a line it does not know
            # ("? can't find"), and .save is one; ngspice and LTspice read it anywhere
            self.emit([".save", *vectors])
        for block in circuit.control:
            if self.dialect.control_blocks:
                body.extend(_control_lines(block))
            else:
                self.notes.append(f".control block dropped ({self.dialect.name} has none)")
        body.append(".end")
        head = [title_line(circuit.title)] + [NOTE + note for note in self.notes]
        return "\n".join(head + body) + "\n"

    # --- pieces ---

    def output_vectors(self) -> list[str]:
        """``v(node)`` of each output node (renamed as the dialect needs), checked to exist."""
        known = set(_all_nodes(self.circuit)) - {"0"}
        for node in self.outputs:
            if node not in known:
                raise NetlistError(f"cannot save the output {node!r}: no node of the circuit")
        return [f"v({self.node(node)})" for node in self.outputs]

    def implied_by_ic(self, element: Capacitor) -> bool:
        """Whether ``element``'s ``IC=`` says what ``.ic`` and ``uic`` already say."""
        transient = self.circuit.transient
        if not self.drop_implied_ic or transient is None or not transient.uic:
            return False
        if id(element) not in self.top_level:
            return False  # a capacitor inside a subcircuit: .ic names top-level nodes
        ic = self.circuit.initial_conditions
        voltages = [0.0 if node == "0" else ic.get(node, 0.0) for node in element.nodes]
        values = [element.ic, *voltages]
        if any(isinstance(value, Expression) for value in values):
            return False
        return float(element.ic) == float(voltages[0]) - float(voltages[1])

    def emit(self, tokens: list[str]) -> None:
        """Append one logical line, broken onto ``+`` lines before the dialect's width."""
        line = tokens[0]
        for token in tokens[1:]:
            if len(line) + 1 + len(token) > self.dialect.width:
                self.lines.append(line)
                line = "+ " + token
            else:
                line += " " + token
        self.lines.append(line)

    def value(self, value: Value) -> str:
        if isinstance(value, Expression) and self.scope_values is not None:
            value = evaluate(value.text, self.scope_values)  # checked to evaluate beforehand
        if isinstance(value, Expression):
            return "{" + rewrite_expression(value.text, self.dialect) + "}"
        number = float(value)
        if not math.isfinite(number):
            raise NetlistError(f"cannot write the value {number!r}: SPICE has no such number")
        text = format_value(number)
        # Every SPICE reads the suffix in any case, but spicelib's number parser (1.6.4) reads
        # a lower-case "10meg" as 10 milli; "Meg" reads as mega everywhere.
        return text[:-3] + "Meg" if text.endswith("meg") else text

    def node(self, name: str) -> str:
        return self.renames.get(name, name)

    def nodes(self, element: Element) -> list[str]:
        return [self.node(n) for n in element.nodes]

    def option(self, key: str, value: Value | bool | str) -> str:
        if value is True:
            return key
        if value is False:
            # A flag that is off is the same as no flag at all.
            return ""
        if isinstance(value, str):
            return f"{key}={value}"  # a word, such as method=gear
        return f"{key}={self.value(value)}"

    def model(self, model: Model) -> None:
        params = [
            f"{model_param_name(model.kind, key, self.dialect)}={self.value(value)}"
            for key, value in model.params.items()
        ]
        if model.kind.upper() == "SW" and self.dialect.name == "ltspice":
            vh = model.params.get("vh")
            if isinstance(vh, float | int) and vh < 0:
                self.notes.append(
                    f"model {model.name}: LTspice reads a negative Vh as a smooth transition,"
                    " ngspice as reversed hysteresis"
                )
        if not params:
            self.emit([f".model {model.name} {model.kind.upper()}"])
            return
        params[0] = f"{model.kind.upper()}({params[0]}"
        params[-1] += ")"
        self.emit([".model", model.name] + params)

    def subcircuit(self, sub: Subcircuit) -> None:
        header = [".subckt", sub.name] + [self.node(p) for p in sub.ports]
        self.scope_values = self.folded.get(fold(sub.name))
        if sub.params and self.scope_values is None:
            header.append("params:")
            header += [f"{k}={self.value(v)}" for k, v in sub.params.items()]
        self.emit(header)
        for model in sub.models.values():
            self.model(model)
        for inner in sub.subcircuits.values():
            self.subcircuit(inner)
        for element in sub.elements:
            self.element(element)
        self.scope_values = None
        self.lines.append(f".ends {sub.name}")

    def element(self, element: Element) -> None:
        letter = _LETTERS.get(type(element))
        if letter is None or element.letter != letter or not _NAME.fullmatch(element.name):
            raise NetlistError(
                f"cannot write element {element.name!r} ({type(element).__name__}): a SPICE "
                f"name starts with its type letter ({letter}) and has no spaces or ()={{}},;"
            )
        tokens = [element.name, *self.nodes(element)]
        v = self.value
        if isinstance(element, Resistor):
            tokens.append(v(element.resistance))
        elif isinstance(element, Capacitor | Inductor):
            value = element.capacitance if isinstance(element, Capacitor) else element.inductance
            tokens.append(v(value))
            implied = isinstance(element, Capacitor) and self.implied_by_ic(element)
            if element.ic is not None and not implied:
                tokens.append(f"IC={v(element.ic)}")
        elif isinstance(element, VoltageSource | CurrentSource):
            tokens += self.source(element)
        elif isinstance(element, Switch):
            # Switch before Vcvs/Vccs: all three share the four-node base class.
            tokens.append(element.model)
            if element.initial:
                tokens.append(element.initial.upper())
        elif isinstance(element, Vcvs):
            tokens.append(v(element.gain))
        elif isinstance(element, Vccs):
            tokens.append(v(element.transconductance))
        elif isinstance(element, Cccs):
            tokens += [element.control, v(element.gain)]
        elif isinstance(element, Ccvs):
            tokens += [element.control, v(element.transresistance)]
        elif isinstance(element, PolyVoltageControlled | PolyCurrentControlled):
            tokens = [element.name, self.node(element.positive), self.node(element.negative)]
            tokens.append(f"POLY({len(element.controls)})")
            for control in element.controls:
                tokens += (
                    [self.node(c) for c in control] if isinstance(control, tuple) else [control]
                )
            tokens += [v(c) for c in element.coefficients]
        elif isinstance(element, Jfet | Bjt):
            tokens.append(element.model)
            if isinstance(element.area, Expression) or element.area != 1.0:
                tokens.append(v(element.area))
        elif isinstance(element, Diode):
            tokens.append(element.model)
            if isinstance(element.area, Expression) or element.area != 1.0:
                tokens.append(v(element.area))
        elif isinstance(element, SubcircuitCall):
            tokens.append(element.subcircuit)
            if element.params and self.dialect.instance_params_keyword:
                tokens.append("params:")
            tokens += [f"{k}={v(val)}" for k, val in element.params.items()]
        else:
            raise NetlistError(f"{element.name}: cannot write a {type(element).__name__}")
        self.emit(tokens)

    def source(self, source: VoltageSource | CurrentSource) -> list[str]:
        tokens: list[str] = []
        dc = source.dc
        if source.waveform is None or isinstance(dc, Expression) or dc != 0.0:
            tokens += ["DC", self.value(dc)]
        if _nonzero(source.ac_magnitude) or _nonzero(source.ac_phase):
            tokens += ["AC", self.value(source.ac_magnitude)]
            if _nonzero(source.ac_phase):
                tokens.append(self.value(source.ac_phase))
        if source.waveform is not None:
            tokens += self.waveform(source.name, source.waveform)
        return tokens

    def waveform(self, owner: str, shape: Waveform) -> list[str]:
        if isinstance(shape, Sin):
            fields = [shape.offset, shape.amplitude, shape.frequency]
            fields += _trimmed([shape.delay, shape.damping, shape.phase])
            if len(fields) == 6 and self.dialect.name == "multisim":
                self.notes.append(
                    f"{owner}: SIN phase (6th field) is an ngspice/LTspice extension of "
                    "SPICE3's SIN, unverified in Multisim"
                )
            return self.call("SIN", fields)
        if isinstance(shape, Pulse):
            fields = [shape.initial, shape.pulsed, shape.delay, shape.rise, shape.fall]
            width = shape.width
            if shape.period is not None:
                if not isinstance(width, Expression) and math.isinf(width):
                    raise NetlistError(
                        f"{owner}: a PULSE with a period needs a finite width; SPICE cannot "
                        "write an infinite one"
                    )
                fields += [width, shape.period]
            elif isinstance(width, Expression) or not math.isinf(width):
                fields.append(width)
            # An infinite width without a period is SPICE's default (pw = per = tstop: one
            # pulse that lasts to the end of the run), so it is left out.
            return self.call("PULSE", fields)
        if isinstance(shape, Pwl):
            if not shape.points:
                raise NetlistError(f"{owner}: a PWL needs at least one (time, value) point")
            return self.call("PWL", [x for point in shape.points for x in point])
        raise NetlistError(f"{owner}: cannot write the waveform {type(shape).__name__}")

    def call(self, keyword: str, fields: list[Value]) -> list[str]:
        tokens = [self.value(f) for f in fields]
        tokens[0] = f"{keyword}({tokens[0]}"
        tokens[-1] += ")"
        return tokens

    def analysis(self, analysis) -> list[str]:
        v = self.value
        if isinstance(analysis, Transient):
            tokens = [".tran", v(analysis.tstep), v(analysis.tstop)]
            if analysis.tstart != 0.0 or analysis.tmax is not None:
                tokens.append(v(analysis.tstart))
            if analysis.tmax is not None:
                tokens.append(v(analysis.tmax))
            if analysis.uic:
                tokens.append("uic")
            return tokens
        if isinstance(analysis, OperatingPoint):
            return [".op"]
        if isinstance(analysis, AcSweep):
            return [
                ".ac",
                fold(analysis.variation),
                str(int(analysis.points)),
                v(analysis.fstart),
                v(analysis.fstop),
            ]
        raise NetlistError(f"cannot write the analysis {analysis!r}")


_LETTERS: dict[type, str] = {
    Resistor: "R",
    Capacitor: "C",
    Inductor: "L",
    VoltageSource: "V",
    CurrentSource: "I",
    Vcvs: "E",
    Vccs: "G",
    Cccs: "F",
    Ccvs: "H",
    Diode: "D",
    Switch: "S",
    PolyVcvs: "E",
    PolyVccs: "G",
    PolyCccs: "F",
    PolyCcvs: "H",
    Jfet: "J",
    Bjt: "Q",
    SubcircuitCall: "X",
}
_NAME = re.compile(r"[^\s(){}=,;'\"]+")


def _nonzero(value: Value) -> bool:
    return isinstance(value, Expression) or value != 0.0


def _trimmed(fields: list[Value]) -> list[Value]:
    """``fields`` without its trailing zeros (SPICE's defaults for optional waveform fields)."""
    while fields and not _nonzero(fields[-1]):
        fields = fields[:-1]
    return fields


def _control_lines(block: str) -> list[str]:
    """A ``.control`` block as lines, wrapped in ``.control``/``.endc`` unless it already is."""
    lines = block.strip("\n").splitlines()
    first = fold(lines[0].strip()) if lines else ""
    if first.startswith(".control"):
        return lines
    return [".control", *lines, ".endc"]


def _expressions(item: object) -> Iterator[Expression]:
    """Every Expression inside ``item`` (dataclasses, dicts, lists and tuples looked into)."""
    if isinstance(item, Expression):
        yield item
    elif dataclasses.is_dataclass(item) and not isinstance(item, type):
        for spec in dataclasses.fields(item):
            yield from _expressions(getattr(item, spec.name))
    elif isinstance(item, dict):
        for value in item.values():
            yield from _expressions(value)
    elif isinstance(item, list | tuple):
        for value in item:
            yield from _expressions(value)


def _foldable_subcircuits(circuit: Circuit) -> dict[str, dict[str, float]]:
    """Top-level subcircuits (lower-case names) whose defaults can be folded in, each with the
    parameter values its expressions see: the global ``.param`` values, then its defaults."""
    scopes: list[Circuit | Subcircuit] = [circuit]
    calls: list[SubcircuitCall] = []
    while scopes:
        scope = scopes.pop()
        calls += [e for e in scope.elements if isinstance(e, SubcircuitCall)]
        scopes.extend(scope.subcircuits.values())
    overridden = {fold(call.subcircuit) for call in calls if call.params}
    values: dict[str, float] = {}
    try:
        for name, value in circuit.params.items():
            values[fold(name)] = _number(value, values)
    except ValueError:
        return {}
    folded = {}
    for sub in circuit.subcircuits.values():
        if not sub.params or sub.subcircuits or fold(sub.name) in overridden:
            continue
        own = dict(values)
        try:
            for name, value in sub.params.items():
                own[fold(name)] = _number(value, own)
            for expression in _expressions([sub.elements, list(sub.models.values())]):
                evaluate(expression.text, own)
        except ValueError:
            continue
        folded[fold(sub.name)] = own
    return folded


def _number(value: Value, values: dict[str, float]) -> float:
    return evaluate(value.text, values) if isinstance(value, Expression) else float(value)


def _all_nodes(circuit: Circuit) -> set[str]:
    names: set[str] = set(circuit.initial_conditions)
    scopes: list[Circuit | Subcircuit] = [circuit]
    while scopes:
        scope = scopes.pop()
        for element in scope.elements:
            names.update(element.nodes)
        if isinstance(scope, Subcircuit):
            names.update(scope.ports)
        scopes.extend(scope.subcircuits.values())
    return names


def _node_renames(circuit: Circuit, dialect: Dialect) -> dict[str, str]:
    """Nodes whose names ``dialect`` cannot take, mapped to new names no other node has."""
    pattern = re.compile(dialect.node_pattern)
    names = _all_nodes(circuit)
    taken = {fold(n) for n in names}
    renames: dict[str, str] = {}
    for name in sorted(names):
        if pattern.fullmatch(name):
            continue
        base = re.sub(r"[^A-Za-z0-9_]", "_", name) or "n"
        new, count = base, 1
        while fold(new) in taken:
            count += 1
            new = f"{base}_{count}"
        taken.add(fold(new))
        renames[name] = new
    return renames
