"""A switch's transition at its crossing: a switch discharging a capacitor against the exact
solution and ngspice's tight trace; the rule that locates the crossing."""

import numpy as np
import pytest

from circuitsim.netlist.reader import parse_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.devices.switch import transition_retry
from tests.solver.conftest import requires_ngspice

KERNELS = ["python", "ports", "compiled"]
TAU = 100 * 1e-6  # RON C, s
T_ON = 0.5e-3  # the ramp 0 -> 1 V over 1 ms crosses VT = 0.5 V here, s

DISCHARGE = """* a switch discharging a capacitor when its control ramp crosses 0.5 V
V1 ctl 0 PWL(0 0 1m 1)
C1 a 0 1u IC=1
S1 a 0 ctl 0 SWX
.model SWX SW(vt=0.5 vh=0 ron=100 roff=1e12)
.tran 1u 1m uic
.end
"""


def exact(t: np.ndarray) -> np.ndarray:
    """v(a), volts: 1 until the crossing, then exp(-(t - T_ON) / TAU) (ROFF's leak: 1e-8 of
    it, below what is checked)."""
    return np.where(t < T_ON, 1.0, np.exp(-(t - T_ON) / TAU))


@pytest.mark.parametrize("kernel", KERNELS)
def test_switch_discharging_a_capacitor_turns_on_at_the_crossing(kernel):
    circuit = parse_netlist(DISCHARGE)
    waves = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=kernel))
    t, v = waves.time, waves["v(a)"]
    # turning on for the whole step that crosses (a 1 us step, TAU = 100 us) was 3.6e-3 off
    assert np.max(np.abs(v - exact(t))) < 1e-4
    assert waves.stats["accepted"] < 1100  # the crossing costs a few steps, not a cascade


@requires_ngspice
def test_switch_discharge_agrees_with_ngspice_tight_trace():
    from circuitsim.interop.ngspice import run_ngspice

    tight = DISCHARGE.replace(".tran 1u 1m uic", ".tran 1u 1m 0 10n uic")
    tight = tight.replace(".end", ".options reltol=1e-6\n.end")
    reference = run_ngspice(tight, probes=["v(a)"])
    assert np.max(np.abs(reference["v(a)"] - exact(reference.time))) < 1e-3  # the referee
    ours = simulate(parse_netlist(DISCHARGE))
    on_theirs = np.interp(reference.time, ours.time, ours["v(a)"])
    assert np.max(np.abs(on_theirs - reference["v(a)"])) < 1e-3


def test_transition_rule_stops_short_then_steps_just_past():
    h, min_step = 1e-6, 1e-17
    # a crossing half way through a step after steps of 1 us: end short of it, unchanged
    assert transition_retry(0.5, h, 1e-6, min_step) == pytest.approx(0.5e-6 * (1 - 1e-3))
    # the crossing 0.5 ns after the step's start (the step before: 1 us): a 1 ns step
    assert transition_retry(0.5e-9 / h, h, 1e-6, min_step) == pytest.approx(1e-9)
    # that step, retried, is accepted with its transition; so is a step without one
    assert transition_retry(0.5, 1e-9, 1e-6, min_step) == 0.0
    assert transition_retry(1.0, h, 1e-6, min_step) == 0.0
