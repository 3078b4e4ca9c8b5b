"""add_opamp / ensure_diode_model: what they put into a circuit, and their errors."""

import pytest

from circuitsim.netlist.circuit import Circuit, SubcircuitCall, VoltageSource
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.opamps import OPAMP_KINDS, add_opamp, ensure_diode_model


def test_kinds():
    assert OPAMP_KINDS == ("ideal", "tl074")


def test_ideal_section_connections_and_definition():
    circuit = Circuit("t")
    add_opamp(circuit, "XU1A", "0", "s1", "y1", "ideal")
    call = circuit.element("XU1A")
    assert isinstance(call, SubcircuitCall)
    assert call.connections == ("0", "s1", "y1")
    assert call.subcircuit.lower() == "opamp_ideal"
    assert call.params == {}
    assert list(circuit.subcircuits) == ["opamp_ideal"]
    assert circuit.subcircuits["opamp_ideal"].ports == ("inp", "inm", "out")
    # no supplies for ideal op-amps
    assert [e.name for e in circuit.elements] == ["XU1A"]


def test_tl074_sections_share_one_definition_and_one_pair_of_supplies():
    circuit = Circuit("t")
    add_opamp(circuit, "XU1A", "0", "s1", "y1", "tl074")
    add_opamp(circuit, "XU1B", "0", "s2", "y2", "TL074")
    assert circuit.element("XU1B").connections == ("0", "s2", "vcc", "vee", "y2")
    assert list(circuit.subcircuits) == ["tl074"]
    sources = [e for e in circuit.elements if isinstance(e, VoltageSource)]
    assert [(s.name, s.positive, s.negative, s.dc) for s in sources] == [
        ("VCC", "vcc", "0", 15.0),
        ("VEE", "vee", "0", -15.0),
    ]


def test_offset_parameter_on_tl074_only():
    circuit = Circuit("t")
    add_opamp(circuit, "XU1A", "0", "a", "b", "tl074", offset_volts=3e-3)
    assert circuit.element("XU1A").params == {"vos": 3e-3}
    with pytest.raises(SynthesisError, match="ideal"):
        add_opamp(circuit, "XU1B", "0", "a", "c", "ideal", offset_volts=3e-3)


@pytest.mark.parametrize(
    ("name", "kind", "match"),
    [("XU1", "lm741", "unknown op-amp kind"), ("U1", "ideal", "start with X")],
)
def test_bad_requests(name, kind, match):
    with pytest.raises(SynthesisError, match=match):
        add_opamp(Circuit("t"), name, "0", "a", "b", kind)


def test_duplicate_name_refused():
    circuit = Circuit("t")
    add_opamp(circuit, "XU1A", "0", "a", "b", "ideal")
    with pytest.raises(SynthesisError, match="already used"):
        add_opamp(circuit, "xu1a", "0", "c", "d", "ideal")


def test_diode_model_added_once():
    circuit = Circuit("t")
    name = ensure_diode_model(circuit)
    assert ensure_diode_model(circuit) == name
    assert name.lower() == "d1n4148"
    assert list(circuit.models) == ["d1n4148"]
    assert circuit.models["d1n4148"].kind == "D"
