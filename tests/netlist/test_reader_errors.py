"""Each reader error: its exact message, its line number, and that it is a NetlistError."""


import pytest

from circuitsim.netlist import reader as reader_module
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.reader import NetlistWarning, parse_netlist, read_netlist

V_USAGE = "(expected: Vname n+ n- [[DC] v] [AC mag [phase]] [SIN|PULSE|PWL(...)])"
R_USAGE = "(expected: Rname n+ n- value)"
E_USAGE = "(expected: Ename n+ n- nc+ nc- gain | POLY(n) nc1+ nc1- ... p0 p1 ...)"
F_USAGE = "(expected: Fname n+ n- vcontrol gain | POLY(n) v1 ... p0 p1 ...)"
TRAN = "(expected: .tran tstep tstop [tstart [tmax]] [uic])"

# name: (netlist text, line number, exact message)
ERRORS = {
    "resistor without value": ("t\nR1 a b\n", 2, f"missing value {R_USAGE}"),
    "resistor extra field": ("t\nR1 a b 1k 2k\n", 2, f"unexpected '2k' {R_USAGE}"),
    "ambiguous 4k7": (
        "t\n* c\nR1 a b 4k7\n",
        3,
        "bad number for value: not a number: '4k7' (found 'k7' after the number, where only a "
        "scale suffix and unit letters may follow, e.g. 4.7k or 10uF; write 4.7k, not 4k7)",
    ),
    "huge number": (
        "t\nR1 a b 1e999\n",
        2,
        "bad number for value: number out of range: '1e999' (beyond the float range)",
    ),
    "unsupported element": (
        "t\nK1 l1 l2 0.9\n",
        2,
        "unsupported element type 'K' in 'K1' (supported: C D E F G H I J L Q R S V X)",
    ),
    "unsupported directive": (
        "t\n.temp 27\n",
        2,
        "unsupported directive '.temp' (supported: .ac .endl .ends .ic .inc .include .lib "
        ".model .op .opt .option .options .param .subckt .title .tran)",
    ),
    "global": (
        "t\n.global vcc\n",
        2,
        ".global is not supported: only ground 0 (alias gnd) is global; pass the node through "
        "the subcircuit's ports instead",
    ),
    "leading continuation": (
        "t\n+ R1 a b 1k\n",
        2,
        "continuation line '+' with no line before it to continue",
    ),
    "error on a continued line reports its first line": (
        "t\nR1 a\n* a comment between\n+ b\n+ 1q1\n",
        2,
        "bad number for value: not a number: '1q1' (found 'q1' after the number, where only a "
        "scale suffix and unit letters may follow, e.g. 4.7k or 10uF)",
    ),
    "unbalanced brace": ("t\nR1 a b {2*x\n", 2, "unbalanced '{' at column 8: no matching '}'"),
    "stray brace": ("t\nR1 a b 2}\n", 2, "unbalanced '}' at column 9: no '{' before it"),
    "bad expression": (
        "t\nR1 a b {2*}\n",
        2,
        "bad expression for value: unexpected end of the expression at column 3 in '2*'",
    ),
    "empty expression": ("t\nR1 a b {}\n", 2, f"empty expression for value {R_USAGE}"),
    "unclosed quote": ("t\nR1 a b 'x*2\n", 2, 'unbalanced quote at column 8: no closing "\'"'),
    "capacitor parameter": (
        "t\nC1 a b 1u TC=1\n",
        2,
        "unsupported parameter 'tc' (expected: Cname n+ n- value [IC=v])",
    ),
    "IC without value": (
        "t\nC1 a b 1u IC=\n",
        2,
        "missing value of IC (expected: Cname n+ n- value [IC=v])",
    ),
    "SIN too short": ("t\nV1 a 0 SIN(0 1)\n", 2, f"SIN takes 3 to 6 values, got 2 {V_USAGE}"),
    "SIN unclosed": ("t\nV1 a 0 SIN(0 1 1k\n", 2, f"missing ')' to close SIN( {V_USAGE}"),
    "PULSE too long": (
        "t\nV1 a 0 PULSE(0 1 2 3 4 5 6 7)\n",
        2,
        f"PULSE takes 2 to 7 values, got 8 {V_USAGE}",
    ),
    "PWL odd": (
        "t\nV1 a 0 PWL(0 0 1)\n",
        2,
        f"PWL needs time-value pairs, got 3 value(s) {V_USAGE}",
    ),
    "PWL backwards": (
        "t\nV1 a 0 PWL(0 0 2m 1 1m 0)\n",
        2,
        f"PWL times must not decrease {V_USAGE}",
    ),
    "DC twice": ("t\nV1 a 0 DC 1 DC 2\n", 2, f"DC given twice {V_USAGE}"),
    "source junk": ("t\nV1 a 0 DC 1 foo\n", 2, f"unexpected 'foo' {V_USAGE}"),
    "VALUE": (
        "t\nE1 a 0 value={v(b)}\n",
        2,
        f"nonlinear form VALUE is not supported, only linear and POLY(n) {E_USAGE}",
    ),
    "POLY without coefficients": (
        "t\nE1 a 0 poly(2) b 0 c 0\n",
        2,
        f"POLY needs at least one coefficient {E_USAGE}",
    ),
    "E too short": ("t\nE1 a 0 b\n", 2, f"missing node nc- {E_USAGE}"),
    "F too short": ("t\nF1 a 0 V1\n", 2, f"missing gain {F_USAGE}"),
    "diode without model": (
        "t\nD1 a b\n",
        2,
        "missing model name (expected: Dname anode cathode model [area])",
    ),
    "switch flag": (
        "t\nS1 a b c d sm MAYBE\n",
        2,
        "expected ON or OFF, found 'maybe' (expected: Sname n+ n- nc+ nc- model [ON|OFF])",
    ),
    "X alone": (
        "t\nX1\n",
        2,
        "missing subcircuit name (expected: Xname node ... subckt [params: name=value ...])",
    ),
    "X param without value": (
        "t\nX1 a b sub params: r\n",
        2,
        "missing '=' after r (expected: Xname node ... subckt [params: name=value ...])",
    ),
    ".tran short": ("t\n.tran 1u\n", 2, f"missing tstop {TRAN}"),
    ".tran negative": ("t\n.tran -1u 1m\n", 2, f"tstep and tstop must be positive {TRAN}"),
    ".tran long": ("t\n.tran 1u 1m 0 1u 5\n", 2, f"unexpected '5' {TRAN}"),
    ".tran undefined param": (
        "t\n.tran 1u {tstop}\n",
        2,
        f"cannot evaluate tstop: undefined parameter 'tstop' in 'tstop' {TRAN}",
    ),
    ".ac variation": (
        "t\n.ac log 10 1 1k\n",
        2,
        "expected dec, oct or lin, found 'log' (expected: .ac dec|oct|lin points fstart fstop)",
    ),
    ".ac points": (
        "t\n.ac dec 2.5 1 1k\n",
        2,
        "number of points must be a positive integer, got 2.5 "
        "(expected: .ac dec|oct|lin points fstart fstop)",
    ),
    ".ic without v()": (
        "t\n.ic out=1\n",
        2,
        "expected v(node), found 'out' (expected: .ic v(node)=value ...)",
    ),
    ".param without value": (
        "t\n.param a\n",
        2,
        "expected name=value, found 'a' (expected: .param name=value)",
    ),
    ".param bad expression": (
        "t\n.param a={1+}\n",
        2,
        "bad expression for parameter 'a': unexpected end of the expression at column 3 in '1+'",
    ),
    ".param unbalanced": ("t\n.param a=(1+2\n", 2, "unbalanced parentheses or braces in .param"),
    ".model unbalanced": (
        "t\n.model d1 D(is=1\n",
        2,
        "unbalanced parentheses in the parameter list "
        "(expected: .model name kind(param=value ...))",
    ),
    ".model twice": ("t\n.model d1 D\n.model D1 D\n", 3, "model 'D1' defined twice"),
    ".ends alone": ("t\n.ends\n", 2, ".ends without a .subckt before it"),
    ".ends other name": (
        "t\n.subckt a x\n.ends b\n",
        3,
        ".ends b does not match the open .subckt a",
    ),
    "missing .ends": ("t\n.subckt amp x\nR1 x 0 1\n.end\n", 2, ".subckt amp has no .ends"),
    ".subckt twice": (
        "t\n.subckt a x\n.ends\n.subckt A y\n.ends\n",
        4,
        "subcircuit 'A' defined twice",
    ),
    "ground port": (
        "t\n.subckt a 0 x\n.ends\n",
        2,
        "ground (0) cannot be a subcircuit port "
        "(expected: .subckt name port ... [params: name=default ...])",
    ),
    ".tran in .subckt": (
        "t\n.subckt a x\n.tran 1u 1m\n.ends\n",
        3,
        ".tran is not allowed inside a .subckt",
    ),
    ".control without .endc": ("t\nR1 a 0 1\n.control\nrun\n", 3, ".control block without .endc"),
    ".include without file": ("t\n.include\n", 2, ".include needs a file name"),
    ".endl alone": ("t\n.endl\n", 2, ".endl without a .lib section before it"),
    ".op argument": ("t\n.op now\n", 2, "unexpected 'now' after .op"),
}


@pytest.mark.parametrize("name", list(ERRORS))
def test_error_message_and_line(name):
    text, line, message = ERRORS[name]
    with pytest.raises(NetlistError) as info:
        parse_netlist(text, source="case.cir")
    error = info.value
    assert (error.file, error.line, error.message) == ("case.cir", line, message)
    assert str(error).startswith(f"case.cir:{line}: {message}")
    physical = text.splitlines()[line - 1]
    assert error.text.strip() and error.text.split()[0] == physical.split()[0]


def test_include_not_found_names_both_places(tmp_path, monkeypatch):
    monkeypatch.setattr(reader_module, "LIBRARY_DIR", tmp_path / "lib")
    with pytest.raises(NetlistError) as info:
        parse_netlist("t\n\n.include nothere.inc\n", base_dir=str(tmp_path))
    assert info.value.line == 3
    assert info.value.message == (
        f"include file 'nothere.inc' not found (looked for {tmp_path / 'nothere.inc'} or "
        f"{tmp_path / 'lib' / 'nothere.inc'})"
    )


def test_include_cycle(tmp_path):
    (tmp_path / "a.inc").write_text("* a\n.include b.inc\n")
    (tmp_path / "b.inc").write_text("R1 x 0 1\n.include a.inc\n")
    (tmp_path / "main.cir").write_text("main\n.include a.inc\n.end\n")
    with pytest.raises(NetlistError) as info:
        read_netlist(tmp_path / "main.cir")
    a, b = (tmp_path / "a.inc").resolve(), (tmp_path / "b.inc").resolve()
    assert (info.value.file, info.value.line) == (str(b), 2)
    assert info.value.message == f"include cycle: {a} -> {b} -> {a}"


def test_error_inside_include_names_that_file(tmp_path):
    (tmp_path / "parts.inc").write_text("* parts\n\nR1 a b\n")
    with pytest.raises(NetlistError) as info:
        parse_netlist("t\n.include parts.inc\n", base_dir=str(tmp_path))
    assert (info.value.file, info.value.line) == (str((tmp_path / "parts.inc").resolve()), 3)


def test_missing_lib_section(tmp_path):
    (tmp_path / "x.lib").write_text(".lib a\n.model d1 D\n.endl\n")
    with pytest.raises(NetlistError) as info:
        parse_netlist("t\n.lib x.lib b\n", base_dir=str(tmp_path))
    assert info.value.line == 2
    assert (
        info.value.message == f"library section 'b' not found in {(tmp_path / 'x.lib').resolve()}"
    )


def test_library_folder_is_the_fallback(tmp_path, monkeypatch):
    lib = tmp_path / "lib"
    lib.mkdir()
    (lib / "mine.lib").write_text(".model dx D(is=1f)\n")
    monkeypatch.setattr(reader_module, "LIBRARY_DIR", lib)
    circuit = parse_netlist("t\n.lib mine.lib\n", base_dir=str(tmp_path))
    assert circuit.models["dx"].params == {"is": 1e-15}


def test_unreadable_file_is_a_netlist_error(tmp_path):
    with pytest.raises(NetlistError, match="cannot read netlist"):
        read_netlist(tmp_path / "absent.cir")
    (tmp_path / "bin.cir").write_bytes(b"title\nR1 a b \xff\xfe\n")
    with pytest.raises(NetlistError, match="cannot read netlist"):
        read_netlist(tmp_path / "bin.cir")


@pytest.mark.parametrize("directive", [".save", ".print", ".plot", ".probe", ".meas", ".measure"])
def test_output_requests_are_ignored_with_a_warning(directive):
    with pytest.warns(NetlistWarning, match=rf"case.cir:3: \{directive} ignored"):
        circuit = parse_netlist(f"t\nR1 a 0 1k\n{directive} tran v(a)\n", source="case.cir")
    assert [e.name for e in circuit.elements] == ["R1"]


def test_lines_after_end_are_refused():
    # ngspice 39 reads them (test_reader_alignment.py measures it), other SPICEs do not
    with pytest.raises(NetlistError, match="after .end") as info:
        parse_netlist("t\nR1 a 0 1k\n.END\nthis is not spice\n")
    assert info.value.line == 4


@pytest.mark.parametrize("name", ["a" * 5000, "a\x00b", "{(((1)))}"])
def test_include_names_the_filesystem_refuses_are_not_found(name):
    # found by the fuzz test: a 5000-character name made Path.is_file raise OSError
    with pytest.raises(NetlistError, match="not found") as info:
        parse_netlist(f"t\n.include {name}\n")
    assert info.value.line == 2


def test_a_subcircuit_header_with_many_ports_and_a_repeat_is_refused_naming_the_port():
    # 50,000 ports: the duplicate check was quadratic (a fuzzed 100 kB header: minutes)
    ports = " ".join(f"p{i}" for i in range(50_000)) + " p7"
    with pytest.raises(NetlistError, match=r"port 'p7' listed twice"):
        parse_netlist(f"* t\n.subckt big {ports}\nR1 p0 p1 1k\n.ends\n.end\n")
