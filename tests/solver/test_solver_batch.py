"""Batched variants (circuitsim.solver.batch) against single runs and closed-form answers."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from circuitsim.netlist.circuit import (
    Capacitor,
    Circuit,
    Diode,
    Inductor,
    Model,
    Resistor,
    Sin,
    Transient,
    VoltageSource,
)
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.batch import batch_transient, union_circuit
from circuitsim.solver.devices.diode import THERMAL_VOLTAGE
from circuitsim.solver.errors import CircuitInputError

# binary fractions: a fixed step of H lands exactly on tstop (no roundoff-sized last step)
H = 2.0**-19  # s, about 1.9 us


def rc_discharge(r: float, c: float = 1e-6, v0: float = 2.0, tstop: float = 2560 * H) -> Circuit:
    return Circuit(
        elements=[Resistor("R1", "a", "0", r), Capacitor("C1", "a", "0", c, ic=v0)],
        analyses=[Transient(tstep=1e-5, tstop=tstop, uic=True)],
    )


def rlc_ringing(r: float) -> Circuit:
    """Series R L C discharging C (IC 1 V) through R and L."""
    return Circuit(
        elements=[
            Capacitor("C1", "a", "0", 1e-6, ic=1.0),
            Resistor("R1", "a", "b", r),
            Inductor("L1", "b", "0", 10e-3, ic=0.0),
        ],
        analyses=[Transient(tstep=5e-6, tstop=1536 * H, uic=True)],
    )


def diode_resistor(r: float) -> Circuit:
    """A slow sine through a diode into a resistor (no storage: each point is a DC solution)."""
    return Circuit(
        elements=[
            VoltageSource("V1", "in", "0", waveform=Sin(0.0, 2.0, 100.0)),
            Diode("D1", "in", "out", "dmod"),
            Resistor("R1", "out", "0", r),
        ],
        models={"dmod": Model("dmod", "D", {"is": 1e-14, "n": 1.0})},
        analyses=[Transient(tstep=1e-4, tstop=10e-3)],
        options={"reltol": 1e-6},
    )


def single_and_batch(circuits, options):
    singles = [simulate(c, options) for c in circuits]
    batch = batch_transient(circuits, options)
    return singles, batch


@pytest.mark.parametrize(
    "make, values",
    [(rc_discharge, (500.0, 1e3, 2e3)), (rlc_ringing, (20.0, 50.0, 120.0))],
    ids=["rc", "rlc"],
)
def test_linear_variants_equal_single_runs_on_a_fixed_grid(make, values):
    circuits = [make(v) for v in values]
    options = SimulationOptions(reltol=1e-6, fixed_step=H)
    singles, batch = single_and_batch(circuits, options)
    for k, single in enumerate(singles):
        np.testing.assert_allclose(batch.time, single.time, rtol=0, atol=1e-15)
        for name in single.names:
            scale = np.max(np.abs(single[name]))
            assert np.max(np.abs(batch.signals[name][k] - single[name])) <= 1e-6 * scale


def test_rc_variants_match_the_exponential():
    values = (500.0, 1e3, 2e3)
    batch = batch_transient([rc_discharge(r) for r in values], SimulationOptions(reltol=1e-6))
    for k, r in enumerate(values):
        exact = 2.0 * np.exp(-batch.time / (r * 1e-6))
        assert np.max(np.abs(batch.signals["v(a)"][k][1:] - exact[1:])) < 2e-4


def test_rlc_variants_match_the_damped_oscillation():
    values = (20.0, 50.0, 120.0)
    batch = batch_transient([rlc_ringing(r) for r in values], SimulationOptions(reltol=1e-6))
    t = batch.time
    for k, r in enumerate(values):
        inductance, capacitance = 10e-3, 1e-6
        alpha = r / (2 * inductance)
        omega = math.sqrt(1 / (inductance * capacitance) - alpha**2)
        # capacitor voltage of a series RLC released from v(0) = 1 V, i(0) = 0
        exact = np.exp(-alpha * t) * (np.cos(omega * t) + alpha / omega * np.sin(omega * t))
        # t = 0 is skipped: under uic the engine reports x before the IC= charges act
        assert np.max(np.abs(batch.signals["v(a)"][k][1:] - exact[1:])) < 2e-3


def test_adaptive_batch_agrees_with_single_runs_within_golden_tolerance():
    circuits = [rlc_ringing(r) for r in (20.0, 50.0, 120.0)]
    singles, batch = single_and_batch(circuits, SimulationOptions(reltol=1e-6))
    for k, single in enumerate(singles):
        ours = np.interp(single.time, batch.time, batch.signals["v(a)"][k])
        assert np.max(np.abs(ours - single["v(a)"])) <= 1e-3 * np.ptp(single["v(a)"])


def test_diode_variants_equal_single_runs_and_the_shockley_solution():
    values = (200.0, 1e3, 5e3)
    circuits = [diode_resistor(r) for r in values]
    options = SimulationOptions(reltol=1e-6, fixed_step=1e-4)
    singles, batch = single_and_batch(circuits, options)
    vt = THERMAL_VOLTAGE
    for k, (single, r) in enumerate(zip(singles, values, strict=True)):
        out = batch.signals["v(out)"][k]
        np.testing.assert_allclose(batch.time, single.time, rtol=0, atol=1e-15)
        assert np.max(np.abs(out - single["v(out)"])) <= 1e-6 * np.max(np.abs(single["v(out)"]))
        # independent answer: v_in = v_d + R i with i = IS (exp(v_d / Vt) - 1) + gmin v_d
        for t, v in zip(batch.time[::7], out[::7], strict=True):
            vin = 2.0 * math.sin(2 * math.pi * 100.0 * t)

            def kcl(vd, vin=vin, r=r):
                return vd + r * (1e-14 * math.expm1(vd / vt) + 1e-12 * vd) - vin

            vd = brentq(kcl, -3.0, 3.0, xtol=1e-15)
            assert abs(v - (vin - vd)) <= 1e-5 + 1e-4 * abs(v)


def test_different_topologies_are_refused():
    other = rc_discharge(1e3)
    other.elements[0] = Resistor("R1", "a", "b", 1e3)
    with pytest.raises(CircuitInputError, match="variant 1"):
        union_circuit([rc_discharge(1e3), other])
