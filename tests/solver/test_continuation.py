"""transient_from: a run that carries on from where another ended, against closed forms and
against one uninterrupted run."""

import numpy as np
import pytest

from circuitsim.netlist.circuit import (
    Capacitor,
    Circuit,
    Diode,
    Inductor,
    Model,
    Resistor,
    Sin,
    VoltageSource,
)
from circuitsim.solver import SimulationOptions, transient
from circuitsim.solver.continuation import initial_state, transient_from
from circuitsim.solver.errors import CircuitInputError

KERNELS = ["python", "compiled", "ports"]


def rc(resistance=1e3, v0=2.0) -> Circuit:
    """R from a to ground, C (1 uF, IC=v0) from a to ground: tau = R * 1 uF."""
    return Circuit(
        elements=[Resistor("R1", "a", "0", resistance), Capacitor("C1", "a", "0", 1e-6, ic=v0)]
    )


@pytest.mark.parametrize("kernel", KERNELS)
def test_rc_discharge_in_chunks_follows_the_exponential(kernel):
    """Five chunks of 1 ms equal 2 exp(-t / 1 ms): the capacitor's charge crosses each
    boundary (a restart from .ic would jump back to 2 V)."""
    options = SimulationOptions(reltol=1e-6, kernel=kernel)
    state, ends = None, []
    for _ in range(5):
        waves, state = transient_from(rc(), 1e-5, 1e-3, state=state, options=options)
        assert waves.time[-1] == pytest.approx(1e-3)
        ends.append(state.voltage("a"))
    exact = 2.0 * np.exp(-np.arange(1, 6))
    np.testing.assert_allclose(ends, exact, rtol=2e-3)


@pytest.mark.parametrize("kernel", KERNELS)
def test_a_changed_resistor_acts_from_the_state_reached(kernel):
    """1 ms at tau = 1 ms, then R doubled: 2 e^-1 e^-(t/2 ms) (the matrix restamped, the
    charge carried)."""
    options = SimulationOptions(reltol=1e-6, kernel=kernel)
    _, state = transient_from(rc(1e3), 1e-5, 1e-3, state=None, options=options)
    waves, _ = transient_from(rc(2e3), 1e-5, 2e-3, state=state, options=options)
    exact = 2.0 * np.exp(-1.0) * np.exp(-waves.time / 2e-3)
    assert np.max(np.abs(waves["a"] - exact)) < 2e-3 * 2.0 * np.exp(-1.0)


def test_with_voltages_charges_the_capacitor():
    """A kick: the state's node set to 5 V decays from 5 V."""
    state = initial_state(rc()).with_voltages({"a": 5.0})
    assert state.voltage("a") == 5.0
    waves, _ = transient_from(rc(), 1e-5, 1e-3, state=state, options=SimulationOptions(reltol=1e-6))
    np.testing.assert_allclose(waves["a"][-1], 5.0 * np.exp(-1.0), rtol=2e-3)


@pytest.mark.parametrize("kernel", ["python", "ports"])
def test_initial_state_is_the_uic_start(kernel):
    """From the circuit's own uic start (IC=1.5 V: a charge, node a at 0 V) the run is the
    plain uic run, point for point."""
    options = SimulationOptions(reltol=1e-6, kernel=kernel)
    state = initial_state(rc(v0=1.5))
    waves, _ = transient_from(rc(v0=0.0), 1e-5, 1e-3, state=state, options=options)
    plain = transient(rc(v0=1.5), 1e-5, 1e-3, uic=True, options=options)
    np.testing.assert_array_equal(waves.time, plain.time)
    np.testing.assert_allclose(waves["a"], plain["a"], rtol=1e-12, atol=1e-15)


def test_an_inductor_current_is_carried():
    """RL: i(t) = 1 A e^(-t R/L); the current is an unknown, not a node voltage, and
    crosses the boundary too."""
    circuit = Circuit(
        elements=[Inductor("L1", "a", "0", 1e-3, ic=1.0), Resistor("R1", "a", "0", 1.0)]
    )
    options = SimulationOptions(reltol=1e-6)
    _, state = transient_from(circuit, 1e-5, 1e-3, state=None, options=options)
    waves, state = transient_from(circuit, 1e-5, 1e-3, state=state, options=options)
    # v(a) = -L di/dt = R i (the current leaves L1 at a... SPICE sign), |v| = R |i|
    np.testing.assert_allclose(abs(state.voltage("a")), np.exp(-2.0), rtol=2e-3)


def test_a_state_of_another_wiring_is_refused():
    _, state = transient_from(rc(), 1e-5, 1e-4)
    other = Circuit(
        elements=[
            Resistor("R1", "a", "b", 1e3),
            Resistor("R2", "b", "0", 1e3),
            Capacitor("C1", "a", "0", 1e-6),
        ]
    )
    with pytest.raises(CircuitInputError, match="another wiring"):
        transient_from(other, 1e-5, 1e-4, state=state)


@pytest.mark.parametrize("kernel", ["python", "ports"])
def test_chunks_of_a_diode_circuit_equal_one_run(kernel):
    """A sine into a diode clipper with an RC load, run in 10 chunks (the source's phase
    carried by hand) against one run: a diode's internal node (its series resistance) is
    carried too; from .ic alone it restarted at 0 V and the chunked run failed."""
    model = Model("D1", "D", {"is": 2.4e-9, "n": 1.85, "rs": 1.1, "cjo": 2e-12})

    def clipper(phase: float) -> Circuit:
        return Circuit(
            elements=[
                VoltageSource("V1", "in", "0", waveform=Sin(0.0, 2.0, 1e3, 0.0, 0.0, phase)),
                Resistor("R1", "in", "a", 1e3),
                Diode("D1", "a", "0", "D1"),
                Resistor("R2", "a", "b", 1e3),
                Capacitor("C1", "b", "0", 1e-7),
            ],
            models={"d1": model},
        )

    options = SimulationOptions(kernel=kernel)
    whole = transient(clipper(0.0), 1e-6, 5e-3, tmax=1e-6, uic=True, options=options)
    state, times, values = None, [], []
    for k in range(10):
        start = k * 5e-4
        waves, state = transient_from(
            clipper(360.0 * 1e3 * start % 360.0), 1e-6, 5e-4, 1e-6, state, options
        )
        times.append(start + waves.time)
        values.append(waves["b"])
    chunked = np.interp(whole.time, np.concatenate(times), np.concatenate(values))
    span = np.ptp(whole["b"])
    keep = whole.time > 5e-4
    assert np.sqrt(np.mean((chunked[keep] - whole["b"][keep]) ** 2)) < 1e-3 * span
