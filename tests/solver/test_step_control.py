"""Step control as ngspice: TMAX default, breakpoints hit exactly, tstart honoured."""

import numpy as np
import pytest

from circuitsim.netlist.circuit import Capacitor, Circuit, Pulse, Pwl, Resistor, VoltageSource
from circuitsim.solver import SimulationOptions, transient


def resistive(waveform=None) -> Circuit:
    return Circuit(
        elements=[
            VoltageSource("V1", "a", "0", dc=1.0, waveform=waveform),
            Resistor("R1", "a", "0", 1e3),
        ]
    )


def test_default_tmax_is_min_of_tstep_and_span_over_50():
    # nothing limits the step but TMAX: no charges, no breakpoints besides tstop
    w = transient(resistive(), 1e-3, 10e-3)  # tstep = 1 ms > 10 ms / 50 = 0.2 ms
    assert np.max(np.diff(w.time)) <= 0.2e-3 * (1 + 1e-9)
    assert np.max(np.diff(w.time)) >= 0.2e-3 * (1 - 1e-9)
    w = transient(resistive(), 1e-4, 100e-3)  # tstep = 0.1 ms < 100 ms / 50 = 2 ms
    assert np.max(np.diff(w.time)) <= 1e-4 * (1 + 1e-9)


def test_given_tmax_is_honoured():
    w = transient(resistive(), 1e-3, 10e-3, tmax=3e-5)
    assert np.max(np.diff(w.time)) <= 3e-5 * (1 + 1e-9)


@pytest.mark.parametrize("kernel", ["python", "compiled"])
def test_pwl_and_pulse_corners_are_time_points(kernel):
    pwl = Pwl(((0.0, 0.0), (1.3e-3, 1.0), (2.71e-3, -1.0), (4e-3, 0.5)))
    c = resistive(pwl)
    c.add(
        VoltageSource("V2", "b", "0", waveform=Pulse(0.0, 1.0, 0.77e-3, 1e-5, 2e-5, 1e-3, 3e-3)),
        Resistor("R2", "b", "c", 1e3),
        Capacitor("C2", "c", "0", 1e-7),
    )
    w = transient(c, 1e-4, 5e-3, options=SimulationOptions(kernel=kernel))
    assert w.stats["kernel"] == kernel
    corners = [1.3e-3, 2.71e-3, 4e-3, 0.77e-3, 0.78e-3, 1.78e-3, 1.8e-3, 3.77e-3, 3.78e-3]
    for corner in corners:
        assert np.min(np.abs(w.time - corner)) < 1e-15, corner
    # the PWL value is exact at its corners and linear between them
    assert np.allclose(w["a"], np.interp(w.time, *np.array(pwl.points).T), atol=1e-12)


def test_tstart_drops_earlier_points():
    w = transient(resistive(), 1e-4, 5e-3, tstart=2e-3)
    assert w.time[0] >= 2e-3 - 1e-12 and w.time[-1] == 5e-3
