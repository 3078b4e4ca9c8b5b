"""The ``convert`` and ``check`` verbs: files in, files out, exit codes."""

import pytest

from circuitsim.cli import main
from circuitsim.netlist.reader import parse_netlist, read_netlist

CLEAN = """clean divider
V1 in 0 DC 3
R1 in out 2k
R2 out 0 1k
.op
.end
"""

# One finding of each electrical kind, each named in the message: a node behind a capacitor
# (no DC path), two sources in parallel (loop), a dangling resistor end (floating).
FAULTY = """faulty
V1 in 0 DC 3
V2 in 0 DC 5
R1 in out 1k
C1 out mid 1u
R2 mid top 1k
C2 top 0 1u
R3 in dangling 1k
D1 in 0 nomodel
.op
.end
"""


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_check_clean_exits_0(tmp_path, capsys):
    path = _write(tmp_path, "clean.cir", CLEAN)
    assert main(["check", str(path)]) == 0
    assert capsys.readouterr().out == f"{path}: no findings\n"


def test_check_findings_exit_1_with_names(tmp_path, capsys):
    path = _write(tmp_path, "faulty.cir", FAULTY)
    assert main(["check", str(path)]) == 1
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 4
    text = "\n".join(out)
    assert "undefined-model: D1 uses model 'nomodel'" in text
    assert "floating-node: node dangling has one connection only (R3)" in text
    assert (
        "no-dc-path: nodes mid, top have no DC path to ground (connected only through C1, C2)"
        in text
    )
    assert "voltage-loop: V1, V2 form a loop" in text


@pytest.mark.parametrize(
    "text",
    ["unreadable\nR1 a\n.end\n", "unreadable\nK1 l1 l2 0.5\n.end\n"],
    ids=["too-few-fields", "unsupported-element"],
)
def test_check_unreadable_exits_2(tmp_path, capsys, text):
    path = _write(tmp_path, "bad.cir", text)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("circuitsim check: error: ") and f"{path}:2" in err


def test_check_missing_file_exits_2(tmp_path, capsys):
    assert main(["check", str(tmp_path / "nope.cir")]) == 2
    assert "nope.cir" in capsys.readouterr().err


@pytest.mark.parametrize("dialect", ["ngspice", "ltspice", "multisim"])
def test_convert_writes_a_file_that_reads_back(tmp_path, dialect):
    src = _write(tmp_path, "in.cir", CLEAN.replace("R2 out 0 1k", "R2 out 0 {2^2*250}"))
    out = tmp_path / "out.cir"
    assert main(["convert", str(src), "--dialect", dialect, "-o", str(out)]) == 0
    text = out.read_text()
    assert "{2**2*250}" in text
    back, original = read_netlist(out), read_netlist(src)
    assert back.elements[:2] == original.elements[:2]
    from circuitsim.netlist.flatten import flatten

    assert flatten(back).elements[2].resistance == 1000.0


def test_convert_to_stdout_and_bad_input(tmp_path, capsys):
    src = _write(tmp_path, "in.cir", CLEAN)
    assert main(["convert", str(src), "--dialect", "ltspice"]) == 0
    assert parse_netlist(capsys.readouterr().out).elements == read_netlist(src).elements
    bad = _write(tmp_path, "bad.cir", "bad\nR1 a\n.end\n")
    assert main(["convert", str(bad), "-o", str(tmp_path / "o.cir")]) == 2
    assert not (tmp_path / "o.cir").exists()


def test_reader_warnings_are_one_line_each_on_stderr(tmp_path, capsys):
    path = _write(tmp_path, "w.cir", CLEAN.replace(".op", ".print dc v(out)\n.op"))
    assert main(["check", str(path)]) == 0
    err = capsys.readouterr().err
    assert err.startswith(f"warning: {path}:5: .print ignored") and err.count("\n") == 1
