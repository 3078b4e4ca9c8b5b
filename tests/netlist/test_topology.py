"""Topology checks: each kind of finding on the smallest circuit that has it, and clean circuits.

Each circuit's expected finding follows from circuit theory (KCL/KVL), not from our code: a
node joined to ground only through a capacitor has an undefined DC voltage, two ideal voltage
sources in parallel form a KVL loop, and so on.
"""

import shutil
import time

import pytest

from circuitsim.netlist.circuit import (
    Capacitor,
    Cccs,
    Ccvs,
    Circuit,
    CurrentSource,
    Diode,
    Inductor,
    Model,
    Resistor,
    Subcircuit,
    SubcircuitCall,
    Switch,
    Vccs,
    Vcvs,
    VoltageSource,
)
from circuitsim.netlist.reader import parse_netlist
from circuitsim.netlist.topology import Finding, check_circuit


def _kinds(findings: list[Finding]) -> list[str]:
    return sorted(f.kind for f in findings)


def _rc() -> Circuit:
    c = Circuit(title="rc")
    c.add(
        VoltageSource("V1", "in", "0", dc=1.0),
        Resistor("R1", "in", "out", 1e3),
        Capacitor("C1", "out", "0", 1e-6),
    )
    return c


def test_clean_circuit_has_no_findings():
    assert check_circuit(_rc()) == []


def test_clean_circuit_with_every_kind_of_element():
    c = _rc()
    c.models["dm"] = Model("dm", "D", {"is": 1e-14})
    c.models["sm"] = Model("sm", "SW", {"vt": 0.5})
    c.add(
        Inductor("L1", "out", "m", 1e-3),
        Resistor("R2", "m", "0", 1.0),
        Diode("D1", "m", "0", "dm"),
        Switch("S1", "m", "0", "in", "0", model="sm"),
        Vcvs("E1", "e", "0", "out", "0", 2.0),
        Resistor("R3", "e", "0", 1e3),
        Vccs("G1", "e", "0", "out", "0", 1e-3),
        Ccvs("H1", "h", "0", "V1", 10.0),
        Resistor("R4", "h", "0", 1e3),
        Cccs("F1", "h", "0", "V1", 2.0),
        CurrentSource("I1", "out", "0", dc=1e-3),
    )
    assert check_circuit(c) == []


def test_floating_node_names_the_node_and_element():
    c = _rc()
    c.add(Resistor("R9", "out", "dangling", 1.0))
    [finding] = check_circuit(c)
    assert finding.kind == "floating-node"
    assert finding.nodes == ("dangling",) and finding.elements == ("R9",)


def test_node_behind_capacitor_has_no_dc_path():
    c = _rc()
    c.add(Capacitor("C2", "out", "mid", 1e-6), Resistor("R5", "mid", "top", 1e3))
    c.add(Capacitor("C3", "top", "0", 1e-6))
    [finding] = check_circuit(c)
    assert finding.kind == "no-dc-path"
    assert finding.nodes == ("mid", "top")
    assert set(finding.elements) == {"C2", "C3"}


def test_node_seen_only_by_a_controlling_input_has_no_dc_path():
    c = _rc()
    c.add(Vcvs("E1", "e", "0", "sense", "0", 1.0), Resistor("RL", "e", "0", 1.0))
    c.add(Capacitor("CS", "sense", "0", 1e-9), Resistor("RS", "sense", "0", 1e3))
    assert check_circuit(c) == []
    c.elements = [e for e in c.elements if e.name not in ("CS", "RS")]
    kinds = _kinds(check_circuit(c))
    # One control terminal only: both floating and without a DC path; floating wins alone.
    assert kinds == ["floating-node"]


def test_current_source_cut_set():
    c = _rc()
    c.add(CurrentSource("I1", "0", "x", dc=1e-3), Resistor("R7", "x", "y", 1e3))
    c.add(CurrentSource("I2", "y", "0", dc=1e-3))
    [finding] = check_circuit(c)
    assert finding.kind == "current-source-cutset"
    assert finding.nodes == ("x", "y") and set(finding.elements) == {"I1", "I2"}


def test_current_source_into_capacitor_is_a_dc_cut_set():
    c = _rc()
    c.add(CurrentSource("I1", "0", "x", dc=1e-3), Capacitor("C5", "x", "0", 1e-6))
    [finding] = check_circuit(c)
    assert finding.kind == "no-dc-path" and set(finding.elements) == {"I1", "C5"}


def test_parallel_voltage_sources_form_a_loop():
    c = _rc()
    c.add(VoltageSource("V2", "in", "0", dc=2.0))
    [finding] = check_circuit(c)
    assert finding.kind == "voltage-loop"
    assert set(finding.elements) == {"V1", "V2"}


def test_loop_of_source_inductor_and_vcvs():
    c = _rc()
    c.add(Inductor("L1", "in", "a", 1e-3), Vcvs("E1", "a", "0", "out", "0", 1.0))
    [finding] = check_circuit(c)
    assert finding.kind == "voltage-loop"
    assert set(finding.elements) == {"V1", "L1", "E1"}
    assert set(finding.nodes) == {"in", "a", "0"}


def test_shorted_voltage_source_is_a_loop_of_one():
    c = _rc()
    c.add(VoltageSource("V3", "out", "out", dc=1.0))
    kinds = _kinds(check_circuit(c))
    assert kinds == ["voltage-loop"]


def test_duplicate_names_are_case_insensitive_and_per_scope():
    c = _rc()
    c.add(Resistor("r1", "out", "0", 1.0))
    sub = Subcircuit("blk", ("a", "b"), [Resistor("R1", "a", "b", 1.0)])
    c.subcircuits["blk"] = sub
    [finding] = check_circuit(c)
    assert finding.kind == "duplicate-name" and finding.elements == ("R1", "r1")


def test_undefined_and_wrong_kind_models():
    c = _rc()
    c.models["sm"] = Model("sm", "SW", {})
    c.add(Diode("D1", "out", "0", "nomodel"), Diode("D2", "out", "0", "sm"))
    c.models["dm"] = Model("dm", "D", {})
    c.add(Switch("S1", "out", "0", "in", "0", model="dm"))
    found = {f.elements[0]: f.kind for f in check_circuit(c)}
    assert found == {"D1": "undefined-model", "D2": "wrong-model-kind", "S1": "wrong-model-kind"}


def test_undefined_subcircuit_and_port_count():
    c = _rc()
    c.subcircuits["blk"] = Subcircuit("blk", ("a", "b"), [Resistor("RB", "a", "b", 1.0)])
    c.add(SubcircuitCall("X1", ("out", "0"), "nosuch"))
    c.add(SubcircuitCall("X2", ("out", "0", "in"), "blk"))
    found = {f.elements[0]: f.kind for f in check_circuit(c)}
    assert found == {"X1": "undefined-subcircuit", "X2": "port-count"}


def test_model_and_subcircuit_scopes():
    # A model defined inside a .subckt is visible there and in its nested .subckt only.
    inner = Subcircuit("inner", ("p",), [Diode("DI", "p", "0", "local")])
    outer = Subcircuit(
        "outer",
        ("a",),
        [SubcircuitCall("XI", ("a",), "inner"), Resistor("RO", "a", "0", 1.0)],
        models={"local": Model("local", "D", {})},
        subcircuits={"inner": inner},
    )
    c = _rc()
    c.subcircuits["outer"] = outer
    c.add(Diode("DT", "out", "0", "local"), SubcircuitCall("XT", ("out",), "inner"))
    found = {f.elements[0]: f.kind for f in check_circuit(c)}
    assert found == {"DT": "undefined-model", "XT": "undefined-subcircuit"}


def test_unconnected_subcircuit_port():
    c = _rc()
    c.subcircuits["blk"] = Subcircuit("blk", ("a", "b", "c"), [Resistor("RB", "a", "b", 1.0)])
    [finding] = check_circuit(c)
    assert finding.kind == "unconnected-port" and finding.nodes == ("c",)
    assert "blk" in finding.message


def test_undefined_control_source():
    c = _rc()
    c.add(Cccs("F1", "out", "0", "Vnone", 1.0), Ccvs("H1", "h", "0", "R1", 1.0))
    c.add(Resistor("RH", "h", "0", 1.0))
    found = {f.elements[0]: f.kind for f in check_circuit(c)}
    assert found == {"F1": "undefined-control", "H1": "undefined-control"}


def test_large_flat_ladder_is_checked_quickly_and_clean():
    # The solver calls check_circuit to explain singular matrices: it must scale linearly.
    c = Circuit()
    c.add(VoltageSource("V1", "n0", "0", dc=1.0))
    for k in range(2000):
        c.add(Resistor(f"R{k}", f"n{k}", f"n{k + 1}", 1.0))
        c.add(Capacitor(f"C{k}", f"n{k + 1}", "0", 1e-9))
    c.add(Resistor("RL", "n2000", "0", 1.0))
    started = time.perf_counter()
    assert check_circuit(c) == []
    # Not a timing assertion: recorded so a regression is visible in -rA output.
    print(f"2000-section ladder checked in {time.perf_counter() - started:.3f} s")


# --- ngspice as referee: the electrical findings are exactly the circuits it cannot solve -


requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)

REFEREE = {
    "no-dc-path": "V1 in 0 DC 1\nR1 in out 1k\nC1 out mid 1u\nR2 mid top 1k\nC2 top 0 1u\n",
    "current-source-cutset": "V1 in 0 DC 1\nR1 in 0 1k\nI1 0 x DC 1m\nR7 x y 1k\nI2 y 0 DC 1m\n",
    "voltage-loop": "V1 in 0 DC 1\nR1 in 0 1k\nL1 in a 1m\nE1 a 0 in 0 1\n",
    "clean": "V1 in 0 DC 1\nR1 in out 1k\nC1 out 0 1u\nL1 out m 1m\nR2 m 0 1k\nI1 0 out DC 1m\n",
}


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("kind", sorted(REFEREE))
def test_findings_agree_with_ngspice_operating_point(kind):
    from circuitsim.interop.errors import NgspiceError
    from circuitsim.interop.ngspice import run_ngspice

    text = f"{kind}\n{REFEREE[kind]}.op\n.end\n"
    kinds = _kinds(check_circuit(parse_netlist(text)))
    if kind == "clean":
        assert kinds == []
        run_ngspice(text)  # solves without error
    else:
        assert kinds == [kind]
        with pytest.raises(NgspiceError, match="singular matrix"):
            run_ngspice(text)


def test_electrical_findings_inside_subcircuit_instances_use_flat_names():
    # A capacitor-coupled internal node: no DC path, once per instance.
    body = [Capacitor("C1", "a", "m", 1e-9), Resistor("R1", "m", "k", 1e3)]
    body.append(Capacitor("C2", "k", "b", 1e-9))
    c = _rc()
    c.subcircuits["blk"] = Subcircuit("blk", ("a", "b"), body)
    c.add(SubcircuitCall("X1", ("out", "0"), "blk"), SubcircuitCall("X2", ("in", "0"), "blk"))
    findings = check_circuit(c)
    assert _kinds(findings) == ["no-dc-path", "no-dc-path"]
    assert [f.nodes for f in findings] == [("x1.k", "x1.m"), ("x2.k", "x2.m")]
    assert set(findings[0].elements) == {"C.X1.C1", "C.X1.C2"}


def test_circuit_that_cannot_be_flattened_is_reported():
    c = _rc()
    c.subcircuits["blk"] = Subcircuit("blk", ("a",), [Resistor("RB", "a", "0", 1.0)])
    c.add(SubcircuitCall("X1", ("out",), "blk", {"nosuch": 1.0}))
    [finding] = check_circuit(c)
    assert finding.kind == "unflattenable" and "nosuch" in finding.message
