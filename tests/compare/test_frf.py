"""Frequency response functions: the model's against analytic receptances, the circuit's
.ac against the model's (both engines), peaks and half-power damping, the CLI verb.

Independent answers: a mass-spring-damper forced by F0 sin(2 pi f t), receptance
X/F = 1 / (k - m w^2 + j c w), resonance at f_n sqrt(1 - 2 zeta^2) and half-power bandwidth
2 zeta f_n for light damping, written out here; the wheelset inside its clearance, where the
flange force is zero, against (j w I - A)^-1 on the linear part A of the stability analysis.
"""

import json
import math

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.compare.frf import (
    circuit_response,
    departure,
    differences,
    model_response,
    resonances,
)
from circuitsim.mechanics import load_model
from circuitsim.mechanics.errors import ModelError
from circuitsim.mechanics.frf import region_matrix
from circuitsim.mechanics.stability import state_matrix
from circuitsim.netlist.circuit import AcSweep
from circuitsim.synthesis import synthesize
from circuitsim.synthesis.options import SynthesisOptions
from tests.conftest import requires_ngspice

M, C, K = 2.0, 3.0, 800.0  # kg, N s/m, N/m: f_n = 3.18 Hz, zeta = 0.0375

OSCILLATOR = f"""
[model]
name = "oscillator"
kind = "second_order"

[coordinates]
names = ["x"]
units = ["m"]

[parameters]
m = {{ value = {M}, unit = "kg" }}
c = {{ value = {C}, unit = "N s/m" }}
k = {{ value = {K}, unit = "N/m" }}
f = {{ value = 3.0, unit = "Hz" }}
F0 = {{ value = 10.0, unit = "N" }}

[options]
freq = "f"

[matrices]
M = [["m"]]
C = [["c"]]
K = [["k"]]

[forcing.push]
amplitude = "F0"
unit = "N"
frequency = "f"
enters = {{ x = 1 }}
"""


@pytest.fixture(scope="module")
def oscillator(tmp_path_factory):
    path = tmp_path_factory.mktemp("frf") / "oscillator.toml"
    path.write_text(OSCILLATOR)
    return path, load_model(path).system()


def _receptance(f):
    w = 2 * np.pi * f
    return 1 / (K - M * w**2 + 1j * C * w)


def test_the_model_s_receptance_is_the_oscillator_s(oscillator):
    _, system = oscillator
    sweep = AcSweep("dec", 50, 0.1, 100.0)
    response = model_response(system, sweep)
    f = response.frequencies
    assert response.inputs == ("push",) and response.states == ("x", "x_dot")
    assert np.allclose(response.of("push", "x"), _receptance(f), rtol=1e-12)
    assert np.allclose(response.of("push", "x_dot"), 2j * np.pi * f * _receptance(f), rtol=1e-12)


def test_peaks_and_half_power_damping_are_read_off_the_curve(oscillator):
    _, system = oscillator
    fn = math.sqrt(K / M) / (2 * math.pi)
    zeta = C / (2 * math.sqrt(K * M))
    response = model_response(system, AcSweep("dec", 2000, 1.0, 10.0))
    (peak,) = resonances(response.frequencies, response.of("push", "x"))
    assert peak.frequency == pytest.approx(fn * math.sqrt(1 - 2 * zeta**2), rel=1e-5)
    assert peak.magnitude == pytest.approx(
        1 / (C * 2 * math.pi * fn * math.sqrt(1 - zeta**2)), rel=1e-4
    )
    # half-power points of |X/F|: r^2 = 1 - 2 zeta^2 -+ 2 zeta sqrt(1 - zeta^2)
    low, high = (1 - 2 * zeta**2 + s * 2 * zeta * math.sqrt(1 - zeta**2) for s in (-1, 1))
    bandwidth = (math.sqrt(high) - math.sqrt(low)) / (2 * math.sqrt(1 - 2 * zeta**2))
    assert peak.damping_ratio == pytest.approx(bandwidth, rel=1e-4)
    assert peak.damping_ratio == pytest.approx(zeta, rel=5e-3)  # exact as zeta -> 0


def test_the_wheelset_inside_its_clearance_has_the_linear_part_s_matrix():
    model = load_model(None)
    system = model.system(None, model.option_parameters({"freq": 3.0}), {"flange": True})
    assert np.array_equal(region_matrix(system), state_matrix(model))
    # in contact (y beyond eta) the flange stiffness adds to the lateral one
    inside = region_matrix(system, np.array([0.02, 0, 0, 0]))
    assert not np.allclose(inside, state_matrix(model))
    with pytest.raises(ModelError, match="lies on kink"):
        region_matrix(system, np.array([float(model.parameters["eta"]), 0, 0, 0]))


@pytest.mark.parametrize("engine", ["builtin", pytest.param("ngspice", marks=requires_ngspice)])
def test_the_ideal_circuit_s_frf_is_the_model_s(engine):
    """The issue's bound: within 0.1 dB and 1 degree over 0.1-100 Hz of model frequency."""
    model = load_model(None)
    system = model.system(None, model.option_parameters({"freq": 3.0}), {"flange": True})
    sweep = AcSweep("dec", 20, 0.1, 100.0)
    synthesis = synthesize(system, SynthesisOptions(series="exact"))
    ours = circuit_response(synthesis, system, sweep, engine)
    reference = model_response(system, sweep)
    for state in system.states:
        d_db, d_deg = differences(reference.of("track", state), ours.of("track", state))
        assert np.nanmax(np.abs(d_db)) < 0.1 and np.nanmax(np.abs(d_deg)) < 1.0, state
        assert np.count_nonzero(np.isnan(d_db)) == 0


def test_a_faster_time_scale_moves_the_tl074_departure_down_in_model_frequency():
    """The op-amps' bandwidth is fixed in circuit hertz: a circuit run K times faster than
    the model meets it K times lower in model frequency."""
    model = load_model(None)
    system = model.system(None, model.option_parameters({"freq": 3.0}), {"flange": True})
    sweep = AcSweep("dec", 20, 1.0, 1e5)
    reference = model_response(system, sweep).of("track", "y_dot")
    found = {}
    for scale in (1.0, 10.0):
        options = SynthesisOptions(opamp="tl074", series="exact", time_scale=scale)
        ours = circuit_response(synthesize(system, options), system, sweep).of("track", "y_dot")
        found[scale] = departure(sweep_frequencies(sweep), reference, ours, 0.1, 1.0)
    assert found[1.0] is not None and found[10.0] is not None
    assert found[10.0] < found[1.0] / 3


def sweep_frequencies(sweep):
    from circuitsim.compare.frf import model_sweep

    return model_sweep(sweep)


def test_cli_frf_prints_writes_and_exits_by_the_bounds(oscillator, tmp_path, capsys):
    path, _ = oscillator
    csv, png = tmp_path / "o.csv", tmp_path / "o.png"
    args = ["frf", "--model", str(path), "--engine", "builtin", "--fmin", "0.5", "--fmax", "50"]
    assert main([*args, "--csv", str(csv), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "push -> x: model peak 3.1" in out and "within 0.1 dB / 1 deg" in out
    header = csv.read_text().splitlines()[0].split(",")
    assert header[:3] == ["frequency", "model:push:x:mag", "model:push:x:deg"]
    assert "builtin:push:x_dot:deg" in header and png.stat().st_size > 10_000
    assert main([*args, "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["frequencies"][2] == 41 and not summary["beyond"]
    assert main([*args, "--region", "nowhere=1"]) == 2
    assert main([*args, "--fmax", "0.1"]) == 2
