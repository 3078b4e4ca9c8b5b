"""The command line refuses bad option values with one clear line and exit code 2, before any
long computation; figures follow their suffix; warnings and progress are plain lines; a closed
pipe ends a run quietly."""

import importlib
import io
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from circuitsim.cli import main

ROOT = Path(__file__).resolve().parents[1]
MAGIC = {".png": b"\x89PNG", ".pdf": b"%PDF", ".svg": b"<?xml"}


def _must_not_run(*args, **kwargs):
    raise AssertionError("the long computation started before the options were checked")


@pytest.fixture
def no_long_work(monkeypatch):
    """Every verb's long computation replaced by a failure: a refusal must come first."""
    for module, name in [
        ("circuitsim.compare.sweep", "run_sweep"),
        ("circuitsim.compare.case", "run_case"),
        ("circuitsim.studies.reproduce", "reproduce"),
        ("circuitsim.mechanics", "solve"),
        ("circuitsim.mechanics", "critical_speed"),
        ("circuitsim.solver", "simulate"),
        ("circuitsim.interop.ngspice", "run_ngspice"),
        ("circuitsim.synthesis.generate", "generate"),  # the module, not the function
    ]:
        monkeypatch.setattr(importlib.import_module(module), name, _must_not_run)
    # building a sweep's systems is cheap per value, not for ten million of them
    from circuitsim.cli import sweep_verbs

    built = []

    def few_systems(*args, **kwargs):
        built.append(1)
        if len(built) > 100:
            raise AssertionError("a sweep built more than 100 systems before its checks")
        return scenario_system(*args, **kwargs)

    scenario_system = sweep_verbs.scenario_system
    monkeypatch.setattr(sweep_verbs, "scenario_system", few_systems)


def _refused(argv, capsys) -> str:
    """Run ``argv``; assert exit code 2 and one error line; return stderr."""
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    assert f"circuitsim {argv[0]}: error: " in captured.err
    return captured.err


SWEEP = ["sweep", "--values", "50,60", "--tstop", "0.5"]

REFUSED = {
    # A: a parameter both swept and fixed (through its own name or an option's alias)
    "sweep-freq-and-f": (
        ["sweep", "--param", "freq", "--param", "f=5", "--values", "1,2", "--tstop", "0.5"],
        ["--param f=5", "--param freq"],
    ),
    "sweep-speed-and-V": (
        [*SWEEP, "--param", "speed", "--param", "V=60"],
        ["--param V=60", "--param speed"],
    ),
    "sweep-V-and-speed-option": ([*SWEEP, "--param", "V", "--speed", "60"], ["--speed 60"]),
    "sweep-freq-and-freq-option": (
        ["sweep", "--param", "f", "--freq", "2", "--values", "1,2", "--tstop", "0.5"],
        ["--freq 2", "--param f"],
    ),
    "sweep-unknown": ([*SWEEP, "--param", "nosuch"], ["--param nosuch", "known: V"]),
    # B and C: times, windows, values, jobs
    "sweep-window-negative": ([*SWEEP, "--param", "speed", "--window", "-1"], ["--window"]),
    "sweep-window-zero": ([*SWEEP, "--param", "speed", "--window", "0"], ["--window"]),
    "sweep-window-nan": ([*SWEEP, "--param", "speed", "--window", "nan"], ["--window"]),
    "sweep-window-longer": (
        [*SWEEP, "--param", "speed", "--window", "2"],
        ["--window 2 s is longer", "--tstop: 0.5 s"],
    ),
    "sweep-window-longer-than-default": (
        ["sweep", "--param", "speed", "--values", "50,60", "--window", "6"],
        ["--window 6 s", "5 s"],
    ),
    "sweep-values-inf": (
        ["sweep", "--param", "speed", "--values", "1:inf:1", "--tstop", "0.5"],
        ["--values", "finite"],
    ),
    "sweep-values-too-many": (
        ["sweep", "--param", "speed", "--values", "1:1e7:1", "--tstop", "0.5"],
        ["--values", "10,000"],
    ),
    "sweep-values-nan": (
        ["sweep", "--param", "speed", "--values", "50,nan", "--tstop", "0.5"],
        ["--values", "finite"],
    ),
    "sweep-tstop-nan": ([*SWEEP[:3], "--tstop", "nan", "--param", "speed"], ["--tstop", "nan"]),
    "sweep-tstop-inf": ([*SWEEP[:3], "--tstop", "inf", "--param", "speed"], ["--tstop", "inf"]),
    "sweep-tstop-zero": ([*SWEEP[:3], "--tstop", "0", "--param", "speed"], ["--tstop"]),
    "sweep-speed-nan": ([*SWEEP, "--param", "freq", "--speed", "nan"], ["--speed", "nan"]),
    "sweep-jobs": ([*SWEEP, "--param", "speed", "--jobs", "-3"], ["--jobs", "-3"]),
    "ode-dt-zero": (["ode", "--tstop", "1", "--dt", "0", "--csv", "x.csv"], ["--dt", "got 0"]),
    "ode-dt-negative": (["ode", "--tstop", "1", "--dt", "-1", "--csv", "x.csv"], ["--dt"]),
    "ode-dt-nan": (["ode", "--dt", "nan"], ["--dt", "nan"]),
    "ode-too-many-rows": (
        ["ode", "--tstop", "1", "--dt", "1e-9", "--csv", "x.csv"],
        ["--dt 1e-09", "--tstop 1", "rows"],
    ),
    "ode-tstop-inf": (["ode", "--tstop", "inf"], ["--tstop", "inf"]),
    "ode-tstop-nan": (["ode", "--tstop", "nan"], ["--tstop", "nan"]),
    "ode-tstop-negative": (["ode", "--tstop", "-1"], ["--tstop", "-1"]),
    "ode-rtol-zero": (["ode", "--rtol", "0"], ["--rtol", "between 0 and 1"]),
    "ode-rtol-two": (["ode", "--rtol", "2"], ["--rtol", "got 2"]),
    "ode-rtol-nan": (["ode", "--rtol", "nan"], ["--rtol"]),
    "ode-speed-nan": (["ode", "--speed", "nan"], ["--speed", "got nan"]),
    "ode-amplitude-inf": (["ode", "--amplitude", "inf"], ["--amplitude", "got inf"]),
    "ode-y0-nan": (["ode", "--y0", "nan"], ["--y0"]),
    "ode-plot-suffix": (["ode", "--plot", "y.xyz"], ["--plot y.xyz", ".xyz", "png"]),
    "simulate-plot-suffix": (
        ["simulate", str(ROOT / "tests/solver/golden/rc.cir"), "--plot", "p.xyz"],
        ["--plot p.xyz", ".xyz"],
    ),
    # D: NaN thresholds would pass every comparison
    "compare-nan-thresholds": (
        ["compare", "--no-flange", "--tstop", "2", "--max-nrmsd", "nan", "--tolerance", "nan"],
        ["--max-nrmsd", "nan"],
    ),
    "compare-tolerance-nan": (["compare", "--tolerance", "nan"], ["--tolerance", "nan"]),
    "compare-tolerance-zero": (["compare", "--tolerance", "0"], ["--tolerance"]),
    "compare-max-nrmsd-negative": (["compare", "--max-nrmsd", "-1"], ["--max-nrmsd"]),
    "compare-tstop-inf": (["compare", "--tstop", "inf"], ["--tstop", "inf"]),
    "compare-plot-suffix": (["compare", "--plot", "c.xyz"], ["--plot c.xyz"]),
    "reproduce-workers-negative": (["reproduce", "--workers", "-1"], ["--workers", "-1"]),
    "reproduce-workers-zero": (["reproduce", "--workers", "0"], ["--workers", "got 0"]),
    "stability-speed-nan": (["stability", "--speed", "nan"], ["--speed", "got nan"]),
    "stability-bracket-inf": (["stability", "--bracket", "1", "inf"], ["--bracket", "1 inf"]),
    "stability-bracket-reversed": (["stability", "--bracket", "100", "10"], ["--bracket"]),
    "generate-swing-nan": (["generate", "--swing", "nan", "-o", "g.cir"], ["--swing"]),
    "generate-time-scale-zero": (["generate", "--time-scale", "0", "-o", "g.cir"], ["--time"]),
    "generate-tstop-inf": (["generate", "--tstop", "inf", "-o", "g.cir"], ["--tstop"]),
    "generate-switch-at-nan": (["generate", "--switch-at", "nan", "-o", "g.cir"], ["--switch-at"]),
    "generate-switch-at-negative": (
        ["generate", "--switch-at", "-1", "-o", "g.cir"],
        ["--switch-at"],
    ),
}


@pytest.mark.parametrize("argv, words", list(REFUSED.values()), ids=list(REFUSED))
def test_bad_option_values_are_refused_before_any_work(
    argv, words, no_long_work, tmp_path, monkeypatch, capsys
):
    monkeypatch.chdir(tmp_path)  # relative output names land here (none may be written)
    out = ["--out", str(tmp_path / "out")] if argv[0] in ("sweep", "reproduce") else []
    err = _refused([*argv, *out], capsys)
    for word in words:
        assert word in err
    assert "np.float64" not in err
    assert not (tmp_path / "out").exists()  # refused before the output folder is made
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "argv, option",
    [
        (["ode", "--param", "eta=inf"], "--param"),
        (["ode", "--param", "eta=nan"], "--param"),
        (["generate", "--range", "y=nan", "-o", "g.cir"], "--range"),
        (["generate", "--range", "y=inf", "-o", "g.cir"], "--range"),
    ],
)
def test_non_finite_assignments_are_refused_by_the_parser(argv, option, no_long_work, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}: expected" in err and "finite" in err


def test_stability_speed_message_is_a_plain_number(no_long_work, capsys):
    err = _refused(["stability", "--speed", "nan"], capsys)
    assert err.strip() == "circuitsim stability: error: --speed must be a finite number, got nan"


# --- output paths checked before the long work ---------------------------------------------


@pytest.mark.parametrize(
    "argv",
    [
        ["ode", "--csv", "{missing}/y.csv"],
        ["ode", "--plot", "{missing}/y.png"],
        ["simulate", str(ROOT / "tests/solver/golden/rc.cir"), "--csv", "{missing}/w.csv"],
        ["simulate", str(ROOT / "tests/solver/golden/rc.cir"), "--plot", "{missing}/w.svg"],
        ["compare", "--plot", "{missing}/c.png"],
        ["compare", "--write-netlist", "{missing}/c.cir"],
    ],
    ids=["ode-csv", "ode-plot", "simulate-csv", "simulate-plot", "compare-plot", "compare-netlist"],
)
def test_unwritable_outputs_are_refused_first(argv, no_long_work, tmp_path, capsys):
    missing = str(tmp_path / "no" / "such")
    argv = [a.replace("{missing}", missing) for a in argv]
    err = _refused(argv, capsys)
    assert "cannot write" in err and "does not exist" in err


@pytest.mark.parametrize("verb", ["sweep", "reproduce"])
def test_an_output_folder_that_is_a_file_is_refused_first(verb, no_long_work, tmp_path, capsys):
    afile = tmp_path / "afile"
    afile.write_text("keep")
    argv = [verb, "--out", str(afile)]
    if verb == "sweep":
        argv += ["--param", "speed", "--values", "50,60", "--tstop", "0.5"]
    err = _refused(argv, capsys)
    assert f"--out {afile}: it is a file, not a folder" in err
    assert afile.read_text() == "keep"


# --- figures in the format of their suffix -------------------------------------------------


@pytest.mark.parametrize("suffix", [".pdf", ".svg"])
def test_ode_plot_follows_its_suffix(suffix, tmp_path, capsys):
    path = tmp_path / f"y{suffix}"
    argv = ["ode", "--tstop", "0.2", "--no-flange", "--plot", str(path)]
    assert main(argv) == 0
    assert path.read_bytes().startswith(MAGIC[suffix])


@pytest.mark.parametrize("suffix", [".png", ".pdf", ".svg"])
def test_overlay_figure_follows_its_suffix(suffix, tmp_path):
    """The compare verb's --plot (plot_overlay through save_figure) writes what it names."""
    from circuitsim.compare.plots import plot_overlay

    t = np.linspace(0.0, 1.0, 50)
    reference = {"y": (t, np.sin(t))}
    path = tmp_path / f"c{suffix}"
    plot_overlay(path, reference, {"builtin": {"y": (t, np.sin(t) + 1e-3)}}, errors=True)
    assert path.read_bytes().startswith(MAGIC[suffix])


# --- warnings as plain lines -----------------------------------------------------------------


def test_simulate_prints_netlist_warnings_as_plain_lines(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("warn.cir").write_text("rc\nV1 a 0 1\nR1 a 0 1k\n.print tran v(a)\n.op\n.end\n")
    assert main(["simulate", "warn.cir"]) == 0
    err = capsys.readouterr().err
    assert err.startswith("warning: warn.cir:4: .print ignored")
    assert "NetlistWarning" not in err and "reader.py" not in err


def test_other_warnings_are_plain_lines_too(capsys, monkeypatch):
    """Any warning a verb's library calls issue (numpy's, scipy's ...) is one plain line."""
    import warnings

    from circuitsim.cli import model_verbs

    def warn(args):
        warnings.warn("overflow encountered in multiply", RuntimeWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(model_verbs, "_run_stability", warn)
    assert main(["stability"]) == 0
    assert capsys.readouterr().err == "warning: overflow encountered in multiply\n"


# --- the sweep's progress and summary ---------------------------------------------------------


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_sweep_progress_is_plain_lines_off_a_terminal():
    from circuitsim.cli.sweep_verbs import _SweepBar

    stream = io.StringIO()
    bar = _SweepBar(stream)
    for done in range(101):
        bar(done / 100, f"builtin: {done} of 100 variants")
    bar.close()
    lines = stream.getvalue().splitlines()
    assert "\r" not in stream.getvalue()
    assert len(lines) == 11  # the start and every tenth
    assert lines[0].strip() == "0.0%  builtin: 0 of 100 variants"
    assert lines[-1] == "100.0%  builtin: 100 of 100 variants"


def test_sweep_bar_on_a_terminal_is_redrawn_and_closed():
    from circuitsim.cli.sweep_verbs import _SweepBar

    stream = _Terminal()
    bar = _SweepBar(stream)
    bar(0.0, "start")
    bar(0.5, "half")
    assert stream.getvalue().count("\r") == 2 and "\n" not in stream.getvalue()
    bar.close()
    assert stream.getvalue().endswith("\n")
    bar.close()  # once only
    assert stream.getvalue().count("\n") == 1


def test_an_error_during_the_sweep_starts_on_its_own_line(tmp_path, monkeypatch):
    import circuitsim.compare.sweep
    from circuitsim.solver.errors import SolverError

    def fail_halfway(*args, progress=None, **kwargs):
        progress(0.5, "builtin: 1 of 2 variants")
        raise SolverError("singular matrix")

    monkeypatch.setattr(circuitsim.compare.sweep, "run_sweep", fail_halfway)
    stderr = _Terminal()
    monkeypatch.setattr(sys, "stderr", stderr)
    argv = ["sweep", "--param", "speed", "--values", "50,60", "--tstop", "0.5"]
    assert main([*argv, "--out", str(tmp_path)]) == 3  # a failed run (a plain SolverError)
    assert stderr.getvalue().endswith("\ncircuitsim sweep: error: singular matrix\n")


def test_one_value_sweep_says_variant_and_labels_the_window(tmp_path, capsys):
    """A --tstop shorter than the default 1 s window: the window is the whole run, so labelled;
    STEP longer than the range gives START alone."""
    argv = ["sweep", "--param", "speed", "--values", "50:51:5", "--tstop", "0.2"]
    assert main([*argv, "--out", str(tmp_path), "--jobs", "1"]) == 0
    captured = capsys.readouterr()
    assert "1 variant of V" in captured.out
    assert "1 variant;" in captured.err and "\r" not in captured.err
    header = (tmp_path / "sweep.csv").read_text().splitlines()[0]
    assert "max_abs_y_last_0.2s" in header


# --- a closed pipe ---------------------------------------------------------------------------


class _ClosedPipe(io.StringIO):
    def write(self, text: str) -> int:
        raise BrokenPipeError(32, "Broken pipe")

    def flush(self) -> None:
        raise BrokenPipeError(32, "Broken pipe")


def test_a_closed_stdout_ends_quietly(monkeypatch, capsys):
    monkeypatch.setattr(sys, "stdout", _ClosedPipe())
    assert main(["convert", str(ROOT / "tests/solver/golden/rc.cir")]) == 141
    assert capsys.readouterr().err == ""


def test_a_closed_pipe_prints_nothing_in_a_real_process(tmp_path):
    netlist = tmp_path / "big.cir"
    netlist.write_text(
        "big\nV1 a 0 1\n" + "".join(f"R{i} a 0 1k\n" for i in range(5000)) + ".op\n.end\n"
    )
    process = subprocess.Popen(
        [sys.executable, "-m", "circuitsim", "convert", str(netlist)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd=ROOT,
    )
    process.stdout.close()  # the reader is gone before the first line is written
    err = process.stderr.read().decode()
    assert process.wait(timeout=60) == 141
    assert err == ""


# --- parse_values ----------------------------------------------------------------------------


def test_parse_values_refuses_non_finite_and_too_many():
    from circuitsim.compare.errors import ComparisonError
    from circuitsim.compare.values import parse_values

    for text in ("1:inf:1", "nan:2:1", "1:2:nan", "1,inf", "nan"):
        with pytest.raises(ComparisonError, match="finite"):
            parse_values(text)
    for text in ("1:1e7:1", "0:1:1e-300", "-1e308:1e308:1"):
        with pytest.raises(ComparisonError, match="more than 10,000 values"):
            parse_values(text)
    with pytest.raises(ComparisonError, match="more than 3"):
        parse_values("1,2,3,4", limit=3)
    assert parse_values("1:3:1", limit=3).tolist() == [1.0, 2.0, 3.0]
    assert parse_values("1:2:5").tolist() == [1.0]
