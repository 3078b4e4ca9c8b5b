"""Circuits with closed-form answers: RC, RL, RLC under steps and sines, an ideal integrator."""

import numpy as np
import pytest

from circuitsim.netlist.circuit import (
    Capacitor,
    Circuit,
    Inductor,
    Pulse,
    Resistor,
    Sin,
    Vcvs,
    VoltageSource,
)
from circuitsim.solver import SimulationOptions, transient

KERNELS = ["python", "compiled", "ports"]


def tight(kernel: str) -> SimulationOptions:
    return SimulationOptions(reltol=1e-6, kernel=kernel)


def step(v=1.0, at=0.0):
    """A 1 ns rise to ``v`` at ``at`` seconds, held to the end."""
    return Pulse(0.0, v, at, 1e-9, 1e-9, 1.0, None)


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("method", ["trap", "gear"])
def test_rc_discharge_from_ic(method, kernel):
    c = Circuit(elements=[Resistor("R1", "a", "0", 1e3), Capacitor("C1", "a", "0", 1e-6, ic=2.0)])
    opts = SimulationOptions(reltol=1e-6, method=method, kernel=kernel)
    w = transient(c, 1e-5, 5e-3, uic=True, options=opts)
    exact = 2.0 * np.exp(-w.time / 1e-3)
    assert np.max(np.abs(w["a"][1:] - exact[1:])) < 2e-4


@pytest.mark.parametrize("kernel", KERNELS)
def test_rc_step_response(kernel):
    c = Circuit(
        elements=[
            VoltageSource("V1", "in", "0", waveform=step(1.0, 1e-4)),
            Resistor("R1", "in", "out", 1e3),
            Capacitor("C1", "out", "0", 1e-6),
        ]
    )
    w = transient(c, 1e-5, 5e-3, options=tight(kernel))
    tau = np.clip(w.time - 1e-4 - 1e-9, 0, None)
    exact = 1 - np.exp(-tau / 1e-3)
    assert np.max(np.abs(w["out"] - exact)) < 1e-4
    # SPICE sign: the source delivers current, so i(v1) = -(v(in) - v(out)) / R
    assert np.allclose(w["i(v1)"], -(w["in"] - w["out"]) / 1e3, atol=1e-9)


@pytest.mark.parametrize("kernel", KERNELS)
def test_rl_step_current(kernel):
    c = Circuit(
        elements=[
            VoltageSource("V1", "in", "0", waveform=step(2.0)),
            Resistor("R1", "in", "a", 10.0),
            Inductor("L1", "a", "0", 1e-3),
        ]
    )
    w = transient(c, 1e-6, 5e-4, options=tight(kernel))
    exact = 0.2 * (1 - np.exp(-np.clip(w.time - 1e-9, 0, None) * 10.0 / 1e-3))
    assert np.max(np.abs(-w["i(v1)"] - exact)) < 2e-5


@pytest.mark.parametrize("kernel", KERNELS)
def test_rlc_underdamped_step(kernel):
    r, l_, cap = 20.0, 10e-3, 1e-6
    c = Circuit(
        elements=[
            VoltageSource("V1", "in", "0", waveform=step(1.0)),
            Resistor("R1", "in", "a", r),
            Inductor("L1", "a", "b", l_),
            Capacitor("C1", "b", "0", cap),
        ]
    )
    w = transient(c, 5e-6, 3e-3, options=tight(kernel))
    alpha, w0 = r / (2 * l_), 1 / np.sqrt(l_ * cap)
    wd = np.sqrt(w0**2 - alpha**2)
    t = np.clip(w.time - 1e-9, 0, None)
    exact = 1 - np.exp(-alpha * t) * (np.cos(wd * t) + alpha / wd * np.sin(wd * t))
    assert np.max(np.abs(w["b"] - exact)) < 2e-3 * np.ptp(exact)


@pytest.mark.parametrize("kernel", KERNELS)
def test_rc_under_sine(kernel):
    r, cap, f, amp = 1e3, 1e-6, 500.0, 1.0
    c = Circuit(
        elements=[
            VoltageSource("V1", "in", "0", waveform=Sin(0.0, amp, f)),
            Resistor("R1", "in", "out", r),
            Capacitor("C1", "out", "0", cap),
        ]
    )
    w = transient(c, 1e-5, 6e-3, options=tight(kernel))
    wt, k = 2 * np.pi * f * w.time, 2 * np.pi * f * r * cap
    exact = amp / (1 + k**2) * (np.sin(wt) - k * np.cos(wt) + k * np.exp(-w.time / (r * cap)))
    assert np.max(np.abs(w["out"] - exact)) < 1e-3 * amp


@pytest.mark.parametrize("kernel", KERNELS)
def test_ideal_integrator_with_vcvs_opamp(kernel):
    r, cap = 10e3, 10e-9
    c = Circuit(
        elements=[
            VoltageSource("V1", "in", "0", dc=1.0),
            Resistor("R1", "in", "n", r),
            Capacitor("C1", "n", "out", cap),
            Vcvs("E1", "out", "0", "0", "n", 1e6),
        ]
    )
    c.initial_conditions = {"out": 0.5, "n": 0.0}
    w = transient(c, 5e-6, 5e-4, uic=True, options=tight(kernel))
    exact = 0.5 - w.time / (r * cap)
    late = w.time > 5e-5  # after the uic start settles through the 1e6 loop
    assert np.max(np.abs(w["out"][late] - exact[late])) < 1e-3 * np.ptp(exact)
