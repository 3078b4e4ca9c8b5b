"""Reader features one at a time, each value checked against the text it came from."""

import warnings

import pytest

from circuitsim.netlist.circuit import (
    Capacitor,
    Expression,
    Model,
    Pulse,
    Pwl,
    Resistor,
    Sin,
    SubcircuitCall,
    VoltageSource,
)
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.reader import parse_netlist


def one(text):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return parse_netlist("title\n" + text)


def test_title_is_always_the_first_line():
    assert parse_netlist("R1 a 0 1k\nR2 a 0 2k\n").elements == [Resistor("R2", "a", "0", 2e3)]
    assert parse_netlist("* looks like a comment\nR2 a 0 2k\n").title == "* looks like a comment"
    assert parse_netlist("t\n.title Real Title\n").title == "Real Title"
    assert parse_netlist("").elements == []


def test_comments():
    c = one("R1 a b 1k ; semicolon\nR2 a b 2k $ dollar\n  * indented star\nR3 a$b c 3k\n")
    assert [(e.name, e.positive, e.resistance) for e in c.elements] == [
        ("R1", "a", 1e3),
        ("R2", "a", 2e3),
        ("R3", "a$b", 3e3),  # '$' inside a word is part of the name, as in ngspice
    ]


def test_continuations_join_with_comments_between():
    c = one("V1 a 0\n* comment\n+ PULSE(0 5\n\n+ 1m 1u 1u 2m 4m) ; done\n")
    assert c.element("V1").waveform == Pulse(0.0, 5.0, 1e-3, 1e-6, 1e-6, 2e-3, 4e-3)


def test_case_insensitive_keywords_and_nodes():
    c = one("Vin IN Gnd dc 1 AC 2 45\nR1 In OUT 1K\n.TRAN 1U 1M UIC\n.Op\n")
    v = c.element("VIN")
    assert (v.name, v.positive, v.negative, v.dc, v.ac_magnitude, v.ac_phase) == (
        "Vin", "in", "0", 1.0, 2.0, 45.0,
    )  # fmt: skip
    assert c.element("r1").nodes == ("in", "out")
    assert c.transient.uic and c.transient.tstep == 1e-6


@pytest.mark.parametrize(
    ("line", "expected"),
    [
        ("V1 a 0", VoltageSource("V1", "a", "0")),
        ("V1 a 0 5", VoltageSource("V1", "a", "0", dc=5.0)),
        ("V1 a 0 DC=5", None),
        ("V1 a 0 AC", VoltageSource("V1", "a", "0", ac_magnitude=1.0)),
        ("V1 a 0 ac 2", VoltageSource("V1", "a", "0", ac_magnitude=2.0)),
        ("V1 a 0 {vdd}", VoltageSource("V1", "a", "0", dc=Expression("vdd"))),
        ("V1 a 0 vdd", VoltageSource("V1", "a", "0", dc=Expression("vdd"))),
        ("V1 a 0 SIN 0 1 1k", VoltageSource("V1", "a", "0", waveform=Sin(0.0, 1.0, 1e3))),
        (
            "V1 a 0 sin(1, 2, 50, 1m, 10, 90) dc 1",
            VoltageSource("V1", "a", "0", dc=1.0, waveform=Sin(1.0, 2.0, 50.0, 1e-3, 10.0, 90.0)),
        ),
        (
            "V1 a 0 SIN (0 {amp} 1k) AC 1",
            VoltageSource(
                "V1", "a", "0", ac_magnitude=1.0, waveform=Sin(0.0, Expression("amp"), 1e3)
            ),
        ),
        ("V1 a 0 pulse(0 1)", VoltageSource("V1", "a", "0", waveform=Pulse(0.0, 1.0))),
        (
            "V1 a 0 PWL 0 0 1m 1 dc 0.5",
            VoltageSource("V1", "a", "0", dc=0.5, waveform=Pwl(((0.0, 0.0), (1e-3, 1.0)))),
        ),
        (
            "V1 a 0 PWL({t1} 0 {t2} 1)",
            VoltageSource(
                "V1", "a", "0", waveform=Pwl(((Expression("t1"), 0.0), (Expression("t2"), 1.0)))
            ),
        ),
    ],
)
def test_source_forms(line, expected):
    if expected is None:
        with pytest.raises(NetlistError, match="expected DC value, found '='"):
            one(line)
    else:
        assert one(line).elements == [expected]


def test_quoted_expressions_and_bare_names():
    c = one("C1 a 0 'cval*2' IC={v0/2}\nR1 a 0 rload\n")
    assert c.element("C1") == Capacitor("C1", "a", "0", Expression("cval*2"), Expression("v0/2"))
    assert c.element("R1").resistance == Expression("rload")


def test_params_keep_order_and_forms():
    c = one(".param b=2 a = {b*3}\n+ c=sqrt(a) + 1, d='a/2' e=1k\n.PARAM F=2*e\n")
    assert c.params == {
        "b": 2.0,
        "a": Expression("b*3"),
        "c": Expression("sqrt(a) + 1"),
        "d": Expression("a/2"),
        "e": 1e3,
        "f": Expression("2*e"),
    }
    assert list(c.params) == ["b", "a", "c", "d", "e", "f"]


def test_tran_and_ac_accept_parameter_expressions():
    c = one(".param tstop=10m n=10\n.tran {tstop/1000} {tstop}\n.ac dec {n} 1 {1/tstop}\n")
    assert (c.transient.tstep, c.transient.tstop) == (10e-6, 10e-3)
    assert (c.analyses[1].points, c.analyses[1].fstop) == (10, 100.0)


def test_models_with_and_without_parentheses():
    c = one(".model D1 D IS=1f N=2\n.MODEL sw1 SW (vt=1, vh=0.5)\n.model q NPN(bf=100)\n")
    assert c.models == {
        "d1": Model("D1", "D", {"is": 1e-15, "n": 2.0}),
        "sw1": Model("sw1", "SW", {"vt": 1.0, "vh": 0.5}),
        "q": Model("q", "NPN", {"bf": 100.0}),  # kept, though no element uses it
    }


def test_options_flags_and_words():
    c = one(".options noacct reltol=1m method=GEAR\n.option gmin={1p}\n.opt abstol=-1\n")
    assert c.options == {
        "noacct": True,
        "reltol": 1e-3,
        "method": "gear",
        "gmin": 1e-12,  # an expression is evaluated when it can be
        "abstol": -1.0,
    }


def test_initial_conditions():
    c = one(".ic v(a)=1 V(B)=-2m\n+ v(gnd)=0 v(c)={x}\n")
    assert c.initial_conditions == {"a": 1.0, "b": -2e-3, "0": 0.0, "c": Expression("x")}


def test_subckt_forms():
    c = one(
        ".subckt amp in out params: g=2 h={g*2}\nE1 out 0 in 0 {g}\n.ends amp\n"
        ".SUBCKT buf in out g=1\n.param k=3\nE1 out 0 in 0 {g*k}\n.ENDS\n"
        "X1 a b amp\nX2 a b AMP g=5\nX3 a b buf params: g={x}\nX4 amp\n"
    )
    assert c.subcircuits["amp"].params == {"g": 2.0, "h": Expression("g*2")}
    assert c.subcircuits["buf"].params == {"g": 1.0, "k": 3.0}  # body .param is local
    assert c.elements == [
        SubcircuitCall("X1", ("a", "b"), "amp"),
        SubcircuitCall("X2", ("a", "b"), "amp", {"g": 5.0}),
        SubcircuitCall("X3", ("a", "b"), "buf", {"g": Expression("x")}),
        SubcircuitCall("X4", (), "amp"),
    ]
    assert c.params == {}


def test_include_with_quotes_and_inc_alias(tmp_path):
    (tmp_path / "my parts.inc").write_text("R9 x 0 9k\n.end\n* a comment after .end\n")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "inner.inc").write_text(".inc ../other.inc\n")
    (tmp_path / "other.inc").write_text(".param cv=9p\n")
    c = parse_netlist(
        't\n.include "my parts.inc"\n.INC sub/inner.inc\n.include sub/inner.inc\nC9 x 0 {cv}\n',
        base_dir=str(tmp_path),
    )
    # .end inside an include ends only that file (a card after it is refused, see
    # test_reader_alignment.py); a file may be included twice (no cycle;
    # twice is harmless for a .param, while an element would be defined twice)
    assert [e.name for e in c.elements] == ["R9", "C9"]
    assert c.params == {"cv": 9e-12}


def test_lib_sections_skip_unselected_text(tmp_path):
    (tmp_path / "m.lib").write_text(
        "* header\n.lib typ\n.model dm D(is=1n)\n.endl typ\n.lib worst\n.model dm D(is=9n)\n.endl\n"
    )
    c = parse_netlist("t\n.lib m.lib worst\n", base_dir=str(tmp_path))
    assert c.models["dm"].params == {"is": 9e-9}
    c = parse_netlist("t\n.lib 'm.lib' TYP\n", base_dir=str(tmp_path))
    assert c.models["dm"].params == {"is": 1e-9}


def test_control_blocks_kept_raw_in_order():
    c = one(
        ".control\nset x = 1 ; not a comment to us\n+ raw\n.endc\nR1 a 0 1\n.control\nrun\n.endc\n"
    )
    assert c.control == ["set x = 1 ; not a comment to us\n+ raw", "run"]
    with pytest.raises(NetlistError, match="endc without a .control"):
        one(".endc\n")


def test_crlf_and_bom():
    c = parse_netlist("\ufefftitle\r\nR1 a 0 1k\r\n+ \r\n.end\r\n")
    assert c.title == "title" and c.elements == [Resistor("R1", "a", "0", 1e3)]


def test_long_lines_stay_linear():
    # 200k blanks between .param values once cost quadratic time in the value splitter
    c = one(".param a=1" + " " * 200_000 + "b=2\n")
    assert c.params == {"a": 1.0, "b": 2.0}


def test_many_lib_sections_stay_linear(tmp_path):
    body = "".join(f".lib s{i}\n.model d{i} D(is={i + 1}f)\n.endl\n" for i in range(3000))
    (tmp_path / "big.lib").write_text(body)
    c = parse_netlist("t\n.lib big.lib s2999\n", base_dir=str(tmp_path))
    assert c.models == {"d2999": Model("d2999", "D", {"is": 3000e-15})}
