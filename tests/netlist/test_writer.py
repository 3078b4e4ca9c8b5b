"""The writer's text per dialect on small circuits, checked against SPICE syntax by hand.

The expected lines below are written from the simulators' manuals (ngspice 39 manual, LTspice
help, SPICE3f5 for Multisim), not produced by running our writer.
"""

import pytest

from circuitsim.netlist.circuit import (
    AcSweep,
    Capacitor,
    Cccs,
    Ccvs,
    Circuit,
    CurrentSource,
    Diode,
    Expression,
    Inductor,
    Model,
    OperatingPoint,
    Pulse,
    Pwl,
    Resistor,
    Sin,
    Subcircuit,
    SubcircuitCall,
    Switch,
    Transient,
    Vccs,
    Vcvs,
    VoltageSource,
)
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.writer import save_netlist, write_netlist

DIALECTS = ["ngspice", "ltspice", "multisim"]


def _rc() -> Circuit:
    c = Circuit(title="RC step")
    c.add(
        VoltageSource("V1", "in", "0", waveform=Pulse(0.0, 1.0, 0.0, 1e-9, 1e-9, 1e-3, 2e-3)),
        Resistor("R1", "in", "out", 1e3),
        Capacitor("C1", "out", "0", 1e-6, ic=0.0),
    )
    c.analyses.append(Transient(1e-5, 5e-3))
    return c


@pytest.mark.parametrize("dialect", DIALECTS)
def test_rc_text_is_plain_spice_in_every_dialect(dialect):
    # The title is a comment line (spicelib's editor reads a bare first line as a part);
    # LTspice gets plotwinsize=0 (no lossy compression of the waveforms).
    options = ".options plotwinsize=0\n" if dialect == "ltspice" else ""
    assert write_netlist(_rc(), dialect) == (
        "* RC step\n"
        "V1 in 0 PULSE(0 1 0 1n 1n 1m 2m)\n"
        "R1 in out 1k\n"
        "C1 out 0 1u IC=0\n"
        f"{options}"
        ".tran 10u 5m\n"
        ".end\n"
    )


def test_every_element_line():
    c = Circuit(title="all")
    c.add(
        Inductor("L1", "a", "b", 2.2e-3, ic=1e-3),
        VoltageSource("V2", "a", "0", dc=5.0, ac_magnitude=1.0, ac_phase=90.0),
        CurrentSource("I1", "b", "0", dc=1e-3),
        Vcvs("E1", "c", "0", "a", "b", 10.0),
        Vccs("G1", "c", "0", "a", "b", 2e-3),
        Cccs("F1", "c", "0", "V2", 3.0),
        Ccvs("H1", "c", "0", "V2", 50.0),
        Diode("D1", "a", "c", "dmod"),
        Diode("D2", "a", "c", "dmod", area=2.0),
        Switch("S1", "a", "c", "b", "0", model="smod", initial="off"),
        SubcircuitCall("X1", ("a", "c"), "blk", {"r": 470.0}),
    )
    lines = write_netlist(c).splitlines()[1:-1]
    assert lines == [
        "L1 a b 2.2m IC=1m",
        "V2 a 0 DC 5 AC 1 90",
        "I1 b 0 DC 1m",
        "E1 c 0 a b 10",
        "G1 c 0 a b 2m",
        "F1 c 0 V2 3",
        "H1 c 0 V2 50",
        "D1 a c dmod",
        "D2 a c dmod 2",
        "S1 a c b 0 smod OFF",
        "X1 a c blk r=470",
    ]


def test_source_shapes_trim_trailing_defaults():
    c = Circuit(title="shapes")
    c.add(
        VoltageSource("V1", "a", "0", waveform=Sin(0.0, 1.0, 50.0)),
        VoltageSource("V2", "b", "0", waveform=Sin(0.5, 1.0, 50.0, 0.0, 0.0, 30.0)),
        VoltageSource("V3", "c", "0", waveform=Pulse(0.0, 5.0, 1e-3)),
        VoltageSource("V4", "d", "0", dc=1.0, waveform=Pwl(((0.0, 0.0), (1e-3, 2.5)))),
    )
    lines = write_netlist(c).splitlines()[1:-1]
    assert lines == [
        "V1 a 0 SIN(0 1 50)",
        "V2 b 0 SIN(0.5 1 50 0 0 30)",
        # Infinite width, no period: SPICE's defaults (pw = per = tstop), so left out.
        "V3 c 0 PULSE(0 5 1m 0 0)",
        "V4 d 0 DC 1 PWL(0 0 1m 2.5)",
    ]


def test_switch_model_parameters_per_dialect():
    c = Circuit(title="sw")
    c.models["smod"] = Model("smod", "SW", {"vt": 0.5, "vh": 0.1, "ron": 1.0, "roff": 1e6})
    c.models["dmod"] = Model("dmod", "D", {"is": 1e-14, "n": 1.8})
    texts = {d: write_netlist(c, d).splitlines()[1:3] for d in DIALECTS}
    assert texts["ngspice"] == [
        ".model smod SW(vt=0.5 vh=0.1 ron=1 roff=1Meg)",
        ".model dmod D(is=10f n=1.8)",
    ]
    assert texts["ltspice"][0] == ".model smod SW(Vt=0.5 Vh=0.1 Ron=1 Roff=1Meg)"
    assert texts["multisim"][0] == ".model smod SW(VT=0.5 VH=0.1 RON=1 ROFF=1Meg)"


def test_negative_hysteresis_gets_a_note_for_ltspice_only():
    c = Circuit(title="sw")
    c.models["smod"] = Model("smod", "SW", {"vt": 0.0, "vh": -0.1})
    assert "Vh" in write_netlist(c, "ltspice").splitlines()[1]
    assert "* circuitsim:" not in write_netlist(c, "ngspice")


def test_expressions_power_and_logarithm_per_dialect():
    c = Circuit(title="expr")
    c.params["a"] = Expression("2^3 + 10**2")
    c.params["b"] = Expression("log(a) + log10(a) + LOG (2)")
    c.add(Resistor("R1", "x", "0", Expression("a*b")))
    params = {d: write_netlist(c, d).splitlines()[1:3] for d in DIALECTS}
    assert params["ngspice"] == [".param a={2**3 + 10**2}", ".param b={ln(a) + log10(a) + ln(2)}"]
    # LTspice reads ^ as Boolean XOR: the power must be **. Never the ambiguous log.
    assert params["ltspice"] == params["ngspice"]
    # Multisim: ** is its default-mode power (^ would be XOR under .SYNTAX PS).
    assert params["multisim"] == params["ngspice"]


def test_nested_subcircuit_with_parameters():
    inner = Subcircuit(
        "half", ("p", "q"), [Resistor("R1", "p", "q", Expression("rr/2"))], params={"rr": 1e3}
    )
    outer = Subcircuit(
        "div",
        ("in", "out"),
        [
            SubcircuitCall("X1", ("in", "out"), "half", {"rr": Expression("rtop")}),
            Resistor("R2", "out", "0", Expression("rtop")),
        ],
        subcircuits={"half": inner},
        params={"rtop": 2e3},
    )
    c = Circuit(title="nest", subcircuits={"div": outer})
    c.add(SubcircuitCall("XD", ("a", "b"), "div", {"rtop": 4.7e3}))
    assert write_netlist(c).splitlines()[1:9] == [
        ".subckt div in out params: rtop=2k",
        ".subckt half p q params: rr=1k",
        "R1 p q {rr/2}",
        ".ends half",
        "X1 in out half rr={rtop}",
        "R2 out 0 {rtop}",
        ".ends div",
        "XD a b div rtop=4700",
    ]


def test_directives():
    c = _rc()
    c.initial_conditions = {"out": 0.5, "in": 0.0}
    c.options = {"reltol": 1e-4, "method": "gear", "noacct": True}
    c.analyses = [
        Transient(1e-6, 1e-3, 1e-4, 1e-6, uic=True),
        OperatingPoint(),
        AcSweep("dec", 10, 1.0, 1e6),
    ]
    c.control = ["run\nprint v(out)"]
    lines = write_netlist(c).splitlines()
    assert lines[4:] == [
        ".ic v(out)=0.5 v(in)=0",
        ".options reltol=100u method=gear noacct",
        ".tran 1u 1m 100u 1u uic",
        ".op",
        ".ac dec 10 1 1Meg",
        ".control",
        "run",
        "print v(out)",
        ".endc",
        ".end",
    ]
    for dialect in ("ltspice", "multisim"):
        text = write_netlist(c, dialect)
        assert "\n.control" not in text and "print v(out)" not in text
        assert f"* circuitsim: .control block dropped ({dialect} has none)" in text


def test_long_pwl_is_continued_and_no_line_is_long():
    points = tuple((k * 1.234567e-5, (-1.0) ** k * 0.123456789) for k in range(200))
    c = Circuit(title="pwl", elements=[VoltageSource("V1", "a", "0", waveform=Pwl(points))])
    for dialect in DIALECTS:
        lines = [x for x in write_netlist(c, dialect).splitlines() if not x.startswith(".options")]
        assert max(len(line) for line in lines) <= 80
        assert lines[1].startswith("V1 a 0 PWL(0 0.123456789 ")
        assert all(line.startswith("+ ") for line in lines[2:-1])
        assert lines[-2].endswith(")")


def test_multisim_renames_nodes_it_cannot_take():
    c = Circuit(title="names")
    c.add(Resistor("R1", "n.1", "0", 1.0), Resistor("R2", "n_1", "n.1", 1.0))
    text = write_netlist(c, "multisim")
    assert "R1 n_1_2 0 1" in text and "R2 n_1 n_1_2 1" in text
    assert "* circuitsim: node 'n.1' renamed 'n_1_2'" in text
    # ngspice takes the dot: nothing renamed.
    assert "R1 n.1 0 1" in write_netlist(c, "ngspice")


def test_unwritable_values_raise():
    c = Circuit(title="bad", elements=[Resistor("R1", "a", "0", float("nan"))])
    with pytest.raises(NetlistError, match="cannot write the value nan"):
        write_netlist(c)
    c = Circuit(
        title="bad", elements=[VoltageSource("V1", "a", "0", waveform=Pulse(0.0, 1.0, period=1.0))]
    )
    with pytest.raises(NetlistError, match="V1: a PULSE with a period needs a finite width"):
        write_netlist(c)
    with pytest.raises(
        NetlistError, match="unknown dialect 'pspice'; choose one of ngspice, ltspice, multisim"
    ):
        write_netlist(c, "pspice")


def test_save_netlist_is_atomic(tmp_path):
    path = tmp_path / "rc.cir"
    save_netlist(_rc(), path, "ltspice")
    assert path.read_text() == write_netlist(_rc(), "ltspice")
    bad = Circuit(title="bad", elements=[Resistor("R1", "a", "0", float("inf"))])
    with pytest.raises(NetlistError):
        save_netlist(bad, path)
    # The failed write left the earlier file whole and no temporary file behind.
    assert path.read_text() == write_netlist(_rc(), "ltspice")
    assert [p.name for p in tmp_path.iterdir()] == ["rc.cir"]


@pytest.mark.parametrize(
    "element",
    [Resistor("X1", "a", "0", 1.0), Capacitor("C 1", "a", "0", 1.0), Diode("D(1)", "a", "0", "d")],
    ids=["wrong-letter", "space", "parenthesis"],
)
def test_names_spice_cannot_read_back_raise(element):
    c = Circuit(title="names", elements=[element])
    with pytest.raises(NetlistError, match="cannot write element"):
        write_netlist(c)


def test_instance_parameters_keyword_only_for_multisim():
    c = Circuit(title="x", elements=[SubcircuitCall("X1", ("a", "b"), "blk", {"r": 1e3})])
    lines = {d: write_netlist(c, d).splitlines()[1] for d in DIALECTS}
    assert lines["ngspice"] == lines["ltspice"] == "X1 a b blk r=1k"
    assert lines["multisim"] == "X1 a b blk params: r=1k"
    assert (
        write_netlist(
            Circuit(title="x", elements=[SubcircuitCall("X2", ("a",), "b")]), "multisim"
        ).splitlines()[1]
        == "X2 a b"
    )


def test_sin_phase_gets_a_note_for_multisim_only():
    c = Circuit(
        title="sin",
        elements=[VoltageSource("V1", "a", "0", waveform=Sin(0.0, 1.0, 50.0, 0.0, 0.0, 90.0))],
    )
    note = "* circuitsim: V1: SIN phase (6th field) is an ngspice/LTspice extension"
    assert note in write_netlist(c, "multisim")
    assert "* circuitsim" not in write_netlist(c, "ngspice") + write_netlist(c, "ltspice")
