"""What the command-line fuzzer (tests/fuzz/gen_cli.py) found, each as a test: hostile
arguments end in one short error line and exit code 2."""

from pathlib import Path

import pytest

from circuitsim.cli import main
from circuitsim.cli.common import MAX_WORKERS, shown

ROOT = Path(__file__).resolve().parents[1]


def test_a_nul_byte_in_an_argument_is_refused(capsys):
    assert main(["check", "a\x00b.cir"]) == 2
    assert capsys.readouterr().err == "circuitsim: error: an argument contains a NUL character\n"


@pytest.mark.parametrize(
    "argv",
    [
        ["check", "{long}"],
        ["ode", "--model", "{long}"],
        ["convert", str(ROOT / "tests/solver/golden/rc.cir"), "{long}"],  # argparse's error
        ["ode", "--tstop", "0.1", "--csv", "{long}"],
    ],
    ids=["netlist", "model", "usage", "output"],
)
def test_a_5000_character_path_is_cut_in_the_message(argv, tmp_path, capsys):
    long = str(tmp_path / ("x" * 5000))
    try:
        code = main([a.replace("{long}", long) for a in argv])
    except SystemExit as exc:  # argparse's own error exits
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert len(err) < 1200 and "(5,0" in err  # the cut word says how long it was
    assert err.count("error:") == 1


def test_shown_cuts_long_words_only():
    assert shown("short words stay") == "short words stay"
    cut = shown("path " + "y" * 300 + " end")
    assert cut.startswith("path " + "y" * 200 + "...(3") and cut.endswith(" chars) end")


@pytest.mark.parametrize(
    "argv",
    [
        ["reproduce", "--workers", "1" * 400, "--out", "{tmp}/r"],
        ["sweep", "--param", "speed", "--values", "50", "--jobs", str(MAX_WORKERS + 1),
         "--out", "{tmp}/s"],
    ],
    ids=["reproduce", "sweep"],
)  # fmt: skip
def test_worker_counts_past_the_limit_are_refused(argv, tmp_path, capsys):
    assert main([a.replace("{tmp}", str(tmp_path)) for a in argv]) == 2
    assert f"must be at most {MAX_WORKERS:,}" in capsys.readouterr().err


def test_more_jobs_than_variants_runs(tmp_path, capsys):
    argv = ["sweep", "--param", "speed", "--values", "50", "--tstop", "0.05"]
    assert main([*argv, "--jobs", str(MAX_WORKERS), "--out", str(tmp_path)]) == 0
    assert "1 variant of V" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, words",
    [
        (["simulate", str(ROOT / "tests/solver/golden/rc.cir"), "--max-steps", "1" * 400],
         "--max-steps must be at most"),
        (["ode", "--tstop", "0.1", "--max-steps", "1" * 400], "--max-steps must be at most"),
        (["simulate", str(ROOT / "tests/solver/golden/rc.cir"), "--max-wall-time", "nan"],
         "--max-wall-time must be a positive finite number"),
        (
            ["compare", "--write-netlist", ".", "--tstop", "0.1"],
            "cannot write .: it is a directory",
        ),
    ],
    ids=["simulate-steps", "ode-steps", "simulate-wall-time", "compare-netlist-folder"],
)  # fmt: skip
def test_limits_and_output_folders_found_by_the_fuzzer(argv, words, capsys):
    assert main(argv) == 2
    assert words in capsys.readouterr().err
