"""The hunting study: ODE and circuit paths, continuation, critical speeds, bad input.

References: the linear wheelset's exact solution (scipy's expm), a single circuit run over
the chained time, MODEL.md's critical speed 55.6455 m/s.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from circuitsim.mechanics import load_model
from circuitsim.studies.hunting import measure, ode_branch, run_hunting, speed_grid
from circuitsim.studies.hunting_result import HuntingBranch, HuntingError, HuntingSettings

ROOT = Path(__file__).resolve().parents[2]
PUSH = 0.005
MODEL = load_model()


def free(speed: float, flange: bool):
    """The wheelset's free response from a 5 mm push (MODEL.md, paper Fig. 3)."""
    return MODEL.system(parameters={"V": speed, "a": 0.0, "y0": PUSH}, nonlinear={"flange": flange})


def test_ode_branch_below_critical_flange_off_decays_as_the_exact_solution():
    settings = HuntingSettings(settle=3.0, record=1.0, threshold=PUSH, bound=1.0, repush=0.0)
    speeds = np.array([45.0, 50.0])
    systems = [free(v, False) for v in speeds]
    branch, final, _ = ode_branch(systems, speeds, "up", settings, "y", False)
    # the exact solution x(t) = expm(A t) x0, the second step from the first's end
    x = systems[0].x0
    for k, system in enumerate(systems):
        t = np.linspace(3.0, 4.0, 4001)
        y = np.array([(expm(system.A * s) @ x)[0] for s in t])
        assert branch.amplitude[k] == pytest.approx(np.max(np.abs(y)), rel=1e-6)
        x = expm(system.A * 4.0) @ x
    assert branch.status == ["decaying", "decaying"]
    assert branch.amplitude[-1] < 1e-6 * PUSH  # ~0: 4.7e-9 m at 50 m/s after 8 s
    np.testing.assert_allclose(final, x, rtol=1e-6, atol=1e-11)  # solve: atol 1e-12
    assert list(branch.pushed) == [True, False]


def test_ode_steps_continue_from_the_previous_final_state():
    """Two steps at one speed equal one solve over both spans (strict continuation)."""
    from circuitsim.mechanics import solve

    settings = HuntingSettings(settle=1.0, record=0.5, threshold=PUSH, bound=1.0, repush=0.0)
    system = free(58.0, True)
    branch, final, _ = ode_branch([system, system], np.array([58.0, 58.0]), "up", settings,
                                  "y", True)  # fmt: skip
    whole = solve(system, (0.0, 3.0))
    np.testing.assert_allclose(final, whole.x[:, -1], rtol=1e-6, atol=1e-9)
    assert branch.amplitude[1] == pytest.approx(whole.max_abs("y", 2.5, 3.0), rel=1e-6)


def test_circuit_steps_continue_from_the_previous_final_state():
    """Two circuit steps at one speed end where one run over both spans ends."""
    from circuitsim.compare.sweep import sweep_circuits
    from circuitsim.solver.continuation import transient_from
    from circuitsim.studies.hunting import circuit_branch
    from circuitsim.synthesis.options import SynthesisOptions

    settings = HuntingSettings(settle=1.0, record=0.5, threshold=PUSH, bound=1.0, repush=0.0)
    ranges = {"y": 0.012, "psi": 0.012, "y_dot": 0.7, "psi_dot": 0.7}
    one = sweep_circuits([free(58.0, True)], SynthesisOptions(t_stop=1.5, ranges=ranges))
    two = sweep_circuits([free(58.0, True)], SynthesisOptions(t_stop=3.0, ranges=ranges))
    circuit = one.circuits[0]
    branch, final = circuit_branch(
        [circuit, circuit], one.scale_map, np.array([58.0, 58.0]), "up", settings, "y", PUSH,
        True,
    )  # fmt: skip
    assert list(branch.pushed) == [True, False] and final is not None
    tran = two.circuits[0].transient
    waves, whole = transient_from(two.circuits[0], tran.tstep, tran.tstop, tran.tmax)
    for state in ("y", "psi", "y_dot"):
        node = one.scale_map.states[state].node
        assert final.voltage(node) == pytest.approx(whole.voltage(node), rel=2e-3, abs=2e-3)
    # the second step's amplitude is the single run's over its last 0.5 s
    node = one.scale_map.states["y"].node
    late = waves.time >= 2.5 / one.scale_map.time_scale
    volts = np.max(np.abs(waves[f"v({node})"][late]))
    expected = volts / abs(one.scale_map.states["y"].volts_per_unit)
    assert branch.amplitude[1] == pytest.approx(expected, rel=2e-3)


def test_circuit_and_ode_amplitudes_agree_and_the_critical_speeds_bracket_the_linear_one():
    settings = HuntingSettings(settle=2.0, record=1.0)
    speeds = np.array([54.0, 55.0, 56.0, 57.0, 58.0])
    result = run_hunting(free, speeds, "V", "m/s", settings, flanges=(True,))
    for direction in ("up", "down"):
        agreement = result.agreement(direction, True)
        # measured on this grid: max abs 4.4e-6 m up, 3.6e-6 m down, NRMSD 0.020 %, 0.019 %;
        # 2e-5 m is 0.2 % of the 10 mm cycle
        assert agreement["steps"] == speeds.size
        assert agreement["max_abs"] < 2e-5
        assert agreement["nrmsd"] < 1e-3
    for path in ("ode", "circuit"):
        up, down = result.critical(path, True)
        assert up == 56.0 and down == 56.0  # the first grid speed above 55.6455 m/s
    cycle = result.branch("ode", "down", True)
    assert cycle.status[:3] == ["steady"] * 3
    assert 0.009 < cycle.amplitude[0] < 0.0105  # flange-limited: just past eta = 9 mm
    assert "V (m/s),direction,path,flange,amplitude_y (m)" in result.csv_text()


def _branch(direction, speeds, amplitude, status):
    speeds = np.array(speeds, dtype=float)
    pushed = np.zeros(speeds.size, dtype=bool)
    return HuntingBranch("ode", direction, True, speeds, np.array(amplitude), status, pushed)


def test_critical_speeds_show_hysteresis_of_a_subcritical_branch():
    up = _branch("up", [50, 51, 52, 53], [0, 0, 0.01, 0.01],
                 ["decaying", "decaying", "growing", "steady"])  # fmt: skip
    down = _branch("down", [53, 52, 51, 50], [0.01, 0.01, 0.01, 0],
                   ["steady", "steady", "steady", "decaying"])  # fmt: skip
    assert up.critical(0.005) == 52.0
    assert down.critical(0.005) == 51.0  # the cycle holds below where it appeared
    grows = _branch("up", [50, 51, 52], [0, 0.01, 1.0], ["decaying", "growing", "unbounded"])
    assert grows.critical(0.005) is None and grows.onset() == 51.0
    # flange off the system is linear: a slow decay that reads as steady is no limit cycle
    linear = _branch("down", [53, 52, 51], [0.1, 0.1, 0.05], ["growing", "steady", "decaying"])
    linear.flange = False
    assert linear.critical(0.005) is None and linear.onset() == 52.0


def test_measure_tells_decay_growth_and_steady_cycles():
    settings = HuntingSettings(settle=1.0, record=1.0, threshold=0.001, bound=1.0)
    t = np.linspace(0, 2, 20001)
    wave = np.sin(2 * np.pi * 8.5 * t)
    assert measure(t, 0.01 * wave, settings) == (pytest.approx(0.01, rel=1e-3), "steady")
    assert measure(t, 0.01 * np.exp(-t) * wave, settings)[1] == "decaying"
    assert measure(t, 0.01 * np.exp(t) * wave, settings)[1] == "growing"
    assert measure(t, 10 * wave, settings)[1] == "unbounded"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("60:50:1", "STOP >= START"),
        ("55", "at least two speeds"),
        ("56,55", "increasing order"),
        ("a:b:c", "START:STOP:STEP"),
        ("50:60:0", "STEP > 0"),
    ],
)
def test_bad_speed_ranges_are_refused(text, message):
    with pytest.raises(HuntingError, match=message) as caught:
        speed_grid(text)
    assert "--speeds" in str(caught.value)


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--speeds", "70:40:1"], "--speeds '70:40:1'"),
        (["--speeds", "0,10"], "V = 0 m/s: the model cannot be built"),
        (["--speeds", "50:60:1", "--speed", "55"], "V is swept"),
        (["--speeds", "50:60:1", "--settle", "0"], "--settle"),
        (["--speeds", "50:60:1", "--y0", "0"], "the push is 0"),
    ],
)
def test_cli_bad_input_exits_2_with_one_clear_line(arguments, message, tmp_path):
    run = subprocess.run(
        [sys.executable, "-m", "circuitsim", "hunting", *arguments, "--no-circuit",
         "--out", str(tmp_path)],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert run.returncode == 2, run.stderr
    assert message in run.stderr
    assert "Traceback" not in run.stderr
    assert not (tmp_path / "hunting.csv").exists()


def _hunting(arguments, tmp_path):
    return subprocess.run(
        [sys.executable, "-m", "circuitsim", "hunting", *arguments, "--out", str(tmp_path)],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip


def test_cli_writes_the_csv_figure_and_critical_speeds(tmp_path):
    run = _hunting(["--speeds", "55,57", "--settle", "1", "--record", "0.5", "--flange"], tmp_path)
    assert run.returncode == 0, run.stderr
    assert "linear critical V: 55.6455 m/s" in run.stdout
    assert "flange on, circuit: limit cycle appears at" in run.stdout
    assert "ETA" in run.stderr
    rows = (tmp_path / "hunting.csv").read_text().splitlines()
    assert rows[0] == "V (m/s),direction,path,flange,amplitude_y (m),status,cycle,pushed"
    assert len(rows) == 1 + 2 * 2 * 2  # 2 speeds x up/down x ode/circuit
    assert (tmp_path / "hunting.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_runs_the_bogie_on_its_speed_parameter(tmp_path):
    """Any model with a speed-like parameter: the bogie's V, its first state y1 pushed."""
    run = _hunting(
        ["--model", str(ROOT / "circuitsim/mechanics/models/bogie.toml"), "--speeds", "60,75",
         "--settle", "0.5", "--record", "0.5", "--no-circuit", "--flange"],
        tmp_path,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert "linear critical V: 67.1609 m/s" in run.stdout
    rows = (tmp_path / "hunting.csv").read_text().splitlines()
    assert rows[0].startswith("V (m/s),direction,path,flange,amplitude_y1 (m),")
    assert len(rows) == 1 + 2 * 2
