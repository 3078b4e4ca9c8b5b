"""A block schematic of a generated circuit, drawn with schemdraw (SVG and PNG).

The drawing follows the circuit, not the model: every op-amp section is a *stage* drawn the way
an analog computer's patch panel is read - the inputs come in from the left into the summing
junction (each a chain of parts: a resistor, a series pair, a switch and its resistor, a fixed
resistor and a potentiometer), the feedback parts (capacitor, resistor, diodes) sit above the
op-amp, and parts that hang on the output (a precision rectifier's through-diode) leave to the
right. Within a row, a net that leaves one stage and enters the next (an integrator's output
into its inverter, a precision rectifier's half-wave into its second stage) is a wire; any
other chain ends at a labelled net (``y_dot``, ``flange_sig``), so no wire crosses another;
nets with the same label are one node. Rows: one per state (its integrator
and inverter, as the paper's Fig. 5 draws U1A..U2D), then the nonlinear blocks, then the
sources (supplies, references, switch controls, generators). Every element of the circuit
appears once, labelled with its name and value (:func:`layout` says where).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from circuitsim.atomic import write_atomic
from circuitsim.netlist.circuit import (
    Capacitor,
    Circuit,
    Diode,
    Element,
    Resistor,
    SubcircuitCall,
    Switch,
    VoltageSource,
)
from circuitsim.synthesis.blocks import BomEntry
from circuitsim.synthesis.bom import engineering
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.parts import _opamp_model, board_parts

#: Formats ``save_schematic`` writes, by suffix.
FORMATS = ("svg", "png")

#: Stages per row at most (a row wider than this is hard to read on a page).
STAGES_PER_ROW = 4

GROUND = "0"


@dataclass
class Stage:
    """One op-amp section and the parts drawn around it.

    Attributes
    ----------
    opamp : SubcircuitCall
    junction, output, plus : str
        Inverting input, output and non-inverting input nodes.
    feedback : list of Element
        Parts between the junction and the output.
    inputs : list of (list of Element, str)
        Chains from the junction outwards, each with the net it ends at.
    outputs : list of (list of Element, str)
        Chains from the output outwards (parts on no junction), each with its end net.
    """

    opamp: SubcircuitCall
    junction: str
    output: str
    plus: str
    feedback: list[Element] = field(default_factory=list)
    inputs: list[tuple[list[Element], str]] = field(default_factory=list)
    outputs: list[tuple[list[Element], str]] = field(default_factory=list)


@dataclass
class Layout:
    """The circuit cut into rows of stages, plus the parts drawn on their own.

    Attributes
    ----------
    rows : list of (str, list of Stage)
        Title and stages of each row, top to bottom.
    others : list of Element
        Sources and anything on no stage, drawn in the last row with both nets labelled.
    """

    rows: list[tuple[str, list[Stage]]]
    others: list[Element]

    def elements(self) -> list[Element]:
        """Every element drawn, each once."""
        found: list[Element] = []
        for _, stages in self.rows:
            for s in stages:
                found.append(s.opamp)
                found += s.feedback
                for chain, _ in s.inputs + s.outputs:
                    found += chain
        return found + self.others


def _path(element: Element) -> tuple[str, str] | None:
    """The two nodes current flows between (a switch's contacts), None for others."""
    if isinstance(element, Resistor | Capacitor | VoltageSource):
        return element.positive, element.negative
    if isinstance(element, Diode):
        return element.anode, element.cathode
    if isinstance(element, Switch):
        return element.positive, element.negative
    return None


def layout(circuit: Circuit, states: list[str] | None = None) -> Layout:
    """Cut ``circuit`` into stages and rows (see the module's docstring).

    Parameters
    ----------
    circuit : Circuit
        A translator's circuit (op-amp sections as subcircuit calls of the part library).
    states : list of str, optional
        State names, for one row per state (its integrator's output is ``<state>_neg``, its
        inverter's ``<state>``, node names as :func:`~circuitsim.synthesis.naming.node_name`
        makes them); without them the stages fill rows in netlist order.
    """
    from circuitsim.synthesis.naming import node_name

    stages = [
        Stage(e, e.connections[1].lower(), e.connections[-1].lower(), e.connections[0].lower())
        for e in circuit.elements
        if isinstance(e, SubcircuitCall) and _opamp_model(circuit, e) is not None
    ]
    two = [e for e in circuit.elements if _path(e) is not None]
    degree: dict[str, int] = {}
    for e in two:
        for node in _path(e):
            degree[node.lower()] = degree.get(node.lower(), 0) + 1
    stops = {s.junction for s in stages} | {s.output for s in stages} | {GROUND}
    used: set[int] = set()

    def chain(start: str, first: Element) -> tuple[list[Element], str]:
        parts, node, element = [], start, first
        while True:
            parts.append(element)
            used.add(id(element))
            a, b = (n.lower() for n in _path(element))
            node = b if a == node else a
            if node in stops or degree.get(node, 0) != 2:
                return parts, node
            following = [e for e in two if id(e) not in used and node in _lowered(e)]
            if len(following) != 1 or isinstance(following[0], VoltageSource):
                return parts, node
            element = following[0]

    for s in stages:
        for e in two:
            if id(e) not in used and set(_lowered(e)) == {s.junction, s.output}:
                s.feedback.append(e)
                used.add(id(e))
    for s in stages:
        for e in two:
            if id(e) not in used and s.junction in _lowered(e) and not isinstance(e, VoltageSource):
                s.inputs.append(chain(s.junction, e))
    for s in stages:
        for e in two:
            if id(e) not in used and s.output in _lowered(e) and not isinstance(e, VoltageSource):
                s.outputs.append(chain(s.output, e))
    others = [e for e in circuit.elements if id(e) not in used and e not in
              [s.opamp for s in stages]]  # fmt: skip
    rows: list[tuple[str, list[Stage]]] = []
    placed: set[int] = set()
    for state in states or []:
        node = node_name(state)
        row = [s for s in stages if s.output in (node + "_neg", node) and id(s) not in placed]
        if not row:
            continue
        placed.update(id(s) for s in row)
        title, last = rows[-1] if rows else ("", [])
        if rows and title.startswith("state") and len(last) + len(row) <= STAGES_PER_ROW:
            rows[-1] = (title.replace("state ", "states ", 1) + f", {state}", last + row)
        else:
            rows.append((f"state {state}", row))
    rest = [s for s in stages if id(s) not in placed]
    groups: dict[str, list[Stage]] = {}
    for s in rest:
        groups.setdefault(re.sub(r"[A-D]$", "", s.opamp.name.upper()), []).append(s)
    current: list[Stage] = []
    for group in groups.values():
        if current and len(current) + len(group) > STAGES_PER_ROW:
            rows.append(("blocks", current))
            current = []
        current += group
    if current:
        rows.append(("blocks", current))
    return Layout(rows, others)


def _lowered(element: Element) -> tuple[str, str]:
    a, b = _path(element)
    return a.lower(), b.lower()


# --- drawing ---------------------------------------------------------------------------------

DY = 1.4  # vertical pitch of chains (drawing units)
L = 2.6  # length of one part in a chain
CHAR = 0.16  # width of one label character at the font size used


class _Records(dict):
    """The translator's BOM records by part name (lower case), with the bill of materials'
    reference designators (``XFLANGE_ABS1A`` -> ``U3A``) in ``designators``."""

    def __init__(self, circuit: Circuit, bom: list[BomEntry] | None) -> None:
        super().__init__((e.part.lower(), e) for e in bom or [])
        self.designators = {p.part.lower(): p.designator for p in board_parts(circuit, bom or [])}


def _designator(element: Element, records: dict) -> str:
    return getattr(records, "designators", {}).get(element.name.lower(), element.name)


def _value_text(element: Element, records: dict[str, BomEntry]) -> str:
    """``R31A 102 kΩ`` style label: the BOM's designator and the value as a shop writes it."""
    name = _designator(element, records)
    record = records.get(element.name.lower())
    if record is not None and not math.isnan(record.nominal):
        return f"{name} {_short(record.nominal, 'ohm')} pot"
    if isinstance(element, Resistor):
        return f"{name} {_short(element.resistance, 'ohm')}"
    if isinstance(element, Capacitor):
        return f"{name} {_short(element.capacitance, 'F')}"
    if isinstance(element, Diode):
        return f"{name} {element.model.upper()}"
    if isinstance(element, Switch):
        return f"{name} (ctl {element.control_positive})"
    if isinstance(element, VoltageSource):
        wave = element.waveform
        if wave is not None:
            kind = type(wave).__name__.upper()
            if kind == "SIN":
                return f"{name} SIN {_short(wave.amplitude, 'V')} {_short(wave.frequency, 'Hz')}"
            return f"{name} {kind}"
        return f"{name} {float(element.dc):g} V"
    return name


def _short(value, unit: str) -> str:
    """One unit style on every label: ``30.1 kΩ``, ``205 Ω``, ``100 nF``, ``1 µF``."""
    try:
        text = engineering(float(value), unit)
    except (TypeError, ValueError):
        return str(value)
    return text.replace("Ohm", "Ω").replace(" u", " µ")


def _symbol(elm, element: Element, records: dict[str, BomEntry]):
    """The schemdraw element for ``element``, not yet placed."""
    record = records.get(element.name.lower())
    if record is not None and not math.isnan(record.nominal):
        return elm.ResistorVar()
    if isinstance(element, Resistor):
        return elm.Resistor()
    if isinstance(element, Capacitor):
        return elm.Capacitor()
    if isinstance(element, Diode):
        return elm.Diode()
    if isinstance(element, Switch):
        return elm.Switch()
    if isinstance(element, VoltageSource):
        return elm.SourceSin() if element.waveform is not None else elm.SourceV()
    return elm.Resistor()


def _net(d, elm, at, name, side):
    """An open dot labelled with the net's name on ``side`` (left or right)."""
    d.add(elm.Dot(open=True).at(at).label(name, loc=side, fontsize=8, color="#1f4e9e"))


def _chain_width(chain: list[Element], net: str) -> float:
    return len(chain) * L + 0.4 + CHAR * len(net)


def _oriented(chain: list[Element], start: str) -> list[tuple[Element, bool]]:
    """Each part of a chain with whether its path runs against the drawing direction."""
    out, node = [], start
    for e in chain:
        a, b = _lowered(e)
        out.append((e, a != node))
        node = b if a == node else a
    return out


def _wire(d, elm, start, end) -> None:
    """A wire from the previous stage's net at ``start`` (where it ends, and the x of the gap
    between the stages) to an input chain's end at ``end``: right into the gap, then up or
    down, then right."""
    x_net, y_start, x_turn = start
    d.add(elm.Line().at((x_net, y_start)).to((x_turn, y_start)))
    start = (x_turn, y_start)
    d.add(elm.Line().at(start).to((x_turn, end[1])))
    d.add(elm.Line().at((x_turn, end[1])).to(end))


def _leave(d, elm, at, name, wired: bool) -> float:
    """Where a stage's output net ends: a labelled open dot, or (wired on to the next stage) a
    junction dot named below the wire (above it sit the parts' labels). Returns the right edge
    of what was drawn."""
    if not wired:
        _net(d, elm, at, name, "right")
        return at[0] + 0.2 + CHAR * len(name)
    d.add(elm.Dot().at(at).label(name, loc="bottom", halign="left", ofst=(0.1, -0.05),
                                 fontsize=8, color="#1f4e9e"))  # fmt: skip
    return at[0] + 0.1 + CHAR * len(name)


def _draw_stage(
    d,
    elm,
    s: Stage,
    x0: float,
    y0: float,
    records,
    arriving: dict | None = None,
    onward: set[str] = frozenset(),
) -> tuple[float, float, dict]:
    """Draw one stage with its input area's left edge at ``x0`` and the junction at ``y0``.

    ``arriving`` maps the nets the stage drawn just left of this one leaves on (its output and
    its output chains' ends) to where they end: an input chain ending at one of them is wired
    to it (a block's stages joined by wires, as a precision rectifier is drawn) instead of
    labelled. ``onward``: the next stage's input nets (those of this stage's nets are drawn to
    be wired on). Returns the stage's right edge, its bottom and its own leaving nets.
    """
    arriving = arriving or {}
    width_in = max([_chain_width(c, n) for c, n in s.inputs] or [1.0])
    xj = x0 + width_in
    for k, (chain, net) in enumerate(s.inputs):
        y = y0 - k * DY
        x = xj
        for element, reverse in _oriented(chain, s.junction):
            _draw_part(d, elm, element, records, (x, y), (x - L, y), reverse)
            x -= L
        if net in arriving:
            _wire(d, elm, arriving[net], (x, y))
        else:
            _net(d, elm, (x, y), net, "left")
    bottom_in = y0 - max(len(s.inputs) - 1, 0) * DY
    opamp = elm.Opamp(leads=True).right().anchor("in1").at((xj + 0.8, y0)).scale(0.8)
    name = _designator(s.opamp, records)
    d.add(opamp.label(name, loc="center", ofst=(-0.35, 0), fontsize=8))
    _pin_numbers(d, elm, opamp, s, name)
    d.add(elm.Line().at((xj, y0)).to(opamp.in1))
    if s.plus == GROUND:
        d.add(elm.Line().at(opamp.in2).left(0.3))
        d.add(elm.Ground().scale(0.6))
    else:
        d.add(elm.Line().at(opamp.in2).left(0.3))
        _net(d, elm, d.here, s.plus, "left")
    xo = opamp.out[0] + 0.5
    d.add(elm.Line().at(opamp.out).to((xo, opamp.out[1])))
    top = y0
    for k, element in enumerate(s.feedback):
        y = y0 + 1.3 + k * DY
        d.add(elm.Line().at((xj, top)).to((xj, y)))
        d.add(elm.Line().at((xo, y)).to((xo, max(opamp.out[1], y - DY if k else opamp.out[1]))))
        reverse = _lowered(element)[0] != s.junction
        _draw_part(d, elm, element, records, (xj, y), (xo, y), reverse)
        top = y
    if s.inputs:
        d.add(elm.Line().at((xj, y0)).to((xj, bottom_in)))
    d.add(elm.Dot().at((xj, y0)))
    right = _leave(d, elm, (xo + 0.3, opamp.out[1]), s.output, s.output in onward) + 0.3
    d.add(elm.Line().at((xo, opamp.out[1])).to((xo + 0.3, opamp.out[1])))
    leaving = {s.output: (xo + 0.3, opamp.out[1])}
    y = opamp.out[1]
    for chain, net in s.outputs:
        y -= DY
        d.add(elm.Line().at((xo, y + DY)).to((xo, y)))
        x = xo
        for element, reverse in _oriented(chain, s.output):
            _draw_part(d, elm, element, records, (x, y), (x + L, y), reverse)
            x += L
        right = max(right, _leave(d, elm, (x, y), net, net in onward) + 0.3)
        leaving[net] = (x, y)
    # a wire on to the next stage turns in the gap between the stages
    leaving = {net: (end, y_net, right + 0.4) for net, (end, y_net) in leaving.items()}
    return right, min(bottom_in, y, y0 - 1.6), leaving


#: TL074 pin numbers of a section: (inverting input, non-inverting input, output).
TL074_PINS = {"A": ("2", "3", "1"), "B": ("6", "5", "7"), "C": ("9", "10", "8"),
              "D": ("13", "12", "14")}  # fmt: skip


def _pin_numbers(d, elm, opamp, s: Stage, name: str) -> None:
    """The quad package's pin numbers at a section's leads and its supply pins (V+ pin 4,
    V- pin 11, with their nets where the model has supply pins)."""
    match = re.fullmatch(r"U\d+([A-D])", name.upper())
    if match is None:
        return
    minus, plus, out = TL074_PINS[match.group(1)]
    small = {"fontsize": 6, "color": "#8a1c1c"}
    d.add(elm.Label().at((opamp.in1[0] + 0.15, opamp.in1[1] + 0.18)).label(minus, **small))
    d.add(elm.Label().at((opamp.in2[0] + 0.15, opamp.in2[1] - 0.18)).label(plus, **small))
    d.add(elm.Label().at((opamp.out[0] - 0.15, opamp.out[1] + 0.18)).label(out, **small))
    supplies = [n.lower() for n in s.opamp.connections[2:-1]] or ["", ""]
    d.add(elm.Line().at(opamp.vd).up(0.3))
    d.add(elm.Label().at((opamp.vd[0] + 0.1, opamp.vd[1] + 0.3))
          .label(f"4 {supplies[0]}".strip(), loc="right", **small))  # fmt: skip
    d.add(elm.Line().at(opamp.vs).down(0.3))
    d.add(elm.Label().at((opamp.vs[0] + 0.1, opamp.vs[1] - 0.3))
          .label(f"11 {supplies[-1]}".strip(), loc="right", **small))  # fmt: skip


def _draw_part(d, elm, element, records, start, end, reverse: bool) -> None:
    """One part from ``start`` to ``end``; a diode points anode -> cathode along its path."""
    dx, dy = end[0] - start[0], end[1] - start[1]
    # a direction and a length: .to() can flip a source's ends
    symbol = _symbol(elm, element, records).at(start).theta(math.degrees(math.atan2(dy, dx)))
    symbol = symbol.length(math.hypot(dx, dy))
    if isinstance(element, Diode) and reverse:
        symbol = symbol.reverse()
    d.add(symbol.label(_value_text(element, records), loc="top", fontsize=8))


def draw(
    circuit: Circuit,
    states: list[str] | None = None,
    bom: list[BomEntry] | None = None,
    title: str | None = None,
    canvas: str = "svg",
):
    """The schemdraw Drawing of ``circuit`` (see :func:`layout`).

    Parameters
    ----------
    circuit : Circuit
    states : list of str, optional
        State names: one row per state.
    bom : list of BomEntry, optional
        The translator's records: potentiometers are drawn as variable resistors.
    title : str, optional
        Drawn above the first row (default: the circuit's title).
    canvas : str
        ``"svg"`` (text stays text) or ``"matplotlib"`` (for PNG).
    """
    import schemdraw
    import schemdraw.elements as elm

    records = _Records(circuit, bom)
    plan = layout(circuit, states)
    d = schemdraw.Drawing(canvas=canvas, show=False)
    d.config(unit=2.0, fontsize=8, lw=1.0)
    y = 0.0
    heading = title or (circuit.title or "circuit").lstrip("* ")
    d.add(elm.Label().at((0, y + 1.5)).label(heading,
                                                 loc="right", fontsize=11))  # fmt: skip
    for row_title, stages in plan.rows:
        d.add(elm.Label().at((0, y + 0.6)).label(row_title, loc="right", fontsize=9,
                                                 color="#7a4b00"))  # fmt: skip
        top = max(1.3 + (len(s.feedback) - 1) * DY for s in stages)
        y -= top + 0.6
        x, bottom, leaving = 0.0, y, {}
        for k, s in enumerate(stages):
            onward = {net for _, net in stages[k + 1].inputs} if k + 1 < len(stages) else set()
            right, low, leaving = _draw_stage(d, elm, s, x, y, records, leaving, onward)
            x, bottom = right + 0.8, min(bottom, low)
        y = bottom - 1.8
    if plan.others:
        d.add(elm.Label().at((0, y + 0.6)).label("sources", loc="right", fontsize=9,
                                                 color="#7a4b00"))  # fmt: skip
        y -= 1.0
        x = 0.0
        for element in plan.others:
            a, b = _path(element) if _path(element) else (element.nodes[0], element.nodes[-1])
            label = CHAR * len(_value_text(element, records))  # drawn left of the symbol
            x += label
            width = max(1.5, CHAR * max(len(a), len(b)) + 0.6)
            if x + width > 40.0:
                x, y = label, y - 4.0
            _net(d, elm, (x, y), a, "right")
            # drawn upwards: a source's + (its positive node) is at the end
            _draw_part(d, elm, element, records, (x, y - 2.0), (x, y), False)
            if b.lower() == GROUND:
                d.add(elm.Ground().at((x, y - 2.0)).scale(0.6))
            else:
                _net(d, elm, (x, y - 2.0), b, "right")
            x += width + 1.6
    return d


def schematic_image(
    circuit: Circuit,
    fmt: str,
    states: list[str] | None = None,
    bom: list[BomEntry] | None = None,
    title: str | None = None,
) -> bytes:
    """The schematic as ``fmt`` (``svg`` or ``png``) bytes."""
    if fmt not in FORMATS:
        raise SynthesisError(f"cannot draw a schematic as .{fmt}; use .svg or .png")
    d = draw(circuit, states, bom, title, canvas="svg" if fmt == "svg" else "matplotlib")
    if fmt == "svg":
        data = d.get_imagedata("svg")
        return data if isinstance(data, bytes) else data.encode()
    try:
        return d.get_imagedata("png")
    finally:
        figure = getattr(getattr(d, "fig", None), "fig", None)
        if figure is not None:
            import matplotlib.pyplot as plt

            plt.close(figure)


def schematic_format(path: str | os.PathLike) -> str:
    """The format ``path``'s suffix names; SynthesisError naming the file if none fits."""
    suffix = Path(path).suffix.lstrip(".").lower()
    if suffix not in FORMATS:
        raise SynthesisError(
            f"schematic {path}: cannot draw a .{suffix or '(no suffix)'} file; "
            "use a .svg or .png suffix"
        )
    return suffix


def save_schematic(
    circuit: Circuit,
    path: str | os.PathLike,
    states: list[str] | None = None,
    bom: list[BomEntry] | None = None,
    title: str | None = None,
) -> None:
    """Draw ``circuit`` and write it to ``path`` atomically (format from the suffix)."""
    data = schematic_image(circuit, schematic_format(path), states, bom, title)
    write_atomic(path, lambda handle: handle.write(data), binary=True)
