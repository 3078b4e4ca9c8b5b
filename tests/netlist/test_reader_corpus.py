"""The corpus read element by element; every expected value is copied from the netlist text."""

import math
from pathlib import Path

import pytest

from circuitsim.netlist.circuit import (
    AcSweep,
    Capacitor,
    Cccs,
    Ccvs,
    CurrentSource,
    Diode,
    Expression,
    Inductor,
    OperatingPoint,
    Pulse,
    Pwl,
    Resistor,
    Sin,
    SubcircuitCall,
    Switch,
    Transient,
    Vccs,
    Vcvs,
    VoltageSource,
)
from circuitsim.netlist.reader import read_netlist

CORPUS = Path(__file__).parent / "corpus"
FILES = sorted(CORPUS.glob("*.cir"))


def read(name):
    return read_netlist(CORPUS / name)


def test_corpus_is_large_enough():
    assert len(FILES) >= 8


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_every_corpus_file_reads_without_warnings(path, recwarn):
    circuit = read_netlist(path)
    assert circuit.elements and circuit.analyses
    assert circuit.source == str(path)
    assert not recwarn.list


def test_rc_lowpass():
    c = read("rc_lowpass.cir")
    assert c.title == "RC Low-Pass Filter  -- step and frequency response"
    assert c.elements == [
        VoltageSource(
            "VIN", "in", "0", dc=0.0, ac_magnitude=1.0,
            waveform=Pulse(0.0, 5.0, 100e-6, 1e-6, 1e-6, 5e-3, 10e-3),
        ),
        Resistor("R1", "in", "out", 10e3),
        Capacitor("C1", "out", "0", 100e-9),
        Resistor("RLOAD", "out", "0", 1e6),
    ]  # fmt: skip
    assert c.analyses == [Transient(10e-6, 5e-3), AcSweep("dec", 20, 10.0, 100e3)]
    assert c.options == {"reltol": 1e-4, "abstol": 1e-9}  # continued .OPTIONS line


def test_opamp_integrator():
    c = read("opamp_integrator.cir")
    assert c.params == {"rin": 10e3, "cint": 100e-9}
    sub = c.subcircuits["opamp"]
    assert sub.name == "OPAMP" and sub.ports == ("inp", "inm", "out")
    assert sub.params == {"aol": 1e5, "rout": 10.0}
    assert sub.elements == [
        Resistor("RIN", "inp", "inm", 10e6),
        Vcvs("EGAIN", "int", "0", "inp", "inm", Expression("aol")),
        Resistor("ROUT", "int", "out", Expression("rout")),
    ]
    assert c.element("VIN").waveform == Sin(0.0, 1.0, 100.0, 0.0, 0.0, 0.0)
    assert c.element("C1") == Capacitor("C1", "inv", "out", Expression("cint"), ic=0.0)
    assert c.element("XU1") == SubcircuitCall("XU1", ("0", "inv", "out"), "opamp", {"aol": 2e5})
    assert c.initial_conditions == {"out": 0.5}
    assert c.analyses == [Transient(10e-6, 20e-3, 0.0, 10e-6, uic=True)]


def test_diode_rectifier():
    c = read("diode_rectifier.cir")
    assert c.element("Vac").waveform == Sin(0.0, 10.0, 50.0)
    assert c.element("D1") == Diode("D1", "ac1", "pos", "d1n4148")
    assert c.element("D4") == Diode("D4", "neg", "ac2", "d1n4148", 2.0)
    assert c.element("Rneg").resistance == 1e-3  # m is milli, not mega
    assert c.element("Cf").capacitance == 470e-6
    model = c.models["d1n4148"]
    assert (model.name, model.kind) == ("D1N4148", "D")
    assert model.params == {"is": 2.52e-9, "rs": 0.568, "n": 1.752, "cjo": 4e-12, "m": 0.4,
                            "tt": 20e-9}  # fmt: skip


def test_switch():
    c = read("switch_sw.cir")
    assert c.element("S1") == Switch("S1", "sw", "0", "ctl", "0", model="smod", initial="off")
    assert c.element("S2") == Switch("S2", "vcc", "out", "ctl", "0", model="smod", initial="on")
    assert c.element("Vsup").dc == 12.0 and c.element("Vsup").waveform is None
    assert c.element("Vctl").waveform == Pulse(0.0, 5.0, 0.0, 10e-9, 10e-9, 0.5e-3, 1e-3)
    assert c.models["smod"].kind == "SW"
    assert c.models["smod"].params == {"vt": 2.5, "vh": 0.2, "ron": 1.0, "roff": 1e6}


def test_controlled_sources():
    c = read("controlled_sources.cir")
    assert c.element("E1") == Vcvs("E1", "e1", "0", "in", "0", 2.5)
    assert c.element("G1") == Vccs("G1", "0", "g1", "in", "0", 2e-3)
    assert c.element("F1") == Cccs("F1", "0", "f1", "Vsense", 3.0)
    assert c.element("H1") == Ccvs("H1", "h1", "0", "Vsense", 2e3)
    assert c.element("Vsense") == VoltageSource("Vsense", "a", "0", dc=0.0)
    assert c.analyses == [OperatingPoint()]


def test_nested_subcircuits():
    c = read("nested_subckt.cir")
    assert c.params == {"rbase": 1e3, "scale": Expression("2*1")}
    divider = c.subcircuits["divider"]
    assert divider.ports == ("top", "bot", "mid")
    assert divider.params == {"rtop": 1e3, "rbot": Expression("rtop")}
    two = c.subcircuits["twostage"]
    assert two.ports == ("in", "out", "gnd2") and two.params == {"r": 1e3}
    assert two.elements == [
        SubcircuitCall("XA", ("in", "gnd2", "m1"), "divider", {"rtop": Expression("r")}),
        SubcircuitCall(
            "XB",
            ("m1", "gnd2", "out"),
            "divider",
            {"rtop": Expression("2*r"), "rbot": Expression("r")},
        ),
    ]
    assert list(two.subcircuits) == ["buffer"]  # nested definition stays local
    assert two.subcircuits["buffer"].elements == [Vcvs("Ebuf", "o", "0", "i", "0", 1.0)]
    assert c.element("X1").params == {"r": Expression("rbase*scale")}
    assert c.element("Rprobe").resistance == 1e9


def test_include_and_lib_section():
    c = read("include_main.cir")
    assert list(c.models) == ["dsig", "dfast"]  # only the 'fast' section of sections.lib
    assert c.models["dfast"].params == {"is": 1e-9, "n": 1.5, "tt": 1e-9}
    limiter = c.subcircuits["limiter"]
    assert limiter.params == {"r": 1e3}
    assert [e.name for e in limiter.elements] == ["Rs", "D1", "D2"]
    assert c.element("X1") == SubcircuitCall("X1", ("in", "out"), "limiter", {"r": 2.2e3})


def test_pwl_and_current_sources():
    c = read("pwl_sources.cir")
    assert c.element("Vpwl").waveform == Pwl(((0.0, 0.0), (1e-3, 1.0), (2e-3, 1.0), (3e-3, 0.0)))
    ipwl = c.element("Ipwl")
    assert isinstance(ipwl, CurrentSource) and (ipwl.positive, ipwl.negative) == ("0", "b")
    assert ipwl.waveform == Pwl(((0.0, 0.0), (1e-3, 1e-3), (2e-3, 1e-3), (3e-3, 0.0)))
    assert c.element("Idc").dc == 2e-3
    assert c.element("Isin").waveform == Sin(0.0, 1e-3, 1e3)


def test_rlc_with_control_block():
    c = read("rlc_ringing.cir")
    assert c.element("L1") == Inductor("L1", "n1", "n2", 1e-3, ic=10e-3)
    assert c.element("C1") == Capacitor("C1", "n2", "0", 1e-6, ic=0.0)
    assert c.options == {"method": "gear", "maxord": 2.0}
    assert len(c.control) == 1
    assert c.control[0].splitlines() == [
        "run",
        "* meas kept here: ngspice-only, not interpreted by the reader",
        "meas tran vmax MAX v(n2)",
    ]
    f0 = 1 / (2 * math.pi * math.sqrt(c.element("L1").inductance * c.element("C1").capacitance))
    assert f0 == pytest.approx(5.03e3, rel=1e-3)  # the comment in the file


def test_harmonic_oscillator():
    c = read("harmonic_oscillator.cir")
    assert c.params == {"r": 10e3, "c": 100e-9}
    assert c.initial_conditions == {"x": 1.0, "y": 0.0, "xm": -1.0}
    assert [e.name for e in c.elements] == ["Xi1", "Xi2", "Xinv"]
    assert c.element("Xi1").params == {"r": Expression("R"), "c": Expression("C")}
