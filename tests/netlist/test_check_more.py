"""``check`` finds what ``simulate`` cannot run: bad values, zero resistors, nothing to solve.

The expectation for each netlist comes from outside the checker: our engine refuses it (the
solver is run on the same file and must raise), and, where ngspice refuses it too (an
undefined parameter), ngspice is run as the referee. ngspice quietly accepts a 0 ohm resistor
(as 1 milliohm) and never evaluates an unused ``.param``, so for those the engine's refusal is
the expectation: ``check`` answers "can this be simulated here".
"""

import shutil
import subprocess

import pytest

from circuitsim.cli import main
from circuitsim.netlist.circuit import Circuit, Resistor, VoltageSource
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.reader import parse_netlist
from circuitsim.netlist.topology import check_circuit

requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)

# name -> (netlist, expected (kind, elements) findings, words of the message)
CASES = {
    "undefined parameter": (
        "t\nV1 a 0 1\nR1 a 0 {rx}\n.op\n.end\n",
        [("undefined-parameter", ("R1",))],
        ["R1 resistance", "'rx'"],
    ),
    "division by zero": (
        "t\n.param p={1/0}\nV1 a 0 1\nR1 a 0 1k\n.op\n.end\n",
        [("bad-expression", ())],
        ["global parameter p", "division by zero"],
    ),
    "zero resistor": (
        "t\nV1 a 0 1\nR1 a 0 0\n.op\n.end\n",
        [("zero-resistance", ("R1",))],
        ["R1", "resistance 0"],
    ),
    "zero resistor by expression": (
        "t\n.param r=1k\nV1 a 0 1\nR1 a 0 {r-1000}\n.op\n.end\n",
        [("zero-resistance", ("R1",))],
        ["R1", "resistance 0"],
    ),
    "empty file": ("", [("no-nodes", ())], ["no nodes besides ground"]),
    "title only": ("* title only\n", [("no-nodes", ())], ["no nodes besides ground"]),
    "all on ground": (
        "t\nR1 0 0 1k\n.op\n.end\n",
        [("no-nodes", ())],
        ["no nodes besides ground"],
    ),
}


def _simple(findings):
    return [(f.kind, f.elements) for f in findings]


def _simulate(circuit):
    from circuitsim.solver import simulate

    return simulate(circuit)


@pytest.mark.parametrize("case", list(CASES))
def test_check_reports_what_the_engine_refuses(case):
    text, expected, words = CASES[case]
    circuit = parse_netlist(text, source="case.cir")
    findings = check_circuit(circuit)
    assert _simple(findings) == expected
    for word in words:
        assert word in findings[0].message
    with pytest.raises(ValueError):  # NetlistError and CircuitInputError are ValueErrors
        _simulate(circuit)


@requires_ngspice
@pytest.mark.ngspice
def test_ngspice_refuses_the_undefined_parameter_too(tmp_path):
    path = tmp_path / "undef.cir"
    path.write_text(CASES["undefined parameter"][0])
    done = subprocess.run(["ngspice", "-b", str(path)], capture_output=True, text=True, timeout=60)
    assert "Undefined parameter [rx]" in done.stdout + done.stderr


def test_every_bad_value_is_reported_once_not_just_the_first():
    text = (
        "t\n.param p={1/0} q={2*p}\n"
        ".subckt blk a params: r=1k\nR1 a 0 {r/w}\nC1 a 0 {sqrt(-r)}\n.ends\n"
        "V1 a 0 {q}\nX1 a blk r=2k\nX2 a blk r={zz}\nR5 a 0 0\nR6 a b {rx}\nR7 b 0 1k\n"
        ".ic v(a)={yy}\n.tran 1u 1m\n.end\n"
    )
    findings = check_circuit(parse_netlist(text))
    assert _simple(findings) == [
        ("bad-expression", ()),  # p; q and V1 use p and are not reported again
        ("undefined-parameter", ("R.X1.R1",)),
        ("bad-expression", ("C.X1.C1",)),
        ("undefined-parameter", ("X2",)),  # X2's body uses the failed r: not again
        ("undefined-parameter", ("R6",)),
        ("undefined-parameter", ()),  # .ic
        ("zero-resistance", ("R5",)),
    ]
    messages = [f.message for f in findings]
    assert "in X1: C1 capacitance: square root of a negative number" in messages[2]
    assert messages[3].startswith("X2 parameter r: undefined parameter 'zz'")
    assert messages[5].startswith(".ic v(a): undefined parameter 'yy'")


def test_top_level_values_are_checked_when_a_subcircuit_is_missing():
    text = "t\nV1 a 0 1\nX1 a nosuch\nR1 a 0 {rx}\nR2 a 0 0\n.op\n.end\n"
    kinds = _simple(check_circuit(parse_netlist(text)))
    assert kinds == [
        ("undefined-subcircuit", ("X1",)),
        ("undefined-parameter", ("R1",)),
        ("zero-resistance", ("R2",)),
    ]


def test_parameters_that_evaluate_give_no_findings():
    text = (
        "t\n.param rb=1k half={rb/2}\n.subckt blk a b params: r=1\nR1 a b {2*r}\n.ends\n"
        "V1 in 0 {sqrt(4)/2}\nR1 in out {half}\nX1 out 0 blk r={rb}\n.op\n.end\n"
    )
    circuit = parse_netlist(text)
    assert check_circuit(circuit) == []
    _simulate(circuit)  # and the engine runs it


def test_zero_resistor_in_a_circuit_built_in_python():
    circuit = Circuit("built")
    circuit.add(VoltageSource("V1", "in", "0", dc=1.0), Resistor("R1", "in", "0", 0.0))
    [finding] = check_circuit(circuit)
    assert finding.kind == "zero-resistance" and finding.nodes == ("in", "0")


@pytest.mark.parametrize("case", ["undefined parameter", "division by zero", "zero resistor"])
def test_cli_check_exits_1_with_the_finding(tmp_path, capsys, case):
    path = tmp_path / "case.cir"
    path.write_text(CASES[case][0])
    assert main(["check", str(path)]) == 1
    out = capsys.readouterr().out
    kind = CASES[case][1][0][0]
    assert out.startswith(f"{path}: {kind}: ")
    assert "no findings" not in out


@pytest.mark.parametrize("text", ["", "* title only\n"])
def test_cli_check_empty_netlists(tmp_path, capsys, text):
    path = tmp_path / "empty.cir"
    path.write_text(text)
    assert main(["check", str(path)]) == 1
    assert "no-nodes" in capsys.readouterr().out


def test_flatten_raises_by_default_and_collects_when_asked():
    from circuitsim.netlist.flatten import flatten

    circuit = parse_netlist("t\nV1 a 0 1\nR1 a 0 {rx}\n.op\n.end\n", source="x.cir")
    with pytest.raises(NetlistError, match="R1 resistance: undefined parameter 'rx'"):
        flatten(circuit)
    problems = []
    flat = flatten(circuit, problems)
    assert [str(p) for p in problems] == ["R1 resistance: undefined parameter 'rx' in 'rx'"]
    assert problems[0].undefined == "rx" and problems[0].element == "R1"
    assert flat.element("R1").resistance != flat.element("R1").resistance  # NaN stands in
