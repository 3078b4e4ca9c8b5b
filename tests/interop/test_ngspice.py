"""The ngspice runner: an RC step against its analytic solution, failures, a missing binary."""

import shutil

import numpy as np
import pytest

from circuitsim.interop.errors import NgspiceError
from circuitsim.interop.ngspice import RunLimits, ngspice_available, parse_ascii_raw, run_ngspice
from circuitsim.netlist.circuit import (
    AcSweep,
    Capacitor,
    Circuit,
    OperatingPoint,
    Pulse,
    Resistor,
    Transient,
    VoltageSource,
)

requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)

R, C = 1e3, 1e-6  # tau = 1 ms


def _rc_step() -> Circuit:
    c = Circuit(title="rc step")
    c.add(
        VoltageSource("V1", "in", "0", waveform=Pulse(0.0, 1.0, 0.0, 1e-9, 1e-9, 1.0)),
        Resistor("R1", "in", "out", R),
        Capacitor("C1", "out", "0", C),
    )
    c.analyses.append(Transient(1e-5, 5e-3, 0.0, 1e-5))
    return c


@requires_ngspice
@pytest.mark.ngspice
def test_rc_step_matches_the_analytic_solution():
    waves = run_ngspice(_rc_step())
    assert waves.engine == "ngspice"
    assert waves.names == ["v(in)", "v(out)", "i(v1)"]
    t = waves.time
    assert t[0] == 0.0 and t[-1] == pytest.approx(5e-3) and np.all(np.diff(t) > 0)
    exact = 1.0 - np.exp(-t / (R * C))
    after = t > 1e-6  # past the 1 ns rise
    assert np.max(np.abs(waves["out"][after] - exact[after])) < 1e-3
    # Source current: SPICE sign, from n+ through the source, so -(v(in) - v(out))/R.
    expected = -(waves["in"] - waves["out"]) / R
    assert np.allclose(waves["i(v1)"][after], expected[after], atol=1e-9)
    assert waves.stats["wall_time_s"] > 0 and waves.stats["analysis"] == "tran"


@requires_ngspice
@pytest.mark.ngspice
def test_operating_point_is_one_point_at_zero_and_probes_select():
    c = Circuit(title="divider")
    c.add(
        VoltageSource("V1", "in", "0", dc=3.0),
        Resistor("R1", "in", "out", 2e3),
        Resistor("R2", "out", "0", 1e3),
    )
    c.analyses.append(OperatingPoint())
    waves = run_ngspice(c, probes=["out", "i(V1)"])
    assert waves.time.tolist() == [0.0]
    assert waves.names == ["v(out)", "i(v1)"]
    assert waves["out"][0] == pytest.approx(1.0, rel=1e-9)
    assert waves["i(v1)"][0] == pytest.approx(-1e-3, rel=1e-9)
    with pytest.raises(NgspiceError, match="no signal v\\(nope\\)|no signal nope"):
        run_ngspice(c, probes=["nope"])


@requires_ngspice
@pytest.mark.ngspice
def test_file_with_relative_include_and_own_control_block(tmp_path):
    (tmp_path / "load.inc").write_text("R2 out 0 1k\n")
    (tmp_path / "main.cir").write_text(
        "divider from a file\nV1 in 0 DC 2\nR1 in out 1k\n.include load.inc\n.op\n"
        ".control\nrun\nprint v(out)\nquit\n.endc\n.end\n"
    )
    waves = run_ngspice(tmp_path / "main.cir")
    assert waves["out"][0] == pytest.approx(1.0, rel=1e-9)
    assert run_ngspice(str(tmp_path / "main.cir"))["out"][0] == waves["out"][0]


@requires_ngspice
@pytest.mark.ngspice
def test_unknown_subcircuit_raises_with_the_log_line():
    text = "bad\nV1 in 0 DC 1\nR1 in out 1k\nX1 out 0 nosuch\n.op\n.end\n"
    with pytest.raises(NgspiceError) as info:
        run_ngspice(text)
    assert "unknown subckt" in info.value.log.lower()
    assert "x1 out 0 nosuch" in info.value.log.lower()


@requires_ngspice
@pytest.mark.ngspice
def test_singular_circuit_raises_even_though_ngspice_may_exit_0():
    # Two ideal sources in parallel: KVL cannot hold, the matrix is singular.
    text = "loop\nV1 in 0 DC 1\nV2 in 0 DC 2\nR1 in 0 1k\n.tran 1u 10u\n.end\n"
    with pytest.raises(NgspiceError) as info:
        run_ngspice(text)
    assert "singular matrix" in info.value.log.lower()


def test_deck_without_analysis_or_with_another_is_refused_before_running():
    c = _rc_step()
    c.analyses = []
    with pytest.raises(NgspiceError, match="no .tran, .op or .ac analysis"):
        run_ngspice(c)
    c.analyses = [AcSweep("dec", 10, 1.0, 1e3)]
    with pytest.raises(NgspiceError, match=r"no \.tran analysis \(it has: \.ac\)"):
        run_ngspice(c, analysis="tran")
    with pytest.raises(NgspiceError, match="unknown analysis 'dc'"):
        run_ngspice(c, analysis="dc")


@requires_ngspice
@pytest.mark.ngspice
def test_ac_sweep_is_magnitude_and_phase_of_the_rc_lowpass():
    c = _rc_step()
    c.element("V1").ac_magnitude = 1.0
    c.analyses.append(AcSweep("dec", 5, 10.0, 1e5))
    assert run_ngspice(c).stats["analysis"] == "tran"  # .tran first by default
    waves = run_ngspice(c, analysis="ac")
    f = waves.time
    assert f[0] == pytest.approx(10.0) and f[-1] == pytest.approx(1e5) and len(f) == 21
    h = 1.0 / (1.0 + 2j * np.pi * f * R * C)
    assert np.allclose(waves["vm(out)"], np.abs(h), rtol=1e-9)
    assert np.allclose(waves["vp(out)"], np.degrees(np.angle(h)), atol=1e-7)
    assert np.allclose(waves["vm(in)"], 1.0) and np.allclose(waves["vp(in)"], 0.0)
    assert waves.names == ["vm(in)", "vp(in)", "vm(out)", "vp(out)", "im(v1)", "ip(v1)"]


def test_missing_binary_gives_a_clear_error(monkeypatch, tmp_path):
    monkeypatch.setenv("PATH", str(tmp_path))
    assert ngspice_available() is False
    with pytest.raises(NgspiceError, match="ngspice is not installed"):
        run_ngspice(_rc_step())


def test_parse_ascii_raw_by_hand():
    text = (
        "Title: hand made\nDate: today\nPlotname: Transient Analysis\nFlags: real\n"
        "No. Variables: 3\nNo. Points: 2\nVariables:\n"
        "\t0\ttime\ttime\n\t1\tout\tvoltage\n\t2\tv1#branch\tcurrent\n"
        "Values:\n 0\t0.000000000000000e+00\n\t1.5e+00\n\t-2e-03\n\n"
        " 1\t1.000000000000000e-03\n\t2.5e+00\n\t-1e-03\n"
    )
    waves = parse_ascii_raw(text)
    assert waves.time.tolist() == [0.0, 1e-3]
    assert waves.signals["v(out)"].tolist() == [1.5, 2.5]
    assert waves.signals["i(v1)"].tolist() == [-2e-3, -1e-3]
    with pytest.raises(NgspiceError, match="cut short"):
        parse_ascii_raw(text.replace("No. Points: 2", "No. Points: 3"))
    complex_text = (
        text.replace("Flags: real", "Flags: complex")
        .replace("time\ttime", "frequency\tfrequency grid=3")
        .replace("1.5e+00", "0,2")
        .replace("-2e-03", "-3e-3,0")
    )
    ac = parse_ascii_raw(complex_text)
    assert ac.signals["vm(out)"].tolist() == [2.0, 2.5]
    assert ac.signals["vp(out)"].tolist() == [90.0, 0.0]
    assert ac.signals["ip(v1)"].tolist() == [180.0, 180.0]


@requires_ngspice
@pytest.mark.ngspice
def test_words_like_error_in_names_are_not_failures():
    # ngspice echoes the title and prints node tables; neither is an error report.
    text = (
        "Error and singular matrix in the title\n"
        "V1 error 0 PULSE(0 1 0 1u 1u 1m 2m)\nR1 error singular 1k\nC1 singular 0 1u\n"
        ".tran 10u 1m\n.end\n"
    )
    waves = run_ngspice(text)
    assert waves.names == ["v(error)", "v(singular)", "i(v1)"]


@requires_ngspice
@pytest.mark.ngspice
def test_timeout_stops_ngspice_and_raises():
    # A billion time steps: far longer than the half-second allowed (and than the step
    # limit and the memory budget, which would refuse it before the start: lifted here)
    text = "slow\nV1 a 0 SIN(0 1 1meg)\nR1 a 0 1k\n.tran 1p 1m 0 1p\n.end\n"
    with pytest.raises(NgspiceError, match="did not finish within 0.5 s"):
        run_ngspice(text, timeout=0.5, limits=RunLimits(max_steps=None, max_memory=None))
