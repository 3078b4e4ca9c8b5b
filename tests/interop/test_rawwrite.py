"""``simulate --raw``: a binary rawfile in ngspice's layout that the field's tools read back.

The references are the CSV the same command writes (17 significant digits, read back exactly)
and the values ngspice itself prints after its ``load`` command (``numdgt=17``: exact) or
writes again with ``write`` (binary: exact); spicelib's ``RawRead`` and our reader must give the
same doubles, bit for bit, for runs of both engines.
"""

import subprocess
from pathlib import Path

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.interop.rawfile import read_rawfile
from circuitsim.interop.rawwrite import rawfile_bytes, write_rawfile
from circuitsim.solver.waveforms import Waveforms
from tests.conftest import requires_ngspice

# An RC low-pass driven by a pulse and a sine through a second resistor: a few hundred
# points, a voltage-source current, awkward doubles.
RC = """* rc for the raw writer
V1 in 0 PULSE(0 1 1m 10u 10u 2m 5m)
V2 s 0 SIN(0 0.3 700)
R1 in out 1k
R2 s out 3.3k
C1 out 0 1u
.tran 20u 8m
.end
"""


def _simulate(tmp_path: Path, *extra: str) -> tuple[Waveforms, Path]:
    netlist = tmp_path / "rc.cir"
    netlist.write_text(RC)
    csv, raw = tmp_path / "rc.csv", tmp_path / "rc.raw"
    assert main(["simulate", str(netlist), "--csv", str(csv), "--raw", str(raw), *extra]) == 0
    return Waveforms.from_csv(csv), raw


def _ngspice(folder: Path, commands: list[str]) -> str:
    """Run ngspice on a deck of ``commands`` in ``folder``; its standard output."""
    deck = folder / "load.cir"
    # quit: ngspice -b exits 1 after a deck that runs no analysis ("no simulations run")
    lines = ["* load test", ".control", *commands, "quit", ".endc", ".end"]
    deck.write_text("\n".join(lines) + "\n")
    done = subprocess.run(
        ["ngspice", "-b", "-n", str(deck.name)],
        cwd=folder,
        env={"PATH": "/usr/bin:/bin", "HOME": str(folder)},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "error" not in (done.stdout + done.stderr).lower(), done.stdout + done.stderr
    return done.stdout


def _printed_columns(stdout: str, count: int) -> np.ndarray:
    """The rows of ngspice's ``print`` table (index, then ``count`` numbers) as an array."""
    rows = []
    for line in stdout.splitlines():
        parts = line.split()
        if len(parts) == count + 1 and parts[0].isdigit():
            rows.append([float(p) for p in parts[1:]])
    return np.array(rows)


def _assert_bits(actual: np.ndarray, expected: np.ndarray) -> None:
    actual, expected = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    assert actual.shape == expected.shape
    assert np.array_equal(actual.view(np.int64), expected.view(np.int64))


@pytest.mark.parametrize("engine", ["builtin", pytest.param("ngspice", marks=requires_ngspice)])
def test_our_reader_reads_back_the_csv_values(engine, tmp_path):
    csv, raw = _simulate(tmp_path, "--engine", engine)
    back = read_rawfile(raw)
    assert back.names == csv.names == ["v(in)", "v(s)", "v(out)", "i(v1)", "i(v2)"]
    _assert_bits(back.time, csv.time)
    for name in csv.names:
        _assert_bits(back[name], csv[name])
    assert len(csv.time) > 300


def test_the_layout_is_ngspice_39s(tmp_path):
    csv, raw = _simulate(tmp_path)
    data = raw.read_bytes()
    head, body = data.split(b"Binary:\n", 1)
    lines = head.decode().splitlines()
    assert [line.split(":")[0] for line in lines[:6]] == [
        "Title", "Date", "Plotname", "Flags", "No. Variables", "No. Points",
    ]  # fmt: skip
    assert lines[0] == "Title: * rc for the raw writer"
    assert lines[2:6] == [
        "Plotname: Transient Analysis", "Flags: real", "No. Variables: 6",
        f"No. Points: {len(csv.time)}",
    ]  # fmt: skip
    assert lines[6:] == [
        "Variables:", "\t0\ttime\ttime", "\t1\tv(in)\tvoltage", "\t2\tv(s)\tvoltage",
        "\t3\tv(out)\tvoltage", "\t4\ti(v1)\tcurrent", "\t5\ti(v2)\tcurrent",
    ]  # fmt: skip
    table = np.frombuffer(body, dtype="<f8").reshape(len(csv.time), 6)  # point after point
    _assert_bits(table[:, 0], csv.time)
    _assert_bits(table[:, 3], csv["v(out)"])


@requires_ngspice
@pytest.mark.parametrize("engine", ["builtin", "ngspice"])
def test_ngspice_loads_it_and_prints_and_writes_the_same_doubles(engine, tmp_path):
    csv, raw = _simulate(tmp_path, "--engine", engine)
    stdout = _ngspice(
        tmp_path,
        [
            f"load {raw.name}",
            "set numdgt=17",  # %.17e: every double printed exactly
            "print v(out) i(v1)",
            "set filetype=binary",
            "write again.raw",
        ],
    )
    printed = _printed_columns(stdout, 2)
    _assert_bits(printed[:, 0], csv["v(out)"])
    _assert_bits(printed[:, 1], csv["i(v1)"])
    again = read_rawfile(tmp_path / "again.raw")  # what ngspice holds after loading it
    _assert_bits(again.time, csv.time)
    for name in csv.names:
        _assert_bits(again[name], csv[name])


@pytest.mark.parametrize("engine", ["builtin", pytest.param("ngspice", marks=requires_ngspice)])
def test_spicelib_reads_it_as_an_ngspice_file(engine, tmp_path):
    from spicelib import RawRead  # a test dependency: pip install .[test]
    from spicelib.raw.raw_classes import SpiceReadException

    csv, raw = _simulate(tmp_path, "--engine", engine)
    read = RawRead(str(raw), dialect="ngspice", verbose=False)
    # get_trace, not get_axis: spicelib 1.6.4 finds no axis in ngspice 39's own files either
    _assert_bits(read.get_trace("time").get_wave(), csv.time)
    for name in csv.names:
        _assert_bits(read.get_wave(name), csv[name])
    # as for ngspice 39's own files: no Command: line (ngspice 39's load would run it)
    with pytest.raises(SpiceReadException, match="dialect"):
        RawRead(str(raw), verbose=False)


@requires_ngspice
def test_an_operating_point_loads_in_ngspice(tmp_path):
    netlist = tmp_path / "div.cir"
    netlist.write_text("* divider\nV1 a 0 DC 3\nR1 a b 1k\nR2 b 0 2k\n.op\n.end\n")
    raw = tmp_path / "div.raw"
    assert main(["simulate", str(netlist), "--raw", str(raw)]) == 0
    assert b"Plotname: Operating Point" in raw.read_bytes()
    stdout = _ngspice(tmp_path, [f"load {raw.name}", "set numdgt=17", "print v(b) i(v1)"])
    printed = {
        line.split(" = ")[0]: float(line.split(" = ")[1])
        for line in stdout.splitlines()
        if " = " in line
    }
    back = read_rawfile(raw)
    assert back.time.tolist() == [0.0]
    for name in ("v(b)", "i(v1)"):
        _assert_bits(np.array([printed[name]]), back[name])
    assert printed["v(b)"] == pytest.approx(2.0, rel=1e-14)  # 3 V * 2k / 3k
    assert printed["i(v1)"] == pytest.approx(-1e-3, rel=1e-14)  # 1 mA out of its + terminal


def test_a_failed_write_leaves_the_old_file(tmp_path):
    target = tmp_path / "keep.raw"
    target.write_bytes(b"old")
    waves = Waveforms(time=np.array([0.0, 1.0]), signals={"y": np.array([1.0, 2.0])})
    with pytest.raises(ValueError, match="'y' is neither a voltage"):
        write_rawfile(target, waves)
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.raw"]  # no temporary left


def test_signals_of_differing_lengths_are_refused():
    waves = Waveforms(time=np.array([0.0, 1.0]), signals={"v(a)": np.array([1.0])})
    with pytest.raises(ValueError, match="'v\\(a\\)' has 1 values for 2 time points"):
        rawfile_bytes(waves)


def test_raw_with_states_is_a_usage_error(tmp_path, capsys):
    netlist = tmp_path / "rc.cir"
    netlist.write_text(RC)
    scale = tmp_path / "rc.scale.json"
    scale.write_text('{"time_scale": 1.0, "states": {"x": {"node": "out", "volts_per_unit": 1}}}')
    raw = tmp_path / "x.raw"
    code = main(["simulate", str(netlist), "--states", str(scale), "--raw", str(raw)])
    assert code == 2
    assert "--raw writes node voltages" in capsys.readouterr().err
    assert not raw.exists()
