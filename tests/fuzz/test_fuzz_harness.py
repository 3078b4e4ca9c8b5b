"""The fuzz harness classifies each kind of outcome as documented in ``harness.py``."""

import time

from circuitsim.netlist.errors import NetlistError
from tests.fuzz.campaign import generator_names
from tests.fuzz.harness import Case, CliResult, classify_cli, cli_call, run_case, run_cases


def _raise(exc: BaseException):
    def call():
        raise exc

    return call


def test_outcome_kinds_of_library_calls():
    cases = [
        Case("d", "clean", "", lambda: 42),
        Case("d", "named", "", _raise(NetlistError("bad", "x.cir", 3))),
        Case("d", "typeerror", "", _raise(TypeError("min expected 1 argument"))),
        Case("d", "recursion", "", _raise(RecursionError("deep"))),
        Case("d", "extra-named", "", _raise(KeyError("k")), named=(KeyError,)),
    ]
    kinds = [run_case(case, 5.0).kind for case in cases]
    assert kinds == ["clean", "named", "traceback", "traceback", "named"]


def test_a_case_past_its_bound_is_a_hang_even_if_it_catches_exceptions():
    def stubborn():
        end = time.monotonic() + 5.0
        while time.monotonic() < end:
            try:
                time.sleep(0.01)
            except Exception:  # the bound's exception is not an Exception: not swallowed
                pass

    start = time.monotonic()
    outcome = run_case(Case("d", "spin", "", stubborn), bound=0.2)
    assert outcome.kind == "hang"
    assert time.monotonic() - start < 2.0


def test_command_line_results():
    assert classify_cli(CliResult(0, "ok", ""))[0] == "clean"
    assert classify_cli(CliResult(1, "x.cir: floating: n1", "1 finding(s)"))[0] == "clean"
    named = CliResult(2, "", "circuitsim check: error: x.cir:3: bad value\n")
    assert classify_cli(named) == ("named", "circuitsim check: error: x.cir:3: bad value")
    trace = CliResult(1, "", "Traceback (most recent call last):\n  ...\nTypeError: x\n")
    assert classify_cli(trace)[0] == "traceback"
    # 3 is a failed run (README "Exit codes"): named when it says why in one line
    assert classify_cli(CliResult(3, "", "circuitsim x: error: y"))[0] == "named"
    assert classify_cli(CliResult(4, "", "circuitsim x: error: y"))[0] == "traceback"
    assert classify_cli(CliResult(2, "", "error: " + "z" * 10_000))[0] == "traceback"


def test_cli_call_runs_the_command_line_in_process(tmp_path):
    missing = str(tmp_path / "missing.cir")
    outcome = run_case(Case("cli", "missing", "", cli_call(["check", missing])), 30.0)
    assert outcome.kind == "named", outcome.detail
    assert "missing.cir" in outcome.detail
    usage = run_case(Case("cli", "usage", "", cli_call(["check", "--no-such-option"])), 30.0)
    assert usage.kind == "named", usage.detail


def test_summary_counts_and_keeps_failures():
    cases = [Case("a", str(k), "text", lambda: 1) for k in range(3)]
    cases.append(Case("b", "bad", "R1 a b {min(1)}", _raise(TypeError("t"))))
    summary = run_cases(cases, time_bound=5.0)
    assert summary.counts[("a", "clean")] == 3
    assert summary.count("traceback") == 1 and summary.count("traceback", "a") == 0
    assert [o.case.name for o in summary.failures] == ["bad"]
    assert "R1 a b {min(1)}" in summary.report()


def test_the_campaign_finds_the_generators():
    assert "gen_netlists" in generator_names()
