"""The KiCad schematic of a generated circuit, read back with kiutils: its nets, derived from
wire end points, pin positions (embedded symbols, placement, rotation) and labels, are the
Circuit's nets, node by node and pin by pin; the references are the bill of materials'."""

import math
from pathlib import Path

import pytest
from kiutils.schematic import Schematic

from circuitsim.mechanics import load_model
from circuitsim.netlist.circuit import (
    Capacitor,
    Diode,
    Resistor,
    SubcircuitCall,
    Switch,
    VoltageSource,
)
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.parts import board_parts

# The TL074 data sheet's pinout: section -> (non-inverting input, inverting input, output).
TL074 = {"A": ("3", "2", "1"), "B": ("5", "6", "7"), "C": ("10", "9", "8"), "D": ("12", "13", "14")}


class _Nets:
    def __init__(self):
        self.parent = {}

    def find(self, x):
        self.parent.setdefault(x, x)
        while self.parent[x] != x:
            self.parent[x] = self.parent[self.parent[x]]
            x = self.parent[x]
        return x

    def union(self, a, b):
        self.parent[self.find(a)] = self.find(b)


def _point(x, y):
    return ("pt", round(x, 2), round(y, 2))


def _read(path: Path):
    """(pins, nets): pins maps (reference, pin number) -> net root; label names by root."""
    sch = Schematic.from_file(str(path))
    library = {s.libId: s for s in sch.libSymbols}
    nets = _Nets()
    pins = {}
    for symbol in sch.schematicSymbols:
        definition = library[symbol.libId]
        reference = next(p.value for p in symbol.properties if p.key == "Reference")
        value = next(p.value for p in symbol.properties if p.key == "Value")
        a = math.radians(symbol.position.angle or 0)
        for unit in definition.units:
            if unit.unitId not in (0, symbol.unit):
                continue
            for pin in unit.pins:
                px, py = pin.position.X, pin.position.Y
                x = symbol.position.X + px * math.cos(a) - py * math.sin(a)
                y = symbol.position.Y - (px * math.sin(a) + py * math.cos(a))
                point = _point(x, y)
                if definition.isPower:
                    nets.union(point, ("net", "0" if value == "GND" else value.lower()))
                else:
                    key = (reference, pin.number)
                    assert key not in pins, f"pin {key} placed twice"
                    pins[key] = point
                    nets.find(point)
    for wire in sch.graphicalItems:
        if getattr(wire, "type", None) == "wire":
            p, q = wire.points
            nets.union(_point(p.X, p.Y), _point(q.X, q.Y))
    for label in sch.globalLabels:
        nets.union(_point(label.position.X, label.position.Y), ("net", label.text.lower()))
    # every wire end must land on a pin, another wire end or a label: no dangling wire, no
    # connection by a T that the check above would miss
    ends = {}
    for wire in sch.graphicalItems:
        if getattr(wire, "type", None) == "wire":
            for p in wire.points:
                ends[_point(p.X, p.Y)] = ends.get(_point(p.X, p.Y), 0) + 1
    anchored = set(pins.values()) | {_point(g.position.X, g.position.Y) for g in sch.globalLabels}
    for s in sch.schematicSymbols:
        if library[s.libId].isPower:
            anchored.add(_point(s.position.X, s.position.Y))
    dangling = [p for p, n in ends.items() if n == 1 and p not in anchored]
    assert not dangling, f"wire ends on nothing at {dangling[:5]}"
    # KiCad also joins a wire end, pin or label that touches the middle of a wire: there must be
    # none, so that the end-point nets above are KiCad's nets
    points = set(ends) | anchored
    for wire in sch.graphicalItems:
        if getattr(wire, "type", None) != "wire":
            continue
        (x1, y1), (x2, y2) = ((round(p.X, 2), round(p.Y, 2)) for p in wire.points)
        assert x1 == x2 or y1 == y2, "a slanted wire"
        for _, x, y in points:
            inside_x = min(x1, x2) < x < max(x1, x2) and y == y1 == y2
            inside_y = min(y1, y2) < y < max(y1, y2) and x == x1 == x2
            assert not (inside_x or inside_y), f"({x}, {y}) touches a wire's middle"
    return sch, pins, nets


def _expected(circuit, bom):
    """(reference, pin number) -> circuit node, from the Circuit and the BOM's designators."""
    designators = {p.part.lower(): p.designator for p in board_parts(circuit, bom)}
    controls = {e.control_positive.lower() for e in circuit.elements if isinstance(e, Switch)}
    expected = {}
    for e in circuit.elements:
        ref = designators[e.name.lower()]
        if isinstance(e, SubcircuitCall):
            package, section = ref[:-1], ref[-1]
            plus, minus, out = TL074[section]
            expected[(package, plus)] = e.connections[0].lower()
            expected[(package, minus)] = e.connections[1].lower()
            expected[(package, out)] = e.connections[-1].lower()
            if len(e.connections) == 5:
                expected[(package, "4")] = e.connections[2].lower()
                expected[(package, "11")] = e.connections[3].lower()
        elif isinstance(e, Diode):
            expected[(ref, "2")] = e.anode.lower()
            expected[(ref, "1")] = e.cathode.lower()
        elif isinstance(e, VoltageSource) and e.positive.lower() in controls:
            continue  # the switch control: the panel switch needs none (the module says so)
        elif isinstance(e, Resistor | Capacitor | Switch | VoltageSource):
            expected[(ref, "1")] = e.positive.lower()
            expected[(ref, "2")] = e.negative.lower()
        else:
            raise AssertionError(f"unexpected element {e.name}")
    return expected


@pytest.mark.parametrize(
    "model, opamp",
    [("wheelset", "tl074"), ("wheelset", "ideal"), ("quarter_car", "ideal"), ("bogie", "tl074"),
     ("wheelset_creep", "ideal")],
)  # fmt: skip
def test_the_schematic_nets_are_the_circuit_nets(tmp_path, model, opamp):
    system = load_model(model).system()
    sch_path = tmp_path / "w.kicad_sch"
    out = generate(system, tmp_path / "w.cir", SynthesisOptions(opamp=opamp), kicad=sch_path)
    circuit, bom = out.synthesis.circuit, out.synthesis.bom
    assert out.kicad_file == sch_path and (tmp_path / "w.spice.lib").is_file()
    sch, pins, nets = _read(sch_path)
    expected = _expected(circuit, bom)
    # every pin of the circuit is drawn, and a node is one schematic net and back
    missing = sorted(set(expected) - set(pins))
    assert not missing, f"pins not in the schematic: {missing[:8]}"
    node_of_net = {}
    net_of_node = {}
    for key, node in expected.items():
        root = nets.find(pins[key])
        assert node_of_net.setdefault(root, node) == node, (
            f"{key}: {node} joins {node_of_net[root]}"
        )
        assert net_of_node.setdefault(node, root) == root, f"node {node} is split at {key}"
    # a label names its node's net (ground is 0), never another's
    for node, root in net_of_node.items():
        if ("net", node) in nets.parent:
            assert nets.find(("net", node)) == root, f"label {node} is on another net"
    # pins the circuit does not have: only unused op-amp sections, grounded followers
    extra = set(pins) - set(expected)
    flags = {_point(n.position.X, n.position.Y) for n in sch.noConnects}
    for reference, number in extra:
        if number in ("4", "11"):  # an ideal op-amp has no supply pins: flagged unconnected
            assert opamp == "ideal" and pins[(reference, number)] in flags
            continue
        section = next(s for s, p in TL074.items() if number in p)
        plus, minus, out_pin = TL074[section]
        assert nets.find(pins[(reference, plus)]) == nets.find(("net", "0"))
        assert nets.find(pins[(reference, minus)]) == nets.find(pins[(reference, out_pin)])
    # the embedded symbols carry KiCad's library names, and the simulation fields are there
    ids = {s.libId for s in sch.libSymbols}
    assert {"Device:R", "Device:C", "Device:D", "Amplifier_Operational:TL074"} <= ids
    opamps = [s for s in sch.schematicSymbols if s.libId == "Amplifier_Operational:TL074"]
    fields = {p.key: p.value for p in opamps[0].properties}
    assert fields["Spice_Primitive"] == "X" and fields["Spice_Lib_File"] == "w.spice.lib"


def test_values_in_kicad_notation(tmp_path):
    system = load_model("wheelset").system()
    out = generate(system, tmp_path / "w.cir", kicad=tmp_path / "w.kicad_sch")
    sch = Schematic.from_file(str(tmp_path / "w.kicad_sch"))
    values = {}
    for s in sch.schematicSymbols:
        props = {p.key: p.value for p in s.properties}
        values[props["Reference"]] = props["Value"]
    names = {
        p.part.lower(): p.designator for p in board_parts(out.synthesis.circuit, out.synthesis.bom)
    }
    for e in out.synthesis.circuit.elements:
        if isinstance(e, Resistor):
            text = values[names[e.name.lower()]]
            scale = {"k": 1e3, "Meg": 1e6}
            number = text.rstrip("kMeg")
            factor = scale.get(text[len(number) :], 1.0)
            assert float(number) * factor == pytest.approx(float(e.resistance), rel=1e-9)
    assert values["R1A"] == "30.1k" and values["R1B"] == "205" and values["C3"] == "100n"


def test_a_bad_suffix_is_refused_before_anything_is_written(tmp_path):
    system = load_model("wheelset").system()
    with pytest.raises(SynthesisError, match=r"w\.sch.*\.kicad_sch"):
        generate(system, tmp_path / "w.cir", kicad=tmp_path / "w.sch")
    assert not list(tmp_path.iterdir())


def test_the_rest_of_circuitsim_does_not_import_kiutils():
    """kiutils is loaded only where a KiCad file is written (--kicad, reproduce), not at import."""
    import subprocess
    import sys

    code = (
        "import sys, circuitsim.cli, circuitsim.synthesis.generate, circuitsim.synthesis.schematic;"
        "print('kiutils' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_a_switch_closed_later_is_refused(tmp_path):
    """The schematic draws S1 closed: a circuit that closes it at a time is refused by name."""
    from circuitsim.synthesis.generate import switch_at

    system = switch_at(load_model("wheelset").system(), 1.0)
    with pytest.raises(SynthesisError, match="switch S1 is not held on"):
        generate(system, tmp_path / "w.cir", kicad=tmp_path / "w.kicad_sch")
    assert not list(tmp_path.iterdir())


def test_generate_kicad_on_the_command_line(tmp_path, capsys):
    from circuitsim.cli import main

    sch = tmp_path / "w.kicad_sch"
    assert main(["generate", "--kicad", str(sch), "-o", str(tmp_path / "w.cir")]) == 0
    out = capsys.readouterr().out
    assert str(sch) in out and str(tmp_path / "w.spice.lib") in out
    assert Schematic.from_file(str(sch)).schematicSymbols
    bad = tmp_path / "bad"
    bad.mkdir()
    assert main(["generate", "--kicad", str(bad / "w.txt"), "-o", str(bad / "w.cir")]) == 2
    assert "--kicad" in capsys.readouterr().err and not list(bad.iterdir())
