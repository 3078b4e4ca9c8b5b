"""Generality: three more models, each generated, checked, and run in ngspice against its ODE.

The models (tests/synthesis/models/): a damped 1-DOF oscillator with a symmetric gap (a dead
zone: both ``abs`` and ``deadzone`` realizations), a two-mass chain with a one-sided stop
between the masses (a kink in x2 - x1 entering both equations with opposite signs, a constant
part), and a driven first-order system with a Chua diode.
"""

import shutil
from pathlib import Path

import pytest

from circuitsim.compare.mapping import map_waveforms
from circuitsim.compare.signals import nrmsd_percent
from circuitsim.interop.ngspice import run_ngspice
from circuitsim.mechanics import load_model, solve
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.scalemap import ScaleMap

MODELS = Path(__file__).parent / "models"
requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)

CASES = [
    ("gap_oscillator", "abs"),
    ("gap_oscillator", "deadzone"),
    ("two_mass_stop", "abs"),
    ("chua_diode", "abs"),
]


@pytest.mark.parametrize(("name", "nonlinear"), CASES)
def test_generated_and_checked(tmp_path, name, nonlinear):
    system = load_model(MODELS / f"{name}.toml").system()
    result = generate(
        system, tmp_path / f"{name}.cir", SynthesisOptions(series="E96", nonlinear=nonlinear)
    )
    assert result.report.ok, result.report.summary()
    kinks = sum(len(term.abs_terms) for term in system.nonlinear)
    offsets = [e for e in result.report.entries if e.what.endswith("offset")]
    directions = sum(int((term.direction != 0).sum()) for term in system.nonlinear)
    assert len(offsets) == kinks * directions


@pytest.mark.parametrize("name", ["two_mass_stop", "chua_diode"])
def test_dead_zone_refused_where_the_term_is_not_one(tmp_path, name):
    system = load_model(MODELS / f"{name}.toml").system()
    with pytest.raises(SynthesisError, match="not a dead zone"):
        generate(system, tmp_path / "x.cir", SynthesisOptions(nonlinear="deadzone"))


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize(("name", "nonlinear"), CASES)
def test_ngspice_matches_the_ode(tmp_path, name, nonlinear):
    system = load_model(MODELS / f"{name}.toml").system()
    result = generate(
        system, tmp_path / f"{name}.cir", SynthesisOptions(series="exact", nonlinear=nonlinear)
    )
    waves = run_ngspice(result.netlist)
    traces = map_waveforms(waves, ScaleMap.load(result.scale_file))
    reference = solve(system, (0.0, result.synthesis.t_stop))
    for i, state in enumerate(system.states):
        t, values = traces[state]
        error = nrmsd_percent(reference.sol(t)[i], values)
        assert error <= 0.5, (state, error)
