"""Duplicate element names: refused per scope by the reader, as ngspice refuses them.

ngspice 39 is the referee: a second ``R1`` (or ``r1``: names are case-insensitive) at the top
level or in one ``.subckt`` body stops it with "device already exists"; the same name at the
top level and in a body, in two bodies, or in two instances of one body is fine (instance
elements get prefixed names, ``r.x1.r1``). The reader must refuse exactly the first kind,
naming the file and line of the second definition and where the first one is.
"""

import shutil
import subprocess
from pathlib import Path

import pytest

from circuitsim.cli import main
from circuitsim.netlist.circuit import Circuit, Resistor, VoltageSource
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.flatten import flatten
from circuitsim.netlist.reader import parse_netlist, read_netlist
from circuitsim.netlist.topology import check_circuit

requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)

HALF = ".subckt half a b\nR1 a b 1k\nR2 b 0 1k\n.ends\n"

# name -> (netlist, line of the second definition, line of the first, scope words)
REFUSED = {
    "resistor": ("dup\nV1 in 0 DC 1\nR1 in out 1k\nR1 out 0 1k\n.op\n.end\n", 4, 3, ""),
    "other case": ("dup\nV1 in 0 DC 1\nR1 in out 1k\nr1 out 0 1k\n.op\n.end\n", 4, 3, ""),
    "capacitor": (
        "dup\nV1 in 0 DC 1\nR1 in out 1k\nC1 out 0 1u\nC1 in 0 1u\n.op\n.end\n",
        5,
        4,
        "",
    ),
    "inductor": (
        "dup\nV1 in 0 DC 1\nL1 in out 1m\nR1 out 0 1k\nL1 out 0 1m\n.op\n.end\n",
        5,
        3,
        "",
    ),
    "voltage source": ("dup\nV1 in 0 DC 1\nR1 in 0 1k\nV1 in 0 DC 2\n.op\n.end\n", 4, 2, ""),
    "current source": ("dup\nI1 0 a DC 1m\nR1 a 0 1k\nI1 0 a DC 1m\n.op\n.end\n", 4, 2, ""),
    "vcvs": ("dup\nV1 in 0 DC 1\nE1 o 0 in 0 2\nR1 o 0 1k\nE1 o 0 in 0 3\n.op\n.end\n", 5, 3, ""),
    "instance": (f"dup\n{HALF}V1 in 0 DC 1\nX1 in out half\nX1 out o2 half\n.op\n.end\n", 8, 7, ""),
    "in a body": (
        "dup\n.subckt half a b\nR1 a b 1k\nR1 b 0 1k\n.ends\nV1 in 0 DC 1\nX1 in out half\n"
        ".op\n.end\n",
        4,
        3,
        " in .subckt half",
    ),
}


def _ngspice(path: Path) -> str:
    done = subprocess.run(
        ["ngspice", "-b", str(path)], capture_output=True, text=True, timeout=120, cwd=path.parent
    )
    return done.stdout + done.stderr


@pytest.mark.parametrize("case", list(REFUSED))
def test_duplicate_in_one_scope_is_refused_with_both_lines(case):
    text, second, first, scope = REFUSED[case]
    with pytest.raises(NetlistError) as info:
        parse_netlist(text, source="dup.cir")
    error = info.value
    assert (error.file, error.line) == ("dup.cir", second)
    name = text.splitlines()[second - 1].split()[0]
    assert error.message == f"element {name} defined twice{scope} (first at dup.cir:{first})"


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("case", list(REFUSED))
def test_ngspice_refuses_the_same_netlists(tmp_path, case):
    path = tmp_path / "dup.cir"
    path.write_text(REFUSED[case][0])
    assert "device already exists" in _ngspice(path)


ACCEPTED = (
    "same names, other scopes\n"
    ".subckt half a b\nR1 a b 1k\nR2 b 0 1k\n.ends\n"
    ".subckt other a\nR1 a 0 1k\n.ends\n"
    "V1 in 0 DC 1\nR1 in 0 1k\nX1 in out half\nX2 out o2 half\nX3 o2 other\n"
    ".op\n.end\n"
)


def test_same_name_in_other_scopes_and_instances_is_accepted():
    circuit = parse_netlist(ACCEPTED)
    names = [e.name for e in flatten(circuit).elements]
    assert names == ["V1", "R1", "R.X1.R1", "R.X1.R2", "R.X2.R1", "R.X2.R2", "R.X3.R1"]


@requires_ngspice
@pytest.mark.ngspice
def test_ngspice_accepts_them_too_and_agrees_on_the_result():
    from circuitsim.interop.ngspice import run_ngspice

    waves = run_ngspice(ACCEPTED)  # raises NgspiceError on any error line
    # in -1k- out; out to ground: X1.R2 (1k) || [X2.R1 (1k) + o2 to ground (X2.R2 || X3.R1)]
    to_ground = 1 / (1 / 1e3 + 1 / (1e3 + 500.0))
    expected_out = to_ground / (1e3 + to_ground)
    assert waves["v(out)"][0] == pytest.approx(expected_out, rel=1e-9)
    assert waves["v(o2)"][0] == pytest.approx(expected_out / 3, rel=1e-9)


def test_duplicate_through_an_include_names_both_files(tmp_path):
    (tmp_path / "parts.inc").write_text("* parts\nR1 out 0 1k\n")
    main_file = tmp_path / "main.cir"
    main_file.write_text("t\nV1 in 0 DC 1\nR1 in out 1k\n.include parts.inc\n.op\n.end\n")
    with pytest.raises(NetlistError) as info:
        read_netlist(main_file)
    error = info.value
    assert Path(error.file).name == "parts.inc" and error.line == 2
    assert error.message.endswith(f"(first at {main_file}:3)")


def test_nested_body_is_its_own_scope():
    text = (
        "t\n.subckt outer a\nR1 a m 1k\n.subckt inner p\nR1 p 0 1k\n.ends inner\n"
        "X1 m inner\n.ends outer\nV1 in 0 DC 1\nX9 in outer\n.op\n.end\n"
    )
    names = [e.name for e in flatten(parse_netlist(text)).elements]
    assert names == ["V1", "R.X9.R1", "R.X9.X1.R1"]


@pytest.mark.parametrize("verb", ["simulate", "convert", "check"])
def test_cli_verbs_refuse_the_tester_netlist(tmp_path, capsys, verb):
    path = tmp_path / "dup.cir"
    path.write_text(REFUSED["resistor"][0])
    code = main([verb, str(path)])
    captured = capsys.readouterr()
    assert code != 0
    assert f"{path}:4: element R1 defined twice (first at {path}:3)" in captured.err
    assert "R1 out 0 1k" not in captured.out  # convert wrote nothing


def test_check_still_reports_duplicates_in_circuits_built_in_python():
    circuit = Circuit("built")
    circuit.add(
        VoltageSource("V1", "in", "0", dc=1.0),
        Resistor("R1", "in", "out", 1e3),
        Resistor("r1", "out", "0", 1e3),
    )
    [finding] = check_circuit(circuit)
    assert finding.kind == "duplicate-name" and finding.elements == ("R1", "r1")
