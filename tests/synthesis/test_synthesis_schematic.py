"""The schematic of a generated circuit: every part drawn once with its name and value, for
every shipped model; the files written atomically; a bad suffix refused by name."""

import re
import xml.etree.ElementTree as ET
from collections import Counter

import pytest

from circuitsim.mechanics import load_model
from circuitsim.netlist.circuit import Resistor, SubcircuitCall
from circuitsim.synthesis.bom import engineering
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.parts import board_parts
from circuitsim.synthesis.schematic import layout, schematic_format, schematic_image
from circuitsim.synthesis.translator import synthesize

SVG = "{http://www.w3.org/2000/svg}"


def _texts(svg: bytes) -> list[str]:
    root = ET.fromstring(svg)
    return ["".join(t.itertext()) for t in root.iter(f"{SVG}tspan")]


def _designators(circuit, bom) -> dict:
    """The bill of materials' reference designators (op-amp sections ``U3A``), by part."""
    return {p.part.lower(): p.designator for p in board_parts(circuit, bom)}


@pytest.mark.parametrize("name", ["wheelset", "quarter_car", "bogie", "wheelset_creep"])
def test_every_part_is_drawn_once_with_its_label(name):
    system = load_model(name).system()
    synthesis = synthesize(system, SynthesisOptions(t_stop=0.5))
    circuit = synthesis.circuit
    plan = layout(circuit, list(system.states))
    drawn = plan.elements()
    assert sorted(id(e) for e in drawn) == sorted(id(e) for e in circuit.elements)
    texts = _texts(schematic_image(circuit, "svg", list(system.states), synthesis.bom))
    first_words = Counter(t.split(" ")[0] for t in texts)
    designators = _designators(circuit, synthesis.bom)
    for element in circuit.elements:
        name = designators[element.name.lower()]
        assert first_words[name] == 1, name
    # the labels with a part's name are as many as the circuit's parts
    names = set(designators.values())
    assert sum(first_words[n] for n in names) == len(circuit.elements)
    # every op-amp section is drawn under the order file's name (U3A, not FLANGE_ABS1A)
    for element in circuit.elements:
        if isinstance(element, SubcircuitCall):
            assert re.fullmatch(r"U\d+[A-D]", designators[element.name.lower()])
    # a resistor's label carries its value in one unit style: kΩ / Ω
    resistor = next(e for e in circuit.elements if isinstance(e, Resistor))
    value = engineering(float(resistor.resistance), "ohm").replace("Ohm", "Ω")
    assert f"{designators[resistor.name.lower()]} {value}" in texts
    # one row per state (merged up to four stages), the paper's sections for the wheelset
    titles = [title for title, _ in plan.rows]
    assert all(any(s in t.split(" ", 1)[1].split(", ") for t in titles if t.startswith("state"))
               for s in system.states)  # fmt: skip
    if name == "wheelset":
        assert [[s.opamp.name for s in row] for _, row in plan.rows[:2]] == [
            ["XU1A", "XU1B", "XU2A", "XU2B"], ["XU1C", "XU1D", "XU2C", "XU2D"]
        ]  # fmt: skip
        assert "R31A 102 kΩ" in texts and "R31B 909 Ω" in texts and "C3 100 nF" in texts
        assert "C1 1 µF" in texts and "S1 (ctl flange_ctl)" in texts
        assert "U3A" in texts and not any("FLANGE_ABS1A" in t for t in texts)


def test_tl074_pin_numbers_and_supply_pins_are_drawn():
    """Each section shows the TL074 data sheet's pins: A is 2 (-), 3 (+), 1 (out); the supply
    pins 4 and 11 carry the rails' nets."""
    system = load_model("wheelset").system()
    synthesis = synthesize(system, SynthesisOptions(opamp="tl074", t_stop=0.5))
    texts = _texts(schematic_image(synthesis.circuit, "svg", list(system.states), synthesis.bom))
    counts = Counter(texts)
    sections = 13  # the wheelset: 8 for the states, 4 in the two |x| blocks, 1 summer
    assert counts["4 vcc"] == sections and counts["11 vee"] == sections
    # pins of section D (U1D, U2D, U3D in the order file): 13 (-), 12 (+), 14 (out)
    names = _designators(synthesis.circuit, synthesis.bom).values()
    d_sections = sum(1 for n in names if re.fullmatch(r"U\d+D", n))
    assert d_sections == 3
    assert counts["14"] == d_sections and counts["13"] == d_sections and counts["12"] == d_sections


def test_generate_writes_png_and_svg_with_the_other_files(tmp_path):
    system = load_model().system()
    png = tmp_path / "w.png"
    result = generate(system, tmp_path / "w.cir", SynthesisOptions(t_stop=0.5), schematic=png)
    assert result.schematic_file == png
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    svg = tmp_path / "w.svg"
    generate(system, tmp_path / "w.cir", SynthesisOptions(t_stop=0.5), schematic=svg)
    assert "U1A" in _texts(svg.read_bytes())
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporaries


def test_bad_suffix_or_folder_writes_nothing(tmp_path, capsys):
    system = load_model().system()
    with pytest.raises(SynthesisError, match=r"schematic .*w\.pdf: cannot draw a \.pdf file"):
        generate(system, tmp_path / "w.cir", schematic=tmp_path / "w.pdf")
    with pytest.raises(OSError, match="does not exist"):
        generate(system, tmp_path / "w.cir", schematic=tmp_path / "no" / "w.svg")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(SynthesisError, match=r"no suffix"):
        schematic_format("drawing")
    from circuitsim.cli import main

    argv = ["generate", "--schematic", str(tmp_path / "w.jpg"), "-o", str(tmp_path / "w.cir")]
    assert main(argv) == 2
    error = capsys.readouterr().err
    assert "--schematic" in error and "w.jpg" in error and "use .svg or .png" in error
    assert list(tmp_path.iterdir()) == []


def _drawn_nets(d) -> tuple[dict, dict]:
    """The drawing's connectivity read from its geometry alone: wires (a wire's end on another
    wire joins it), junction dots, net labels on open dots and ground symbols. Returns each
    part's terminals as groups (by the designator its label starts with) and each group's name
    where a label or a ground names it."""
    def key(p):
        return (round(p[0], 6), round(p[1], 6))

    parent: dict = {}

    def find(p):
        parent.setdefault(p, p)
        while parent[p] != p:
            parent[p] = parent[parent[p]]
            p = parent[p]
        return p

    def join(a, b):
        parent[find(a)] = find(b)

    lines = [(key(e.absanchors["start"]), key(e.absanchors["end"]))
             for e in d.elements if type(e).__name__ == "Line"]  # fmt: skip
    terminals, names = {}, {}
    points = {a for line in lines for a in line}
    for e in d.elements:
        kind = type(e).__name__
        text = e._userlabels[0].label.split(" ")[0] if e._userlabels else ""
        if kind == "Opamp":
            terminals[text] = [key(e.absanchors[p]) for p in ("in2", "in1", "out")]
        elif kind in {"Dot", "Ground"}:
            points.add(key(e.absanchors["start"]))
            if kind == "Ground":
                names[key(e.absanchors["start"])] = "0"
            elif text:
                names[key(e.absanchors["start"])] = text
        elif kind not in {"Line", "Label"} and text:
            terminals[text] = [key(e.absanchors["start"]), key(e.absanchors["end"])]
    points |= {p for ends in terminals.values() for p in ends}
    for a, b in lines:
        join(a, b)
        for p in points:  # a T-junction: an end lying on the wire
            on_x = min(a[0], b[0]) - 1e-6 <= p[0] <= max(a[0], b[0]) + 1e-6
            on_y = min(a[1], b[1]) - 1e-6 <= p[1] <= max(a[1], b[1]) + 1e-6
            cross = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
            if on_x and on_y and abs(cross) < 1e-6:
                join(p, a)
    by_name: dict = {}
    for p, name in names.items():
        by_name.setdefault(name, []).append(p)
    for group in by_name.values():  # nets with the same label are one node
        for p in group[1:]:
            join(p, group[0])
    named = {find(p): name for p, name in names.items()}
    return {t: [find(p) for p in ends] for t, ends in terminals.items()}, named


@pytest.mark.parametrize("name", ["wheelset", "quarter_car", "bogie", "wheelset_creep"])
def test_the_drawing_wires_equal_the_netlist_and_join_a_blocks_stages_by_wire(name):
    """The nets read back from the drawing's geometry are the circuit's nets, and inside a
    block (integrator -> inverter, a precision rectifier's two stages) the stages are joined by
    wires: the rectifier's half-wave net is labelled once where it was labelled at both ends."""
    from circuitsim.netlist.circuit import Capacitor, Diode, Switch, VoltageSource
    from circuitsim.synthesis.schematic import draw

    system = load_model(name).system()
    synthesis = synthesize(system, SynthesisOptions(t_stop=0.5))
    circuit = synthesis.circuit
    d = draw(circuit, list(system.states), synthesis.bom)
    terminals, named = _drawn_nets(d)
    designators = _designators(circuit, synthesis.bom)
    wanted = {}
    for e in circuit.elements:
        if isinstance(e, SubcircuitCall):
            c = [n.lower() for n in e.connections]
            wanted[designators[e.name.lower()]] = [c[0], c[1], c[-1]]
        elif isinstance(e, Resistor | Capacitor | VoltageSource):
            wanted[designators[e.name.lower()]] = [e.positive.lower(), e.negative.lower()]
        elif isinstance(e, Diode):
            wanted[designators[e.name.lower()]] = [e.anode.lower(), e.cathode.lower()]
        elif isinstance(e, Switch):
            wanted[designators[e.name.lower()]] = [e.positive.lower(), e.negative.lower()]
    assert set(terminals) == set(wanted)
    # a group's node: from its name, else from a part whose other end is known (a chain's
    # inner node); every part must then see exactly its circuit nodes
    node = dict(named)
    for _ in range(4):
        for t, groups in terminals.items():
            if len(groups) == 2:
                for g, other in (groups, groups[::-1]):
                    if g not in node and other in node and node[other] in wanted[t]:
                        rest = [n for n in wanted[t] if n != node[other]] or [node[other]]
                        node[g] = rest[0]
    for t, groups in terminals.items():
        drawn = [node.get(g) for g in groups]
        if len(groups) == 3:
            assert drawn == wanted[t], t
        else:
            assert sorted(drawn) == sorted(wanted[t]), t
    # one group per node: no two circuit nodes drawn as one (a short)
    assert len({node[g] for g in node}) == len(set(node))
    if name != "wheelset":
        return
    texts = [e._userlabels[0].label for e in d.elements if type(e).__name__ == "Dot"
             and e._userlabels]  # fmt: skip
    assert texts.count("flange_abs1_h1") == 2  # the feedback end and the wired junction
    wired = [e for e in d.elements if type(e).__name__ == "Dot" and not e.params.get("open")
             and e._userlabels]  # fmt: skip
    assert {e._userlabels[0].label for e in wired} >= {"y_neg", "psi_neg", "flange_abs1_h1"}
