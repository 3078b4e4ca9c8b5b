"""Other tools read our netlists: spicelib's SpiceEditor finds every part, node and value.

spicelib (the Python automation library for LTspice and ngspice, a test dependency) read a
bare title line as a component; the writer now writes the title as a ``*`` comment. Each
netlist ``generate`` writes (the wheelset with the flange and TL074-like op-amps, whose
subcircuit has diodes, a switch and ``params:``; and a non-wheelset model) is read by
spicelib in every dialect, and its component list, nodes and values are compared with the
Circuit's, numbers through spicelib's own number parser.
"""

import math
import warnings
from pathlib import Path

import pytest
from spicelib.utils.float_unit import scan_eng  # a test dependency: pip install .[test]

from circuitsim.netlist.circuit import (
    Capacitor,
    Cccs,
    Ccvs,
    Circuit,
    CurrentSource,
    Diode,
    Expression,
    Inductor,
    Pulse,
    Pwl,
    Resistor,
    Sin,
    SubcircuitCall,
    Switch,
    Vccs,
    Vcvs,
    VoltageSource,
)
from circuitsim.netlist.reader import NetlistWarning, parse_netlist

DIALECTS = ["ngspice", "ltspice", "multisim"]
MODELS = Path(__file__).resolve().parents[1] / "synthesis" / "models"


def _generated(tmp_path, case: str, dialect: str):
    from circuitsim.mechanics import load_model
    from circuitsim.synthesis.generate import generate
    from circuitsim.synthesis.options import SynthesisOptions

    if case == "wheelset":
        system = load_model().system(parameters={"V": 55.0, "f": 3.0, "a": 0.040})
        options = SynthesisOptions(opamp="tl074")
    else:
        system = load_model(MODELS / f"{case}.toml").system()
        options = SynthesisOptions()
    return generate(system, tmp_path / f"{case}_{dialect}.cir", options, dialect)


def _number(text: str) -> float:
    """A number as spicelib reads it (its own engineering-suffix parser)."""
    return float(scan_eng(text))


def _same(text: str, value) -> None:
    if isinstance(value, Expression):
        assert text == "{" + value.text + "}", (text, value)
        return
    assert math.isclose(_number(text), float(value), rel_tol=1e-12, abs_tol=0.0), (text, value)


def _fields(text: str, keyword: str) -> list[str]:
    """The numbers inside ``KEYWORD( ... )`` of a source's value text."""
    inside = text[text.upper().index(keyword + "(") + len(keyword) + 1 : text.rindex(")")]
    return inside.split()


def _check_source(value: str, element: VoltageSource | CurrentSource) -> None:
    tokens = value.split()
    if tokens and tokens[0].upper() == "DC":
        _same(tokens[1], element.dc)
    else:
        assert element.dc == 0.0
    shape = element.waveform
    if isinstance(shape, Sin):
        fields = [shape.offset, shape.amplitude, shape.frequency, shape.delay, shape.damping,
                  shape.phase]  # fmt: skip
        got = _fields(value, "SIN")
        for text, want in zip(got, fields, strict=False):
            _same(text, want)
        assert all(f == 0.0 for f in fields[len(got) :])  # trimmed fields are SPICE's zeros
    elif isinstance(shape, Pwl):
        got = _fields(value, "PWL")
        want = [x for point in shape.points for x in point]
        assert len(got) == len(want)
        for text, number in zip(got, want, strict=True):
            _same(text, number)
    elif isinstance(shape, Pulse):
        got = _fields(value, "PULSE")
        for text, number in zip(got, [shape.initial, shape.pulsed, shape.delay], strict=False):
            _same(text, number)
    else:
        assert shape is None, value


def _check_element(editor, element, renames: dict[str, str]) -> None:
    """The part ``element`` as spicelib reads it: same nodes, same value."""
    name = element.name
    nodes = [renames.get(n, n) for n in element.nodes]
    value = editor.get_component(name).value_str
    params = editor.get_component_parameters(name)
    if isinstance(element, Vcvs | Vccs) and not isinstance(element, Switch):
        # spicelib keeps the two output nodes as ports and the rest as the value text
        assert editor.get_component_nodes(name) == nodes[:2]
        *controls, gain = value.split()
        assert controls == nodes[2:]
        _same(gain, element.gain if isinstance(element, Vcvs) else element.transconductance)
        return
    if isinstance(element, Cccs | Ccvs):
        assert editor.get_component_nodes(name) == nodes
        control, gain = value.split()
        assert control.upper() == element.control.upper()
        _same(gain, element.gain if isinstance(element, Cccs) else element.transresistance)
        return
    assert editor.get_component_nodes(name) == nodes, name
    if isinstance(element, Resistor):
        _same(value, element.resistance)
    elif isinstance(element, Capacitor | Inductor):
        _same(value, element.capacitance if isinstance(element, Capacitor) else element.inductance)
        if element.ic is not None:
            _same(str(params["IC"]), element.ic)
    elif isinstance(element, VoltageSource | CurrentSource):
        _check_source(value, element)
    elif isinstance(element, Diode | Switch):
        assert value.upper() == element.model.upper()
    elif isinstance(element, SubcircuitCall):
        assert value.upper() == element.subcircuit.upper()
        for key, want in element.params.items():
            _same(str(params[key]), want)
    else:
        raise AssertionError(f"{name}: no check for a {type(element).__name__}")


def _check_scope(editor, elements, renames) -> int:
    assert sorted(editor.get_components()) == sorted(e.name for e in elements)
    for element in elements:
        _check_element(editor, element, renames)
    return len(elements)


def _renames(text: str) -> dict[str, str]:
    """Node renames the writer noted (Multisim's node names)."""
    renames = {}
    for line in text.splitlines():
        if line.startswith("* circuitsim: node "):
            old, new = line.split("'")[1], line.split("'")[3]
            renames[old] = new
    return renames


@pytest.mark.parametrize("dialect", DIALECTS)
@pytest.mark.parametrize("case", ["wheelset", "two_mass_stop"])
def test_spicelib_reads_every_part_and_value(tmp_path, case, dialect):
    from spicelib import SpiceEditor

    generated = _generated(tmp_path, case, dialect)
    path = generated.netlist
    text = path.read_text()
    assert text.startswith("* ")  # the title is a comment: no tool reads it as a part
    # what the file holds as our reader reads it: the generator leaves out the capacitors'
    # IC= that .ic says and folds unchanged subcircuit defaults in (writer.write_netlist)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", r".*\.(save|print) ignored", NetlistWarning)
        circuit: Circuit = parse_netlist(text, source=str(path), base_dir=str(path.parent))
    editor = SpiceEditor(str(path))
    renames = _renames(text)
    count = _check_scope(editor, circuit.elements, renames)
    subcircuits = [s.name for s in circuit.subcircuits.values()]
    assert sorted(editor.get_subcircuit_names()) == sorted(subcircuits)
    for sub in circuit.subcircuits.values():
        count += _check_scope(editor.get_subcircuit_named(sub.name), sub.elements, renames)
    assert count >= 20  # the circuit is not trivially empty
    if dialect == "ltspice":
        assert ".options plotwinsize=0" in text.splitlines()


def test_a_bare_title_is_what_spicelib_refuses(tmp_path):
    """The failure the issue reported, kept as the reason for the comment title: spicelib
    1.6.4 wants the first line to be a comment or ``.title``."""
    from spicelib import SpiceEditor
    from spicelib.utils.detect_encoding import EncodingDetectError

    path = tmp_path / "bare.cir"
    path.write_text("rc filter\nR1 a 0 1k\nC1 a 0 1u\n.end\n")
    with pytest.raises(EncodingDetectError):
        SpiceEditor(str(path))
    path.write_text("* rc filter\nR1 a 0 1k\nC1 a 0 1u\n.end\n")
    assert sorted(SpiceEditor(str(path)).get_components()) == ["C1", "R1"]


def test_spicelib_reads_meg_only_capitalized():
    """Why the writer spells the mega suffix ``Meg``: spicelib reads ``10meg`` as 10 milli."""
    assert _number("10Meg") == 1e7
    assert _number("10meg") == pytest.approx(1e-2)
