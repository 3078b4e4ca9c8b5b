"""One exit-code convention for every verb (README, "Exit codes"): 0 done, 1 a finding,
2 bad input, 3 the run failed. The same error gives the same code whatever the verb."""

from pathlib import Path

import pytest

from circuitsim.cli import exit_code, main
from circuitsim.compare.errors import ComparisonError
from circuitsim.interop.errors import NgspiceError
from circuitsim.mechanics import IntegrationError, ModelError
from circuitsim.netlist.errors import NetlistError
from circuitsim.solver.errors import (
    CircuitInputError,
    ConvergenceError,
    SingularMatrixError,
)
from circuitsim.synthesis.errors import SynthesisError

ROOT = Path(__file__).resolve().parents[1]
BAD_MODEL = '[model]\nname = "x"\nkind = "first_order"\n[states]\nnames = ["x"]\n'


@pytest.fixture
def bad_model(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(BAD_MODEL)  # no [matrices]
    return str(path)


@pytest.mark.parametrize(
    "argv",
    [
        ["ode", "--tstop", "0.1"],
        ["stability"],
        ["generate", "-o", "{tmp}/g.cir"],
        ["compare", "--tstop", "0.1"],
        ["sweep", "--param", "speed", "--values", "50,51", "--out", "{tmp}"],
    ],
    ids=lambda argv: argv[0],
)
def test_a_bad_model_file_exits_2_in_every_verb(argv, bad_model, tmp_path, capsys):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main([*argv, "--model", bad_model]) == 2
    assert "matrices: missing table" in capsys.readouterr().err


@pytest.mark.parametrize("verb", ["check", "convert", "simulate"])
def test_a_bad_or_missing_netlist_exits_2_in_every_verb(verb, tmp_path, capsys):
    bad = tmp_path / "bad.cir"
    bad.write_text("title\nR1 a\n.end\n")  # a resistor without its second node
    assert main([verb, str(bad)]) == 2
    assert main([verb, str(tmp_path / "missing.cir")]) == 2
    capsys.readouterr()


@pytest.mark.parametrize(
    "error, code",
    [
        (ModelError("m"), 2),
        (NetlistError("n"), 2),
        (CircuitInputError("c"), 2),
        (SingularMatrixError("s"), 2),
        (SynthesisError("s"), 2),
        (IntegrationError("i"), 3),
        (ConvergenceError("c", time=1e-3), 3),
        (NgspiceError("g"), 3),
        (ComparisonError("c"), 3),
    ],
)
def test_each_library_error_has_its_code(error, code):
    assert exit_code(error) == code


def test_usage_errors_exit_2_and_findings_exit_1(tmp_path, capsys):
    assert main(["ode", "--tstop", "-1"]) == 2
    assert main(["simulate", str(ROOT / "tests/solver/golden/rc.cir"), "--probe", "v(x)"]) == 2
    floating = tmp_path / "floating.cir"
    floating.write_text("t\nV1 a 0 1\nR1 a 0 1k\nC1 b c 1n\n.op\n.end\n")
    assert main(["check", str(floating)]) == 1
    capsys.readouterr()


def test_the_convention_is_in_the_help_and_the_readme(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "exit codes (every verb): 0 done, 1 a finding" in text
    assert "3 the run failed" in text
    readme = (ROOT / "README.md").read_text()
    assert "## Exit codes" in readme
