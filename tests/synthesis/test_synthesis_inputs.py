"""Inputs beyond sinusoids in the circuit: PWL sources against the direct solution.

A damped oscillator driven at once by a step, a half-sine bump and inline points with a jump
(tests/synthesis/models/driven_oscillator.toml), and the wheelset running over the shipped
random track profile: generated, checked, simulated by both engines, within 0.5 % NRMSD.
"""

import shutil
from pathlib import Path

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.compare.case import run_case
from circuitsim.mechanics import load_model
from circuitsim.netlist.circuit import Pwl
from circuitsim.netlist.reader import read_netlist
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.inputs import SAMPLING_ERROR
from circuitsim.synthesis.options import SynthesisOptions

MODELS = Path(__file__).parent / "models"
requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)
ENGINES = ["builtin", pytest.param("ngspice", marks=[requires_ngspice, pytest.mark.ngspice])]


def driven():
    return load_model(MODELS / "driven_oscillator.toml").system()


@pytest.mark.parametrize("dialect", ["ngspice", "ltspice", "multisim"])
def test_pwl_sources_are_written_and_checked(tmp_path, dialect):
    system = driven()
    result = generate(system, tmp_path / "d.cir", SynthesisOptions(time_scale=10.0),
                      dialect)  # fmt: skip
    assert result.report.ok, result.report.summary()
    circuit = read_netlist(result.netlist)
    pwl = {e.name: e.waveform.points for e in circuit.elements if isinstance(
        getattr(e, "waveform", None), Pwl) and e.name.startswith("VFG")}  # fmt: skip
    assert len(pwl) == 3
    for points in pwl.values():
        times = np.array([float(t) for t, _ in points])
        assert times[0] == 0 and np.all(np.diff(times) > 0)  # a jump is a short ramp
        assert times[-1] <= 2.5 / 10.0 + 1e-12 or times[-2] < 2.5 / 10.0  # the time scale
    # the bump (0.15 s half-sine) is sampled finely enough for SAMPLING_ERROR of its peak:
    # at most h^2/8 |u''| = h^2 pi^2 / (8 T^2) of the peak
    bump = np.array([float(t) for t, _ in max(pwl.values(), key=len)]) * 10.0
    h = np.diff(bump[(bump >= 1.0) & (bump <= 1.15 + 1e-9)]).max()
    assert h**2 * np.pi**2 / (8 * 0.15**2) <= SAMPLING_ERROR


@pytest.mark.parametrize("engine", ENGINES)
def test_driven_oscillator_circuit_matches_the_ode(engine):
    case = run_case(driven(), SynthesisOptions(series="exact"), engine)
    for state, metrics in case.comparison.states.items():
        assert metrics.nrmsd_percent <= 0.5, (engine, state, metrics.nrmsd_percent)


@pytest.mark.parametrize("engine", ENGINES)
def test_track_irregularity_end_to_end(tmp_path, capsys, engine):
    netlist = tmp_path / "track.cir"
    code = main(["compare", "--forcing", "irregularity", "--engine", engine,
                 "--write-netlist", str(netlist)])  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0, out
    assert "PASS" in out and "time step 0.00027 s set by the mode of the region flange" in out
    assert "PWL(" in netlist.read_text()
