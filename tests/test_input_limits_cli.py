"""Hostile input files through the command line: exit 2 (or the comparison's own verdict), one
error line naming the file and the key or line, never a traceback.

- /dev/zero and an endless FIFO as every kind of input file (bounded: a subprocess with a
  timeout and an address-space limit, so a regression fails instead of filling the memory);
- scale files (``simulate --states``, ``compare --scale``): nesting 100,000 deep, 401- and
  5,000-digit numbers, infinities, wrong types, 100,001 states;
- raw files (``compare --raw``): negative and absurd counts in ngspice's and LTspice's
  headers, non-finite values, a finite 1e300 V;
- model files whose coefficients no circuit can realize (``generate``): refused before the
  scaling's integration, naming the key.
"""

import json
import os
import resource
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.inputfile import NETLIST_BYTES
from circuitsim.mechanics import load_model, solve
from circuitsim.mechanics.tomlfile import builtin_path
from circuitsim.synthesis.scalemap import ScaleMap

REPO = Path(__file__).resolve().parents[1]
NETLIST = REPO / "netlists" / "wheelset_flange_ideal_ngspice.cir"
SCALE = REPO / "netlists" / "wheelset_flange_ideal_ngspice.scale.json"
MEMORY = 4 * 2**30  # address space of a subprocess: far below what reading /dev/zero would take


def _limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY, MEMORY))


def _run(*argv: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run(
        [sys.executable, "-m", "circuitsim", *argv],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=cwd,
        env=env,
        preexec_fn=_limited,
    )


def _netlist_error(err: str, *words: str) -> None:
    """A netlist's error: one ``error:`` line (the reader shows the offending line under it,
    the ngspice path says first what it will run), no traceback."""
    assert "Traceback" not in err, err
    errors = [line for line in err.splitlines() if "error:" in line]
    assert len(errors) == 1, err
    for word in words:
        assert word in errors[0], errors[0]


def _one_error_line(err: str, *words: str) -> str:
    assert "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


@pytest.mark.parametrize(
    "argv, limit",
    [
        (["ode", "--model", "/dev/zero"], "a model file is at most 16 MiB"),
        (["simulate", "/dev/zero"], "a netlist file is at most 64 MiB"),
        (["check", "/dev/zero"], "a netlist file is at most 64 MiB"),
        (["simulate", str(NETLIST), "--states", "/dev/zero"], "a scale file is at most 16 MiB"),
        (["ode", "--input", "track=/dev/zero"], "a time-series file is at most 16 MiB"),
        (["sweep", "--grid", "/dev/zero"], "a grid file is at most 16 MiB"),
    ],
    ids=["model", "netlist", "check", "states", "input", "grid"],
)
def test_dev_zero_as_any_input_is_refused(argv, limit, tmp_path):
    done = _run(*argv, cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    _one_error_line(done.stderr, "/dev/zero: too large", limit)


def test_an_endless_fifo_as_the_model_is_refused(tmp_path):
    fifo = tmp_path / "model.toml"
    os.mkfifo(fifo)

    def write() -> None:
        fd = os.open(fifo, os.O_WRONLY)
        try:
            while True:
                os.write(fd, b"# " + b"x" * 65534)
        except BrokenPipeError:
            pass
        finally:
            os.close(fd)

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    done = _run("ode", "--model", str(fifo), cwd=tmp_path)
    writer.join(timeout=60)
    assert done.returncode == 2, done.stderr
    _one_error_line(done.stderr, f"{fifo}: too large: more than 16 MiB")
    assert not writer.is_alive()


@pytest.mark.parametrize("engine", ["builtin", "ngspice"])
def test_an_include_past_the_limit_is_refused_on_both_engines(engine, tmp_path, capsys):
    """A sparse file of 64 MiB and one byte (no disk used), and /dev/zero, as includes."""
    big = tmp_path / "big.lib"
    with open(big, "wb") as handle:
        handle.truncate(NETLIST_BYTES + 1)
    for target, words in ((big, "too large: 67,108,865 bytes"), ("/dev/zero", "/dev/zero")):
        netlist = tmp_path / "inc.cir"
        netlist.write_text(f"t\n.include {target}\nR1 a 0 1k\nV1 a 0 1\n.op\n.end\n")
        assert main(["simulate", str(netlist), "--engine", engine]) == 2
        _netlist_error(capsys.readouterr().err, words)


# --- scale files --------------------------------------------------------------------------


def _scale_text(volts: str = "330.0") -> str:
    return (
        '{"time_scale": 1.0, "states": {"y": {"node": "y", "volts_per_unit": ' + volts + ", "
        '"unit": "m"}}}'
    )


HOSTILE_SCALES = {
    "nested": ("[" * 100_000 + "]" * 100_000, "nested too deeply"),
    "401 digits": (_scale_text("1" * 401), "states.y.volts_per_unit: number too large"),
    "5000 digits": (_scale_text("1" * 5000), "not JSON"),
    "1e400": (_scale_text("1e400"), "states.y.volts_per_unit: must be a finite number"),
    "NaN": (_scale_text("NaN"), "states.y.volts_per_unit: must be a finite number"),
    "a string": (_scale_text('"330"'), "states.y.volts_per_unit: expected a number"),
    "zero": (_scale_text("0"), "states.y.volts_per_unit must be nonzero"),
    "an array": ("[1, 2]", "malformed scale map (expected a JSON object)"),
    "states a list": ('{"time_scale": 1, "states": [1]}', "states: expected an object"),
    "time scale huge": (
        '{"time_scale": ' + "9" * 400 + ', "states": {}}',
        "time_scale: number too large: an integer of 400 digits",
    ),
    "node a table": (
        '{"time_scale": 1, "states": {"y": {"node": {}, "volts_per_unit": 1}}}',
        "states.y.node: expected a node name, got an object",
    ),
    "100,001 states": (
        json.dumps(
            {
                "time_scale": 1,
                "states": {f"s{k}": {"node": "y", "volts_per_unit": 1} for k in range(100_001)},
            }
        ),
        "states: 100,001 states, more than 2,000",
    ),
    "two states on one node": (
        '{"time_scale": 1, "states": {"a": {"node": "y", "volts_per_unit": 1}, '
        '"b": {"node": "Y", "volts_per_unit": 2}}}',
        "states.b.node: y is also the node of states.a",
    ),
}


@pytest.mark.parametrize("case", sorted(HOSTILE_SCALES))
@pytest.mark.parametrize("verb", ["simulate", "compare"])
def test_a_hostile_scale_file_is_named(case, verb, tmp_path, capsys):
    text, words = HOSTILE_SCALES[case]
    scale = tmp_path / "s.scale.json"
    scale.write_text(text)
    if verb == "simulate":
        argv = ["simulate", str(NETLIST), "--states", str(scale)]
    else:
        raw = tmp_path / "r.raw"
        raw.write_text("not read: the scale file is read first\n")
        argv = ["compare", "--raw", str(raw), "--scale", str(scale)]
    assert main(argv) == 2
    _one_error_line(capsys.readouterr().err, f"{scale}:", words)


# --- raw files ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def node_voltages():
    """(t, {node: volts}) of the wheelset over 1 s through the shipped scale file: what a
    circuit realizing it exactly would write."""
    model = load_model()
    system = model.system(nonlinear={"flange": True})
    scale = ScaleMap.load(SCALE)
    t = np.linspace(0.0, 1.0, 2001)
    result = solve(system, t_span=(0.0, 1.0), rtol=1e-9, atol=1e-12)
    states = result.sol(t)
    volts = {
        s.node: scale.to_volts(name, states[system.states.index(name)])
        for name, s in scale.states.items()
    }
    return t, volts


def _ascii_raw(t, volts, points: str | None = None, variables: str | None = None) -> str:
    names = ["time", *(f"v({node})" for node in volts)]
    lines = [
        "Title: hostile",
        "Date: now",
        "Plotname: Transient Analysis",
        "Flags: real",
        f"No. Variables: {variables if variables is not None else len(names)}",
        f"No. Points: {points if points is not None else len(t)}",
        "Variables:",
        *(f"\t{k}\t{name}\t{'time' if k == 0 else 'voltage'}" for k, name in enumerate(names)),
        "Values:",
    ]
    columns = [t, *volts.values()]
    for k in range(len(t)):
        lines.append(f" {k}\t{float(columns[0][k])!r}")
        lines.extend(f"\t{float(column[k])!r}" for column in columns[1:])
    return "\n".join(lines) + "\n"


def _compare(raw: Path, capsys) -> tuple[int, str]:
    code = main(["compare", "--raw", str(raw), "--scale", str(SCALE), "--flange", "--json"])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    return code, captured.err


def test_the_clean_raw_file_compares(node_voltages, tmp_path, capsys):
    """The baseline of the cases below: the exact node voltages pass the comparison."""
    raw = tmp_path / "clean.raw"
    raw.write_text(_ascii_raw(*node_voltages))
    code, err = _compare(raw, capsys)
    assert code == 0, err


@pytest.mark.parametrize(
    "points, variables, words",
    [
        ("-1", None, "No. Points: -1 is negative"),
        (None, "-3", "No. Variables: -3 is not a count of vectors"),
        (None, "0", "No. Variables: 0 is not a count of vectors"),
        (None, str(10**9), "No. Variables: 1000000000 is not a count"),
        (str(10**18), None, "cut short"),
    ],
)
def test_ngspice_raw_counts_are_checked(node_voltages, points, variables, words, tmp_path, capsys):
    raw = tmp_path / "bad.raw"
    raw.write_text(_ascii_raw(*node_voltages, points=points, variables=variables))
    code, err = _compare(raw, capsys)
    assert code == 2
    _one_error_line(err, str(raw), words)


def test_an_ltspice_raw_of_minus_one_points_is_refused(tmp_path, capsys):
    header = (
        "Title: x\nDate: now\nPlotname: Transient Analysis\nFlags: real forward\n"
        "No. Variables: 2\nNo. Points: -1\nOffset: 0\nCommand: LTspice\nVariables:\n"
        "\t0\ttime\ttime\n\t1\tV(y)\tvoltage\nBinary:\n"
    )
    raw = tmp_path / "lt.raw"
    raw.write_bytes(b"\xff\xfe" + header.encode("utf_16_le") + np.zeros(8, "<f8").tobytes())
    code, err = _compare(raw, capsys)
    assert code == 2
    _one_error_line(err, str(raw), "No. Points: -1 is negative")


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
def test_a_non_finite_value_in_a_raw_file_is_named(node_voltages, bad, tmp_path, capsys):
    t, volts = node_voltages
    volts = {node: v.copy() for node, v in volts.items()}
    volts["psi"][700] = float(bad)
    raw = tmp_path / "nan.raw"
    raw.write_text(_ascii_raw(t, volts))
    code, err = _compare(raw, capsys)
    assert code == 2
    _one_error_line(err, str(raw), f"v(psi) is {float(bad)} at point 700 (time 0.35)")


def test_a_finite_1e300_volts_is_compared_not_a_traceback(node_voltages, tmp_path, capsys):
    """One point of 1e300 V: the comparison runs to its verdict (beyond the thresholds)."""
    t, volts = node_voltages
    volts = {node: v.copy() for node, v in volts.items()}
    volts["y"][1000] = 1e300
    raw = tmp_path / "huge.raw"
    raw.write_text(_ascii_raw(t, volts))
    code = main(["compare", "--raw", str(raw), "--scale", str(SCALE), "--flange", "--json"])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    assert code == 1
    data = json.loads(captured.out)
    assert data["states"]["y"]["passed"] is False


# --- model coefficients no circuit can realize --------------------------------------------


def _wheelset_with(tmp_path: Path, old: str, new: str) -> Path:
    text = builtin_path().read_text()
    assert old in text
    path = tmp_path / "m.toml"
    path.write_text(text.replace(old, new))
    return path


@pytest.mark.parametrize("stiffness", ["1e30", "1e300"])
def test_a_contact_no_circuit_can_realize_is_refused_before_the_scaling_run(
    stiffness, tmp_path, capsys, monkeypatch
):
    import circuitsim.synthesis.translator as translator

    def no_integration(*args, **kwargs):
        raise AssertionError("the scaling's direct solution ran")

    monkeypatch.setattr(translator, "direct_solution", no_integration)
    model = _wheelset_with(tmp_path, 'linear = { y = "k" }', f"linear = {{ y = {stiffness} }}")
    code = main(["generate", "--model", str(model), "-o", str(tmp_path / "x.cir")])
    assert code == 2
    _one_error_line(capsys.readouterr().err, "not buildable", "nonlinear.flange")
    assert not (tmp_path / "x.cir").exists()


def test_a_damping_no_integrator_can_realize_is_refused(tmp_path, capsys):
    """c_y / m = 1e15 1/s: an integrator of 10 ohm and 1 nF reaches 1e8 1/s."""
    model = _wheelset_with(tmp_path, 'c_y = "7.24e6 / V"', "c_y = 1.5e18")
    code = main(["generate", "--model", str(model), "-o", str(tmp_path / "x.cir")])
    assert code == 2
    _one_error_line(
        capsys.readouterr().err, "not buildable: the coefficient of y_dot in dy_dot/dt", "c_y"
    )


def test_the_shipped_models_are_all_realizable(tmp_path, capsys):
    """The check refuses nothing a circuit is built for (each shipped model generates)."""
    for name in ("wheelset", "bogie", "quarter_car", "wheelset_creep"):
        code = main(["generate", "--model", name, "-o", str(tmp_path / f"{name}.cir")])
        assert code in (0, 1), capsys.readouterr().err


# --- CSV inputs: numbers past the float range ---------------------------------------------


@pytest.mark.parametrize(
    "value, words",
    [("1" * 401, "must be finite"), ("1e400", "must be finite"), ("nan", "must be finite")],
    ids=["401 digits", "1e400", "nan"],
)
def test_a_time_series_value_past_the_float_range_is_named(value, words, tmp_path, capsys):
    series = tmp_path / "u.csv"
    series.write_text(f"time,value\n0,0\n0.5,{value}\n1,0\n")
    assert main(["ode", "--input", f"track={series}", "--tstop", "0.1"]) == 2
    _one_error_line(capsys.readouterr().err, "u.csv line 3")


def test_a_time_series_finite_as_written_but_not_in_seconds_is_named(tmp_path, capsys):
    """1e306 hours is finite as written; in seconds it is past the float range."""
    (tmp_path / "u.csv").write_text("t_h,u\n0,0\n1e306,1\n")
    model = _wheelset_with(
        tmp_path,
        'file = "track_irregularity.csv"\nspeed = "V"\nvalue_unit = "mm"',
        'file = "u.csv"\ntime_unit = "h"\nvalue_unit = "mm"',
    )
    assert main(["ode", "--model", str(model), "--forcing", "irregularity", "--tstop", "0.1"]) == 2
    _one_error_line(
        capsys.readouterr().err,
        "forcing.irregularity.file: u.csv line 3: a point beyond the float range in s and m",
    )


@pytest.mark.parametrize("value", ["1" * 401, "1e400", "9" * 5000], ids=["401", "1e400", "5000"])
def test_a_grid_value_past_the_float_range_is_named(value, tmp_path, capsys):
    grid = tmp_path / "g.csv"
    grid.write_text(f"speed\n50\n{value}\n")
    assert main(["sweep", "--grid", str(grid), "--tstop", "0.1", "--out", str(tmp_path)]) == 2
    _one_error_line(capsys.readouterr().err, f"{grid}: line 3, column 1 (V)", "not a finite")
