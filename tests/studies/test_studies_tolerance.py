"""The tolerance study: seeded draws, the realized critical speed, and a part-tolerance
spread against its closed form."""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from circuitsim.compare.errors import ComparisonError
from circuitsim.mechanics import load_model
from circuitsim.netlist.circuit import Capacitor, Resistor
from circuitsim.studies.reproduce import Scenario
from circuitsim.studies.tolerance import Tolerances, draw_circuits, run_tolerance
from circuitsim.synthesis.options import SynthesisOptions

ROOT = Path(__file__).resolve().parents[2]

LEAK_MODEL = Path(__file__).resolve().parents[1] / "studies" / "leak.toml"


@pytest.fixture(scope="module")
def wheelset():
    return Scenario(3.0, True).system(load_model())


def test_unperturbed_parts_realize_the_models_critical_speed(wheelset):
    result = run_tolerance(
        wheelset, Tolerances(0.0, 0.0), n=2, options=SynthesisOptions(series="exact"),
        simulate=False,
    )  # fmt: skip
    assert result.critical_speed_model == pytest.approx(55.6455, abs=1e-4)  # MODEL.md
    assert np.allclose(result.critical_speed, result.critical_speed_model, rtol=1e-9)
    assert result.speed == 55.0 and result.unstable_fraction == 0.0


def test_a_seed_draws_the_same_circuits_and_results(wheelset):
    tol = Tolerances(0.01, 0.05)
    first = run_tolerance(wheelset, tol, n=3, seed=7, workers=1)
    again = run_tolerance(wheelset, tol, n=3, seed=7, workers=2)
    other = run_tolerance(wheelset, tol, n=3, seed=8, simulate=False)
    assert np.array_equal(first.critical_speed, again.critical_speed)
    for state, metrics in first.metrics.items():
        for name, values in metrics.items():
            assert np.array_equal(values, again.metrics[state][name]), (state, name)
    assert np.array_equal(first.passed, again.passed)
    assert not np.array_equal(first.critical_speed, other.critical_speed)
    # the first circuits of a longer run are the same circuits
    longer = run_tolerance(wheelset, tol, n=5, seed=7, simulate=False)
    assert np.array_equal(longer.critical_speed[:3], first.critical_speed)


def test_drawn_parts_stay_within_a_uniform_tolerance(wheelset):
    from circuitsim.synthesis.translator import synthesize

    base = synthesize(wheelset, SynthesisOptions(series="exact")).circuit
    samples = draw_circuits(base, Tolerances(0.01, 0.05), 20, seed=3)
    assert np.all(np.abs(samples.resistor_errors) <= 0.01)
    assert np.all(np.abs(samples.capacitor_errors) <= 0.05)
    assert samples.capacitor_errors.shape == (20, 4)  # C1..C4
    nominal = {e.name: e for e in base.elements}
    circuit = samples.circuits[5]
    for e in circuit.elements:
        if isinstance(e, Resistor):
            k = samples.resistors.index(e.name)
            expected = float(nominal[e.name].resistance) * (1 + samples.resistor_errors[5, k])
            assert float(e.resistance) == expected
        if isinstance(e, Capacitor):
            k = samples.capacitors.index(e.name)
            expected = float(nominal[e.name].capacitance) * (1 + samples.capacitor_errors[5, k])
            assert float(e.capacitance) == expected


def test_an_rc_integrators_gain_spread_matches_the_closed_form():
    """dx/dt = -x/tau realized by one integrator: its coefficient is 1/(R C) (the inverter's
    ratio cancels: the state is fed back from the integrator's own output), so with R and C
    off by independent uniform errors in +-r and +-c the realized/model ratio
    X = 1/((1+e_R)(1+e_C)) has E[X] = L(r) L(c), L(t) = ln((1+t)/(1-t))/(2t), and
    E[X^2] = 1/((1-r^2)(1-c^2))."""
    system = load_model(LEAK_MODEL).system()
    r, c, n = 0.05, 0.10, 3000
    result = run_tolerance(
        system, Tolerances(r, c), n=n, seed=11,
        options=SynthesisOptions(series="exact", ranges={"x": 1.0}),
        simulate=False,
    )  # fmt: skip
    X = result.A_realized[:, 0, 0] / float(system.A[0, 0])

    def L(t):
        return math.log((1 + t) / (1 - t)) / (2 * t)

    mean = L(r) * L(c)
    second = 1 / ((1 - r * r) * (1 - c * c))
    sd = math.sqrt(second - mean * mean)
    # to first order the relative errors add in quadrature: sd ~ sqrt((r^2 + c^2) / 3)
    assert sd == pytest.approx(math.sqrt((r * r + c * c) / 3), rel=0.02)
    # the sample mean within 4 standard errors, the sample sd within 4 of its own (about
    # sd / sqrt(2 n) for a near-normal spread)
    assert abs(np.mean(X) - mean) < 4 * sd / math.sqrt(n)
    assert abs(np.std(X, ddof=1) - sd) < 4 * sd / math.sqrt(2 * n)
    assert np.all(np.isnan(result.critical_speed))  # no speed in this model


def test_offsets_need_tl074_sections(wheelset):
    with pytest.raises(ComparisonError, match="TL074"):
        run_tolerance(wheelset, Tolerances(0.0, 0.0, offset=3e-3), n=1, simulate=False)


def test_gaussian_offsets_have_the_stated_sigma(wheelset):
    from circuitsim.synthesis.translator import synthesize

    base = synthesize(wheelset, SynthesisOptions(opamp="tl074", series="exact")).circuit
    samples = draw_circuits(base, Tolerances(0.03, 0.0, 3e-3, "gaussian"), 400, seed=5)
    assert samples.offsets.shape == (400, 13)  # 8 state sections + 5 in the flange blocks
    assert np.std(samples.offsets) == pytest.approx(3e-3, rel=0.05)  # 5200 draws
    assert np.std(samples.resistor_errors) == pytest.approx(0.01, rel=0.05)  # 3 % = 3 sigma
    call = next(e for e in samples.circuits[0].elements if e.name == "XU1A")
    assert call.params["vos"] == samples.offsets[0, samples.sections.index("U1A")]


def test_the_tolerance_verb_writes_json_and_histograms(tmp_path):
    out = tmp_path / "mc"
    done = subprocess.run(
        [sys.executable, "-m", "circuitsim", "tolerance", "-n", "3", "--seed", "2",
         "--series", "exact", "--jobs", "2", "--out", str(out)],
        capture_output=True, text=True, cwd=ROOT, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    data = json.loads((out / "tolerance.json").read_text())
    assert data["n"] == 3 and len(data["critical_speed"]) == 3
    assert set(data["metrics"]) == {"y", "psi", "y_dot", "psi_dot"}
    assert len(data["passed"]) == 3 and data["yield"] is not None
    assert (out / "tolerance.png").stat().st_size > 10_000
    assert "simulated and compared 3 of 3 circuits" in done.stderr
    assert "yield:" in done.stdout


def test_the_tolerance_verb_refuses_an_offset_without_tl074(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "circuitsim", "tolerance", "--offset", "3m", "--out",
         str(tmp_path / "x")],
        capture_output=True, text=True, cwd=ROOT, timeout=120,
    )  # fmt: skip
    assert done.returncode == 2
    assert "--offset needs --opamp tl074" in done.stderr


def test_the_studys_metrics_are_the_comparisons(wheelset):
    """state_metrics leaves out only the phase lag: its numbers are compare_traces' own."""
    from circuitsim.compare.case import reference_traces
    from circuitsim.compare.comparison import compare_traces
    from circuitsim.compare.mapping import map_waveforms
    from circuitsim.solver import simulate
    from circuitsim.studies.tolerance import METRICS, state_metrics
    from circuitsim.synthesis.translator import synthesize

    synthesis = synthesize(wheelset, SynthesisOptions(series="exact"))
    circuit = draw_circuits(synthesis.circuit, Tolerances(0.01, 0.05), 1, seed=4).circuits[0]
    traces = map_waveforms(simulate(circuit), synthesis.scale_map, list(wheelset.states))
    _, reference = reference_traces(wheelset, synthesis.t_stop)
    ours = state_metrics(reference, traces)
    theirs = compare_traces(reference, traces).states
    for state, values in ours.items():
        for name in METRICS:
            assert values[name] == getattr(theirs[state], name), (state, name)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--seed", "-1"], "argument --seed: expected an integer >= 0"),
        (["--resistor-tolerance", "150%"], "expected a tolerance like 1% or 0.01"),
        (["-n", "0"], "--samples must be at least 1"),
    ],
)
def test_the_tolerance_verb_refuses_bad_values(tmp_path, argv, message):
    done = subprocess.run(
        [sys.executable, "-m", "circuitsim", "tolerance", *argv, "--out", str(tmp_path / "x")],
        capture_output=True, text=True, cwd=ROOT, timeout=120,
    )  # fmt: skip
    assert done.returncode == 2
    assert message in done.stderr
