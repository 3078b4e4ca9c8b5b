"""The reader agrees with ngspice 39 where a fuzz probe found them apart (issue 21), or refuses.

Each case pairs our reader's answer with ngspice's, measured by running ``ngspice -b`` on the
same text (``-n``: no init files; a private folder as working directory).
"""

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.expressions import NGSPICE_FUNCTIONS, evaluate
from circuitsim.netlist.flatten import flatten
from circuitsim.netlist.reader import parse_netlist
from circuitsim.netlist.topology import check_circuit

requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)


def ngspice_op(text: str, folder: Path) -> tuple[dict[str, float], str]:
    """Node voltages printed by ``ngspice -b -n`` for a netlist with ``.op``, and its log."""
    path = folder / "deck.cir"
    path.write_text(text, encoding="utf-8")
    result = subprocess.run(
        ["ngspice", "-b", "-n", str(path)], capture_output=True, timeout=60, cwd=folder
    )
    log = (result.stdout + result.stderr).decode("utf-8", "replace")
    voltages = {}
    for line in log.splitlines():
        match = re.fullmatch(r"\s+(\S+)\s+([-+]?[0-9.]+e[-+][0-9]+)\s*", line)
        if match and not match[1].endswith("#branch"):
            voltages[match[1]] = float(match[2])
    return voltages, log


DIVIDER = "divider\nV1 a 0 1\nR1 a b 1k\nR2 b 0 1k\n.op\n"


# --- min/max of one argument --------------------------------------------------------------


@pytest.mark.parametrize(("text", "value"), [("min(1)", 1.0), ("max(2)", 2.0), ("min(3,1)", 1.0)])
def test_min_and_max_accept_one_argument(text, value):
    assert evaluate(text, {}) == value


@requires_ngspice
def test_min_max_of_one_argument_as_ngspice(tmp_path):
    text = "t\n.param x={min(1)} y={max(2)}\nV1 a 0 {x+y}\nR1 a 0 1k\n.op\n.end\n"
    voltages, _ = ngspice_op(text, tmp_path)
    assert voltages["a"] == pytest.approx(3.0)
    flat = flatten(parse_netlist(text))
    assert flat.element("V1").dc == 3.0


# --- text after .end -----------------------------------------------------------------------


@requires_ngspice
def test_ngspice_reads_cards_after_end_so_the_reader_refuses_them(tmp_path):
    text = DIVIDER + ".end\nR3 b 0 1\n"
    voltages, _ = ngspice_op(text, tmp_path)
    # ngspice reads R3 (1 ohm across R2): v(b) = 1/1001 V, not the divider's 0.5 V
    assert voltages["b"] == pytest.approx(1 / 1001, rel=1e-3)
    with pytest.raises(NetlistError, match="after .end") as info:
        parse_netlist(text, source="deck.cir")
    assert info.value.line == 7


def test_comments_blank_lines_and_a_second_end_after_end_are_fine():
    circuit = parse_netlist(DIVIDER + ".end\n\n* a note\n.END\n")
    assert [e.name for e in circuit.elements] == ["V1", "R1", "R2"]


def test_a_card_after_end_in_an_included_file_is_refused(tmp_path):
    (tmp_path / "part.inc").write_text("R9 b 0 1k\n.end\nR10 b 0 1\n")
    with pytest.raises(NetlistError, match="after .end") as info:
        parse_netlist(DIVIDER + ".include part.inc\n.end\n", base_dir=str(tmp_path))
    assert info.value.line == 3 and info.value.file.endswith("part.inc")


# --- digits of other scripts ---------------------------------------------------------------


@pytest.mark.parametrize("digits", ["\uff11\uff10", "\u0661\u0660", "\u0967\u0966"])
@pytest.mark.parametrize("where", ["V1 a 0 {}", "V1 a 0 {{{}*1}}", ".param p={}\nV1 a 0 {{p}}"])
def test_digits_of_other_scripts_are_not_numbers(digits, where):
    text = "t\n" + where.format(digits) + "\nR1 a 0 1k\n.op\n.end\n"
    with pytest.raises(NetlistError):
        flatten(parse_netlist(text))


@requires_ngspice
def test_ngspice_refuses_fullwidth_digits_too(tmp_path):
    _, log = ngspice_op("t\nV1 a 0 \uff11\uff10\nR1 a 0 1k\n.op\n.end\n", tmp_path)
    assert re.search(r"error", log, re.IGNORECASE)


# --- tabs after directive keywords ---------------------------------------------------------


@requires_ngspice
def test_a_tab_after_tran_param_include_and_lib_is_a_blank(tmp_path):
    (tmp_path / "part.inc").write_text("R2 b 0 1k\n")
    (tmp_path / "sect.lib").write_text(".lib fast\nR3 b 0 1meg\n.endl\n")
    text = (
        "t\n.param\tr=3k\nV1 a 0 1\nR1 a b {r}\n.include\tpart.inc\n.lib\tsect.lib\tfast\n"
        ".tran\t1u\t10u\n.op\n.end\n"
    )
    circuit = parse_netlist(text, base_dir=str(tmp_path))
    assert circuit.transient is not None and circuit.transient.tstop == 10e-6
    assert [e.name for e in circuit.elements] == ["V1", "R1", "R2", "R3"]
    # ngspice -b runs only the .tran when there is one (and saves no data): the .op alone
    voltages, log = ngspice_op(text.replace(".tran\t1u\t10u\n", ""), tmp_path)
    assert "error" not in log.lower()
    # 1k || 1meg against 3k, as the reader has it
    parallel = 1 / (1 / 1e3 + 1 / 1e6)
    assert voltages["b"] == pytest.approx(parallel / (parallel + 3e3), rel=1e-4)


# --- function names as parameter names ----------------------------------------------------


@pytest.mark.parametrize("name", ["sqrt", "MIN", "log10", "nint"])
def test_a_function_name_cannot_name_a_parameter(name):
    with pytest.raises(NetlistError, match="name of a function") as info:
        parse_netlist(f"t\nV1 a 0 1\n.param {name}=2\n")
    assert info.value.line == 3
    with pytest.raises(NetlistError, match="name of a function"):
        parse_netlist(f"t\n.subckt s a b params: {name}=1\nR1 a b 1k\n.ends\n")


def test_pi_if_time_and_temper_remain_parameter_names():
    # ngspice 39 lets a parameter of these names win (measured: {pi+1} = 3 with pi=2)
    circuit = parse_netlist("t\n.param pi=2 if=1 time=1 temper=1\nV1 a 0 {pi+1}\nR1 a 0 1\n")
    assert flatten(circuit).element("V1").dc == 3.0


@requires_ngspice
def test_ngspice_fails_on_a_function_named_parameter(tmp_path):
    _, log = ngspice_op("t\n.param sqrt=2\nV1 a 0 {sqrt}\nR1 a 0 1k\n.op\n.end\n", tmp_path)
    assert "fatal" in log.lower() or "error" in log.lower()
    assert "sqrt" in NGSPICE_FUNCTIONS


# --- case folding: ASCII only, as ngspice's tolower ----------------------------------------


@requires_ngspice
def test_the_kelvin_sign_is_not_the_letter_k(tmp_path):
    text = "t\nV1 \u212a 0 1\nR1 k b 1k\nR2 b 0 1k\n.op\n.end\n"
    voltages, _ = ngspice_op(text, tmp_path)
    assert voltages["k"] == 0.0 and voltages["b"] == 0.0  # the source drives its own node
    circuit = parse_netlist(text)
    assert circuit.elements[0].nodes == ("\u212a", "0")
    assert circuit.elements[1].nodes == ("k", "b")
    # node k is joined to ground through R1 and R2 only: no finding of a short or a merge
    assert not [f for f in check_circuit(circuit) if "\u212a" in f.message and "k" in f.message]


def test_ascii_capitals_still_fold():
    circuit = parse_netlist("t\nV1 A 0 1\nR1 a B 1k\nR2 b GND 1k\n")
    assert [e.nodes for e in circuit.elements] == [("a", "0"), ("a", "b"), ("b", "0")]


# --- .options values -----------------------------------------------------------------------


def test_an_option_given_as_an_expression_is_evaluated_at_read_time():
    # found by the differential fuzz: ngspice takes reltol={1e-6*10}, our engine wanted a number
    circuit = parse_netlist("t\n.param tight=1e-6\n.options reltol={tight*10} abstol={1p*2}\n")
    assert circuit.options["reltol"] == pytest.approx(1e-5)
    assert circuit.options["abstol"] == pytest.approx(2e-12)


def test_an_option_with_digits_of_another_script_is_refused():
    # ngspice: "bad type given for option reltol"; Python's float() would read it as 1
    with pytest.raises(NetlistError, match="not a number") as info:
        parse_netlist("t\nR1 a 0 1\n.options reltol=\U0001d7e3\n")
    assert info.value.line == 3


# --- the end of a .control block ------------------------------------------------------------


@pytest.mark.parametrize("closer", [".endc", ".ENDC", ".endc;x", ".endc $ note", ".endcs"])
def test_a_control_block_ends_where_ngspice_ends_it(closer):
    # found by the differential fuzz: ".endc;x" did not end the block here, so the circuit's
    # cards after it were swallowed into the block; ngspice matches ".endc" as a prefix
    circuit = parse_netlist(f"t\n.control\nrun\n{closer}\nV1 a 0 1\nR1 a 0 1k\n.op\n.end\n")
    assert [e.name for e in circuit.elements] == ["V1", "R1"]
    assert circuit.control == ["run"]
