"""Operating points against hand-solved answers, and the stress cases of the solver issue."""

import numpy as np
import pytest
from scipy.optimize import brentq

from circuitsim.netlist.circuit import (
    Capacitor,
    Cccs,
    Ccvs,
    Circuit,
    CurrentSource,
    Diode,
    Model,
    Resistor,
    Sin,
    Switch,
    Vccs,
    Vcvs,
    VoltageSource,
)
from circuitsim.solver import SimulationOptions, operating_point, simulate, transient
from circuitsim.solver.devices.diode import THERMAL_VOLTAGE
from circuitsim.solver.errors import ConvergenceError, SingularMatrixError


def test_divider_and_current_source():
    c = Circuit(
        elements=[
            VoltageSource("V1", "a", "0", dc=10.0),
            Resistor("R1", "a", "b", 3e3),
            Resistor("R2", "b", "0", 1e3),
            CurrentSource("I1", "0", "b", 1e-3),
        ]
    )
    w = operating_point(c)
    # node b: (10 - vb)/3k + 1m = vb/1k  ->  vb = (10/3k + 1m) / (1/3k + 1/1k)
    vb = (10 / 3e3 + 1e-3) / (1 / 3e3 + 1 / 1e3)
    assert w["b"][0] == pytest.approx(vb, rel=1e-12)
    assert w["i(v1)"][0] == pytest.approx(-(10 - vb) / 3e3, rel=1e-12)


def test_controlled_sources_dc():
    c = Circuit(
        elements=[
            VoltageSource("V1", "in", "0", dc=2.0),
            Resistor("R1", "in", "a", 1e3),
            VoltageSource("VS", "a", "0", dc=0.0),  # i(vs) = 2 mA
            Cccs("F1", "0", "f", "VS", 3.0),
            Resistor("RF", "f", "0", 100.0),  # v(f) = 0.6
            Ccvs("H1", "h", "0", "VS", 500.0),  # v(h) = 1.0
            Vccs("G1", "0", "g", "h", "0", 2e-3),
            Resistor("RG", "g", "0", 1e3),  # v(g) = 2.0
            Vcvs("E1", "e", "0", "g", "0", -1.5),  # v(e) = -3.0
        ]
    )
    w = operating_point(c)
    assert w["i(vs)"][0] == pytest.approx(2e-3, rel=1e-12)
    assert [w[n][0] for n in ("f", "h", "g", "e")] == pytest.approx([0.6, 1.0, 2.0, -3.0])


def diode_circuit(volts: float, ohms: float) -> Circuit:
    c = Circuit(
        elements=[
            VoltageSource("V1", "a", "0", dc=volts),
            Resistor("R1", "a", "k", ohms),
            Diode("D1", "k", "0", "dm"),
        ]
    )
    c.models["dm"] = Model("dm", "D", {"is": 1e-14, "n": 1.5})
    return c


def diode_reference(volts: float, ohms: float) -> float:
    vte = 1.5 * THERMAL_VOLTAGE
    return brentq(lambda v: (volts - v) / ohms - 1e-14 * np.expm1(v / vte) - 1e-12 * v, -100, 5)


@pytest.mark.parametrize(("volts", "ohms"), [(5.0, 1e3), (1000.0, 1.0), (-50.0, 1e3)])
def test_diode_from_far_start_converges(volts, ohms):
    w = operating_point(diode_circuit(volts, ohms))
    assert w["k"][0] == pytest.approx(diode_reference(volts, ohms), abs=1e-6)


def test_diode_newton_failure_is_a_clear_error():
    # itl_floor=0: the limit applies as given (ngspice would raise itl1=3 to 100)
    opts = SimulationOptions(itl1=3, itl_floor=0, gminsteps=0, srcsteps=0)
    with pytest.raises(ConvergenceError) as info:
        operating_point(diode_circuit(1000.0, 1.0), opts)
    assert info.value.node in ("k", "a", "i(v1)")
    assert "worst node" in str(info.value)


@pytest.mark.parametrize("kernel", ["python", "compiled"])
def test_transient_newton_failure_names_time_step_node(kernel):
    c = diode_circuit(5.0, 1e3)
    c.elements[0] = VoltageSource("V1", "a", "0", waveform=Sin(0.0, 5.0, 1e3))
    with pytest.raises(ConvergenceError) as info:
        transient(c, 1e-5, 1e-3, options=SimulationOptions(itl4=1, itl_floor=0, kernel=kernel))
    err = info.value
    assert err.time is not None and err.step is not None and err.node is not None
    assert "time step too small" in str(err)


def test_floating_node_is_named():
    c = Circuit(
        elements=[
            VoltageSource("V1", "a", "0", dc=1.0),
            Resistor("R1", "a", "0", 1e3),
            Capacitor("C1", "a", "float", 1e-9),
            Capacitor("C2", "float", "x", 1e-9),
            Resistor("R2", "x", "0", 1e3),
        ]
    )
    with pytest.raises(SingularMatrixError, match="float"):
        operating_point(c)


def test_voltage_source_loop_is_singular():
    c = Circuit(
        elements=[
            VoltageSource("V1", "a", "0", dc=1.0),
            VoltageSource("V2", "a", "0", dc=2.0),
            Resistor("R1", "a", "0", 1e3),
        ]
    )
    with pytest.raises(SingularMatrixError, match="i\\(v"):
        operating_point(c)


@pytest.mark.parametrize("kernel", ["python", "compiled"])
def test_switch_chattering_at_threshold_terminates(kernel):
    # The switch is controlled by 5 V - its own output, with no hysteresis: on charges the
    # output above 2.5 V, which turns it off, which lets the output fall below 2.5 V, ...
    # The run must end, by finishing or by a ConvergenceError, within the step bound.
    c = Circuit(
        elements=[
            VoltageSource("V1", "s", "0", dc=5.0),
            Vcvs("E1", "ctrl", "0", "s", "out", 1.0),
            Switch("S1", "s", "out", "ctrl", "0", model="sw"),
            Resistor("R1", "out", "0", 1e3),
            Capacitor("C1", "out", "0", 1e-9),
        ]
    )
    c.models["sw"] = Model("sw", "SW", {"vt": 2.5, "vh": 0.0, "ron": 10.0, "roff": 1e9})
    opts = SimulationOptions(max_steps=20000, kernel=kernel)
    try:
        w = transient(c, 1e-6, 1e-4, uic=True, options=opts)
    except ConvergenceError as err:
        assert err.time is not None and err.step is not None and err.node is not None
    else:
        late = w.time > 2e-5
        assert np.all(np.abs(w["out"][late] - 2.5) < 0.5)  # held at the threshold


@pytest.mark.parametrize("kernel", ["python", "compiled"])
def test_stiff_opamp_pole_with_slow_signal(kernel):
    # Inverting amplifier, gain -2, built from a 1e6-gain VCVS followed by a 10 MHz RC pole,
    # driven by a 2 Hz sine over one second: time constants 1e7 apart.
    c = Circuit(
        elements=[
            VoltageSource("V1", "in", "0", waveform=Sin(0.0, 1.0, 2.0)),
            Resistor("R1", "in", "n", 10e3),
            Resistor("R2", "n", "out", 20e3),
            Vcvs("E1", "p", "0", "0", "n", 1e6),
            Resistor("RP", "p", "out", 1e3),
            Capacitor("CP", "out", "0", 1.59e-11),
        ]
    )
    w = transient(c, 1e-3, 1.0, options=SimulationOptions(max_steps=200000, kernel=kernel))
    assert np.max(np.abs(w["out"] + 2 * w["in"])) < 1e-3
    assert w.stats["accepted"] < 20000


def test_simulate_runs_op_without_tran():
    c = Circuit(elements=[VoltageSource("V1", "a", "0", dc=1.0), Resistor("R1", "a", "0", 2.0)])
    w = simulate(c)
    assert w.time.shape == (1,) and w["i(v1)"][0] == pytest.approx(-0.5)


def test_gmin_and_source_stepping_reach_the_same_solution():
    # Plain Newton solves this one; the fallbacks, run on their own, must land on the same
    # answer (they are what is left when Newton fails).
    from circuitsim.solver.dc import _Solver
    from circuitsim.solver.engine import build_system

    system = build_system(diode_circuit(1000.0, 1.0), None)
    reference = diode_reference(1000.0, 1.0)
    k = system.layout.node("k")
    for method in ("gmin_stepping", "source_stepping"):
        solver = _Solver(system, dc_op=True, clamp_ic=False, stats={})
        ok, x = getattr(solver, method)(np.zeros(system.size))
        assert ok, method
        assert x[k] == pytest.approx(reference, abs=1e-6), method
