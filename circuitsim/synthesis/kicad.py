"""An editable KiCad schematic (``.kicad_sch``, KiCad 6 format) of a generated circuit.

Written with kiutils (the optional ``kicad`` extra). The stages are cut as in
:func:`~circuitsim.synthesis.schematic.layout`: each op-amp section with its input chains,
feedback parts and output parts is drawn with real wires, and chain ends that share a net
inside one block are wired together below their row (:func:`_join_blocks`); global labels
(named after the netlist's nodes) remain where a net leaves its block. Reference designators
are the bill of materials' (op-amp sections ``U3A`` are unit A of the TL074 ``U3``; each
package also gets its supply unit E, and a package's unused sections are wired as grounded
followers).

Simulation: KiCad 6's fields (``Spice_Primitive``, ``Spice_Model``, ``Spice_Lib_File``,
``Spice_Node_Sequence``); KiCad 7 and later convert these fields on load. The op-amps, diode
and switch models live in a SPICE library written beside the schematic
(:func:`spice_library_text`), with a 14-pin wrapper per quad package, because KiCad's netlister
emits one subcircuit call per reference (all units of ``U1`` together). The netlist's
voltage-controlled switch is drawn as the panel switch it stands for (``Switch:SW_SPST``) and
simulated as its closed resistance; its control source is not drawn (the BOM: a manual switch
needs no part).
"""

from __future__ import annotations

import math
import os
import re
import uuid
from pathlib import Path

from kiutils.items.common import ColorRGBA, Effects, Font, PageSettings, Position, Property
from kiutils.items.schitems import (
    Connection,
    GlobalLabel,
    HierarchicalSheetInstance,
    Junction,
    NoConnect,
    SchematicSymbol,
    SymbolInstance,
    Text,
)
from kiutils.schematic import Schematic

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
from circuitsim.netlist.writer import write_netlist
from circuitsim.synthesis.blocks import BomEntry
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.kicad_spice import (
    QUAD,
    check_switches,
    kicad_value,
    source_models,
)
from circuitsim.synthesis.kicad_symbols import PINS, TL074_SECTIONS, library_symbol
from circuitsim.synthesis.parts import board_parts
from circuitsim.synthesis.schematic import GROUND, Stage, layout

GRID = 2.54  # mm
ROW = 7.62  # pitch of parallel chains
PAPERS = {"A3": (420, 297), "A2": (594, 420), "A1": (841, 594), "A0": (1189, 841)}  # mm


def _effects(hide: bool = False) -> Effects:
    return Effects(font=Font(height=1.27, width=1.27), hide=hide)


def _uid() -> str:
    return str(uuid.uuid4())


def _pin_nodes(element: Element) -> dict[str, str]:
    """Symbol pin number -> circuit node of a two-terminal part."""
    if isinstance(element, Diode):
        return {"2": element.anode.lower(), "1": element.cathode.lower()}
    return {"1": element.positive.lower(), "2": element.negative.lower()}


def _lib_id(element: Element) -> str:
    if isinstance(element, Resistor):
        return "Device:R"
    if isinstance(element, Capacitor):
        return "Device:C"
    if isinstance(element, Diode):
        return "Device:D"
    if isinstance(element, Switch):
        return "Switch:SW_SPST"
    if isinstance(element, VoltageSource):
        kind = type(element.waveform).__name__.upper() if element.waveform is not None else "DC"
        return f"Simulation_SPICE:V{kind}"
    raise SynthesisError(f"kicad schematic: no symbol for {element.name}")


def pin_point(lib_id: str, unit: int, number: str, x: float, y: float, angle: int):
    """Where pin ``number`` of a symbol placed at (x, y) rotated by ``angle`` lands (mm,
    schematic coordinates, y down)."""
    for u, n, _, px, py in PINS[lib_id]:
        if n == number and u in (0, unit):
            a = math.radians(angle)
            rx = px * math.cos(a) - py * math.sin(a)
            ry = px * math.sin(a) + py * math.cos(a)
            return round(x + rx, 2), round(y - ry, 2)
    raise KeyError(number)


class _Sheet:
    """Symbols, wires and labels collected before they become a kiutils Schematic."""

    def __init__(self, circuit: Circuit, bom: list[BomEntry] | None, library: str) -> None:
        self.circuit = circuit
        self.library = library
        self.designators = {p.part.lower(): p.designator for p in board_parts(circuit, bom or [])}
        self.schematic = Schematic.create_new()
        self.schematic.version = 20211123
        self.schematic.generator = "eeschema"
        self.endpoints: dict[tuple[float, float], int] = {}
        self.power = 0
        self.sources = source_models(circuit)
        # chain ends of the current row: (net, point, label to the left, block, stage id)
        self.pending: list[tuple[str, tuple[float, float], bool, str, int]] = []
        self.outputs = {
            e.connections[-1].lower() for e in circuit.elements if isinstance(e, SubcircuitCall)
        }
        # all units of a package are one subcircuit call in KiCad's netlist: the quad wrapper
        self.opamp_fields = {
            "Spice_Primitive": "X", "Spice_Model": QUAD, "Spice_Netlist_Enabled": "Y",
            "Spice_Lib_File": library, "Spice_Node_Sequence": " ".join(map(str, range(1, 15))),
        }  # fmt: skip

    # --- primitives -----------------------------------------------------------------------
    def wire(self, *points: tuple[float, float]) -> None:
        for p, q in zip(points, points[1:], strict=False):
            if p == q:
                continue
            self.schematic.graphicalItems.append(
                Connection(type="wire", points=[Position(*p), Position(*q)], uuid=_uid())
            )
            for end in (p, q):
                self.endpoints[end] = self.endpoints.get(end, 0) + 1

    def label(self, net: str, at: tuple[float, float], left: bool) -> None:
        if net == GROUND:
            self.ground(at)
            return
        self.schematic.globalLabels.append(GlobalLabel(
            text=net, shape="passive", position=Position(*at, 180 if left else 0),
            effects=_effects(), uuid=_uid(),
            properties=[Property("Intersheet References", "${INTERSHEET_REFS}", 0,
                                 Position(*at, 0), _effects(True))],
        ))  # fmt: skip

    def ground(self, at: tuple[float, float]) -> None:
        self.power += 1
        self.symbol("power:GND", f"#PWR{self.power:03d}", "GND", at, 0)

    def symbol(self, lib_id, reference, value, at, angle, unit=1, fields=None) -> None:
        nickname, entry = lib_id.split(":")
        uid = _uid()
        x, y = at
        power = lib_id == "power:GND"
        turn = 90 if angle in (90, 270) else 0  # fields read left to right on every part
        if lib_id.startswith("Amplifier_Operational"):
            ref_at, value_at = (x + 2.54, y + 5.08), (x + 2.54, y + 7.62)
        elif lib_id.startswith(("Simulation_SPICE", "power")):
            ref_at, value_at = (x + 6.35, y - 1.27), (x + 6.35, y + 1.27)
        elif turn or lib_id in ("Device:D", "Switch:SW_SPST"):
            ref_at, value_at = (x, y - 2.54), (x, y + 2.54)
        else:
            ref_at, value_at = (x + 3.81, y - 1.27), (x + 3.81, y + 1.27)
        properties = [
            Property("Reference", reference, 0, Position(*ref_at, turn),
                     _effects(power)),
            Property("Value", value, 1, Position(*value_at, turn), _effects(power)),
            Property("Footprint", "", 2, Position(*at, 0), _effects(True)),
            Property("Datasheet", "~", 3, Position(*at, 0), _effects(True)),
        ]  # fmt: skip
        for k, (key, text) in enumerate((fields or {}).items(), start=4):
            properties.append(Property(key, text, k, Position(*at, 0),
                                       _effects(True)))  # fmt: skip
        self.schematic.schematicSymbols.append(SchematicSymbol(
            libraryNickname=nickname, entryName=entry, position=Position(*at, angle), unit=unit,
            uuid=uid, properties=properties, pins={}))  # fmt: skip
        self.schematic.symbolInstances.append(
            SymbolInstance(path=f"/{uid}", reference=reference, unit=unit, value=value)
        )
        for _, end in self._pins(lib_id, unit, at, angle):
            self.endpoints[end] = self.endpoints.get(end, 0) + 1

    def _pins(self, lib_id, unit, at, angle):
        return [(n, pin_point(lib_id, unit, n, *at, angle))
                for u, n, *_ in PINS[lib_id] if u in (0, unit)]  # fmt: skip

    # --- parts ----------------------------------------------------------------------------
    def reference(self, element: Element) -> str:
        return self.designators.get(element.name.lower(), element.name)

    def fields(self, element: Element) -> dict[str, str]:
        if isinstance(element, Diode):
            return {"Spice_Primitive": "D", "Spice_Model": element.model.upper(),
                    "Spice_Netlist_Enabled": "Y", "Spice_Node_Sequence": "2 1",
                    "Spice_Lib_File": self.library}  # fmt: skip
        if isinstance(element, Switch):
            return {"Spice_Primitive": "R", "Spice_Model": "1", "Spice_Netlist_Enabled": "Y"}
        if isinstance(element, VoltageSource):
            return {"Spice_Primitive": "V", "Spice_Model": self.sources[element.name.lower()],
                    "Spice_Netlist_Enabled": "Y"}  # fmt: skip
        return {}

    def value(self, element: Element) -> str:
        if isinstance(element, Resistor):
            return kicad_value(float(element.resistance), "ohm")
        if isinstance(element, Capacitor):
            return kicad_value(float(element.capacitance), "F")
        if isinstance(element, Diode):
            return "1N4148" if element.model.upper() == "D1N4148" else element.model.upper()
        if isinstance(element, Switch):
            return "SW_SPST"
        model = self.sources[element.name.lower()]
        return model if len(model) <= 24 else model.split("(")[0] + "(...)"

    def two(self, element: Element, left_node: str, left: tuple[float, float]) -> tuple:
        """Place ``element`` horizontally with ``left_node`` on its left pin at ``left``;
        returns its right pin's point."""
        lib_id = _lib_id(element)
        nodes = _pin_nodes(element)
        for angle in (0, 90, 180, 270):
            pins = dict(self._pins(lib_id, 1, (0.0, 0.0), angle))
            (n1, p1), (n2, p2) = pins.items()
            if p1[1] != p2[1]:
                continue
            west = n1 if p1[0] < p2[0] else n2
            if nodes[west] == left_node or nodes[n1] == nodes[n2]:
                span = abs(p1[0] - p2[0])
                at = (round(left[0] + span / 2, 2), left[1])
                self.symbol(lib_id, self.reference(element), self.value(element), at, angle,
                            fields=self.fields(element))  # fmt: skip
                return round(left[0] + span, 2), left[1]
        raise SynthesisError(f"kicad schematic: cannot orient {element.name}")  # pragma: no cover


def _span(element: Element) -> float:
    return 10.16 if isinstance(element, Switch) else 7.62


def _lead(sheet: _Sheet, element: Element) -> float:
    """The wire before a part in a chain: long enough that its reference fits (mm)."""
    text = max(len(sheet.reference(element)), len(sheet.value(element))) * 1.1
    return max(GRID, _snap(text - _span(element) + GRID))


def _chain_width(sheet: _Sheet, chain: list[Element], net: str) -> float:
    return sum(_span(e) + _lead(sheet, e) for e in chain) + GRID + 1.27 * len(net) + 5.08


def _snap(x: float) -> float:
    return round(round(x / GRID) * GRID, 2)


def _draw_stage(sheet: _Sheet, s: Stage, x0: float, oy: float) -> tuple[float, float]:
    """One op-amp section with its parts; returns (right edge, lowest y)."""
    width_in = max([_chain_width(sheet, c, n) for c, n in s.inputs] or [5.08])
    xj = _snap(x0 + width_in)
    ox, xo = xj + 12.7, xj + 25.4
    package, section = _section(sheet, s.opamp)
    plus, minus, out = TL074_SECTIONS[section]
    unit = "ABCD".index(section) + 1
    sheet.symbol("Amplifier_Operational:TL074", package, "TL074", (ox, oy), 0, unit,
                 fields=sheet.opamp_fields)  # fmt: skip
    lib = "Amplifier_Operational:TL074"
    pm = pin_point(lib, unit, minus, ox, oy, 0)
    pp = pin_point(lib, unit, plus, ox, oy, 0)
    po = pin_point(lib, unit, out, ox, oy, 0)
    top = oy - ROW * len(s.feedback)
    sheet.wire(pm, (xj, pm[1]))
    sheet.wire(po, (xo, po[1]))
    sheet.wire(pp, (pp[0] - GRID, pp[1]))
    sheet.label(s.plus, (pp[0] - GRID, pp[1]), left=True)
    # feedback above, each row from the junction column to the output column
    previous_j, previous_o = (xj, pm[1]), (xo, po[1])
    for k, element in enumerate(s.feedback):
        y = oy - ROW * (k + 1)
        sheet.wire(previous_j, (xj, y))
        sheet.wire(previous_o, (xo, y))
        left = (_snap(ox - _span(element) / 2), y)
        sheet.wire((xj, y), left)
        right = sheet.two(element, s.junction, left)
        sheet.wire(right, (xo, y))
        previous_j, previous_o = (xj, y), (xo, y)
    # inputs below the junction, from it to the left
    y_in = pm[1]
    previous = (xj, y_in)
    for k, (chain, net) in enumerate(s.inputs):
        y = y_in + ROW * k
        sheet.wire(previous, (xj, y))
        previous = (xj, y)
        x, node = xj, s.junction
        for element in chain:
            start = (round(x - _lead(sheet, element), 2), y)
            sheet.wire((x, y), start)
            nodes = _pin_nodes(element)
            far = next((n for n in nodes.values() if n != node), node)
            left = (round(start[0] - _span(element), 2), y)
            sheet.two(element, far, left)
            x, node = left[0], far
        sheet.wire((x, y), (x - GRID, y))
        sheet.pending.append((net, (x - GRID, y), True, _block(s), id(s)))
    # the output node's label, then the parts hanging on the output, to the right
    sheet.wire((xo, po[1]), (xo + GRID, po[1]))
    sheet.label(s.output, (xo + GRID, po[1]), left=False)
    right_edge = xo + GRID + 1.27 * len(s.output) + 5.08
    previous = (xo, po[1])
    low = y_in + ROW * max(len(s.inputs) - 1, 0)
    for k, (chain, net) in enumerate(s.outputs):
        y = po[1] + ROW * (k + 1)
        sheet.wire(previous, (xo, y))
        previous = (xo, y)
        x, node = xo, s.output
        for element in chain:
            lead = round(x + _lead(sheet, element), 2)
            sheet.wire((x, y), (lead, y))
            right = sheet.two(element, node, (lead, y))
            node = next((n for n in _pin_nodes(element).values() if n != node), node)
            x = right[0]
        sheet.wire((x, y), (x + GRID, y))
        sheet.pending.append((net, (x + GRID, y), False, _block(s), id(s)))
        right_edge = max(right_edge, x + GRID + 1.27 * len(net) + 5.08)
        low = max(low, y)
    del top
    return right_edge, low


def _block(s: Stage) -> str:
    """The block a stage belongs to: its op-amp's name without the section letter (the two
    stages of a precision rectifier ``XFLANGE_ABS1A``/``B`` are one block)."""
    return re.sub(r"[A-D]$", "", s.opamp.name.upper())


def _join_blocks(sheet: _Sheet, stages: list[Stage], low: float) -> float:
    """Wire the row's chain ends that share a net inside one block along a line below the row,
    label the others (and a wired net that also leaves the block); returns the row's new
    bottom (mm)."""
    members: dict[str, set[int]] = {}
    for s in stages:
        chains = [e for c, _ in s.inputs + s.outputs for e in c]
        members.setdefault(_block(s), set()).update(id(e) for e in [s.opamp, *s.feedback, *chains])
    # each side of a stage drops its wires beyond its outermost chain end, one lane each
    edge: dict[tuple[int, bool], float] = {}
    for _, point, left, _, stage in sheet.pending:
        key = (stage, left)
        edge[key] = min(edge.get(key, point[0]), point[0]) if left else max(
            edge.get(key, point[0]), point[0])  # fmt: skip
    groups: dict[tuple[str, str], list[tuple[tuple[float, float], bool, int]]] = {}
    for net, point, left, block, stage in sheet.pending:
        groups.setdefault((block, net), []).append((point, left, stage))
    sheet.pending.clear()
    lanes: dict[tuple[int, bool], int] = {}
    bus = _snap(low + ROW)
    for (block, net), ends in groups.items():
        if len(ends) < 2 or net == GROUND:
            for point, left, _ in ends:
                sheet.label(net, point, left)
            continue
        drops = []
        for point, left, stage in ends:
            lane = lanes[(stage, left)] = lanes.get((stage, left), 0) + 1
            x = edge[(stage, left)] + (-GRID if left else GRID) * lane
            sheet.wire(point, (x, point[1]), (x, bus))
            drops.append(x)
        sheet.wire(*[(x, bus) for x in sorted(drops)])
        # an op-amp's output keeps its label there, so the wired ends carry one too
        outside = net in sheet.outputs or any(
            id(e) not in members[block] and net in (n.lower() for n in e.nodes)
            for e in sheet.circuit.elements
        )
        if outside:
            right = max(drops)
            sheet.wire((right, bus), (right + GRID, bus))
            sheet.label(net, (right + GRID, bus), left=False)
        bus = _snap(bus + 2 * GRID)
    return bus


def _section(sheet: _Sheet, opamp: SubcircuitCall) -> tuple[str, str]:
    designator = sheet.designators.get(opamp.name.lower(), opamp.name)
    match = re.fullmatch(r"(U\d+)([A-D])", designator.upper())
    if match is None:
        raise SynthesisError(f"kicad schematic: op-amp {opamp.name} has no section designator")
    return match.group(1), match.group(2)


def kicad_schematic_text(
    circuit: Circuit,
    states: list[str] | None = None,
    bom: list[BomEntry] | None = None,
    library: str = "circuit.spice.lib",
) -> str:
    """The ``.kicad_sch`` text of ``circuit`` (see the module's docstring).

    Parameters
    ----------
    circuit : Circuit
        A translator's circuit.
    states : list of str, optional
        State names: one row of stages per state, as in the schemdraw drawing.
    bom : list of BomEntry, optional
        The translator's records (designators of the bill of materials).
    library : str
        File name of the SPICE library (:func:`spice_library_text`) beside the schematic.

    The circuit's ``.ic`` and ``.tran`` lines are placed on the sheet as simulation directives,
    so KiCad's simulator runs what the netlist runs.
    """
    sheet = _Sheet(circuit, bom, library)
    for lib_id in PINS:
        sheet.schematic.libSymbols.append(library_symbol(lib_id))
    check_switches(circuit)
    plan = layout(circuit, states)
    y = 30.48
    used: dict[str, set[str]] = {}
    supplies: dict[str, tuple[str, ...]] = {}
    for _, stages in plan.rows:
        oy = _snap(y + ROW * max(len(s.feedback) for s in stages) + 5.08)
        x, low = 20.32, oy
        for s in stages:
            right, bottom = _draw_stage(sheet, s, x, oy)
            package, section = _section(sheet, s.opamp)
            used.setdefault(package, set()).add(section)
            supplies[package] = tuple(n.lower() for n in s.opamp.connections[2:-1])
            x, low = _snap(right + 7.62), max(low, bottom)
        low = _join_blocks(sheet, stages, low)
        y = low + 12.7
    # the packages' supply units and their unused sections
    y = _snap(y + 10.16)
    x = 25.4
    for package in sorted(used, key=lambda u: int(u[1:])):
        lib = "Amplifier_Operational:TL074"
        sheet.symbol(lib, package, "TL074", (x, y), 0, 5, fields=sheet.opamp_fields)
        for number, net in zip(("4", "11"), supplies[package] or (None, None), strict=False):
            p = pin_point(lib, 5, number, x, y, 0)
            q = (p[0], p[1] + (-GRID if number == "4" else GRID))
            if net is None:
                sheet.schematic.noConnects.append(NoConnect(Position(*p), _uid()))
                continue
            sheet.wire(p, q)
            sheet.label(net, q, left=False)
        for section in "ABCD":
            if section in used[package]:
                continue
            x += 25.4
            unit = "ABCD".index(section) + 1
            plus, minus, out = TL074_SECTIONS[section]
            sheet.symbol(lib, package, "TL074", (x, y), 0, unit, fields=sheet.opamp_fields)
            pm, pp, po = (pin_point(lib, unit, n, x, y, 0) for n in (minus, plus, out))
            sheet.wire(pp, (pp[0] - GRID, pp[1]))
            sheet.ground((pp[0] - GRID, pp[1]))
            sheet.wire(po, (po[0] + GRID, po[1]), (po[0] + GRID, pm[1] + 5.08),
                       (pm[0] - GRID, pm[1] + 5.08), (pm[0] - GRID, pm[1]), pm)  # fmt: skip
        x += 30.48
    # the sources, upright, each pin to a label (or ground)
    for element in plan.others:
        if isinstance(element, VoltageSource) and any(
            isinstance(s, Switch) and s.control_positive.lower() == element.positive.lower()
            for s in circuit.elements
        ):
            continue  # a switch's control: the panel switch needs none
        x += 20.32
        lib_id = _lib_id(element)
        sheet.symbol(lib_id, sheet.reference(element), sheet.value(element), (x, y), 0,
                     fields=sheet.fields(element))  # fmt: skip
        for number, node in _pin_nodes(element).items():
            p = pin_point(lib_id, 1, number, x, y, 0)
            q = (p[0], p[1] + (-GRID if number == "1" else GRID))
            sheet.wire(p, q)
            sheet.label(node, q, left=False)
    lines = [line for line in write_netlist(circuit, "ngspice").splitlines()
             if line.lower().startswith((".ic", ".tran"))]  # fmt: skip
    if lines:
        directive = Text(text="\\n".join(lines), position=Position(20.32, 15.24, 0),
                         effects=_effects(), uuid=_uid())  # fmt: skip
        sheet.schematic.texts.append(directive)
    for point, count in sheet.endpoints.items():
        if count >= 3:
            sheet.schematic.junctions.append(Junction(Position(*point), 0, ColorRGBA(), _uid()))
    width = max(p[0] for p in sheet.endpoints) + 30.0
    height = max(p[1] for p in sheet.endpoints) + 40.0
    paper = next((name for name, (w, h) in PAPERS.items() if width <= w and height <= h), "User")
    sheet.schematic.paper = PageSettings(paperSize=paper, width=width, height=height)
    sheet.schematic.sheetInstances = [HierarchicalSheetInstance("/", "1")]
    return sheet.schematic.to_sexpr()


def kicad_library_path(schematic: str | os.PathLike) -> Path:
    """The SPICE library written beside ``FILE.kicad_sch``: ``FILE.spice.lib``."""
    return Path(f"{Path(schematic).with_suffix('')}.spice.lib")


def check_kicad_path(path: str | os.PathLike) -> None:
    """SynthesisError naming ``path`` unless it ends in ``.kicad_sch``."""
    if Path(path).suffix.lower() != ".kicad_sch":
        raise SynthesisError(f"kicad schematic {path}: the file name must end in .kicad_sch")
