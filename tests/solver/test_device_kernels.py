"""Each device family's kernel twin (devices/*_kernel.py, compiled) against the family's numpy
equations (the reference engine's), value for value; the loops' agreement with the reference
engine on whole circuits is tests/solver/test_compiled_kernel.py."""

import numpy as np
import pytest

from circuitsim.netlist.circuit import Circuit, Diode, Model, Pulse, Pwl, Sin, VoltageSource
from circuitsim.solver.devices import diode_kernel, source_kernel, switch_kernel
from circuitsim.solver.devices.diode import DiodeFamily, pnjlim
from circuitsim.solver.devices.source_waveforms import SourceValues
from circuitsim.solver.devices.switch import transition_retry
from circuitsim.solver.layout import Layout
from circuitsim.solver.options import SimulationOptions

VOLTAGES = np.concatenate([np.linspace(-30.0, 1.2, 4001), [-0.0776, 0.0, 0.5, 0.75, 0.8]])


def _diodes() -> DiodeFamily:
    """Three models: no charge, depletion only (M near 1), depletion and transit time."""
    names = ("dplain", "ddep", "dfull")
    circuit = Circuit(elements=[Diode(f"D{k}", "a", "0", m) for k, m in enumerate(names)])
    circuit.models["dplain"] = Model("dplain", "D", {"is": 2e-9, "n": 1.8})
    circuit.models["ddep"] = Model("ddep", "D", {"is": 1e-14, "cjo": 4e-12, "m": 0.95, "vj": 0.7})
    circuit.models["dfull"] = Model(
        "dfull", "D", {"is": 3e-15, "n": 1.1, "cjo": 2e-12, "tt": 5e-9, "fc": 0.4}
    )
    return DiodeFamily(circuit.elements, circuit, Layout(["a"]), SimulationOptions(gmin=1e-12))


def test_junction_current_and_charge_equal_the_family_s():
    family = _diodes()
    data = family.kernel_data()
    jp, cp = data["params"], data["charge"]
    k_ = diode_kernel
    for v in VOLTAGES:
        at_v = np.full(jp.shape[0], v)  # the family evaluates every junction at once
        cd, gd = family._current(at_v)
        q, c = family._charge(at_v, cd, gd)
        for k in range(jp.shape[0]):
            current, conductance = k_.junction_current(
                v, jp[k, k_.ISAT], jp[k, k_.INV_VTE], jp[k, k_.IS_OVER_VTE],
                jp[k, k_.REVERSE_KNEE], jp[k, k_.CUBIC_SCALE], jp[k, k_.THREE_VTE],
                jp[k, k_.GMIN],
            )  # fmt: skip
            assert current == pytest.approx(cd[k], rel=1e-13, abs=1e-30)
            assert conductance == pytest.approx(gd[k], rel=1e-13, abs=1e-30)
            charge, capacitance = k_.junction_charge(v, current, conductance, *cp[k])
            assert charge == pytest.approx(q[k], rel=1e-12, abs=1e-30)
            assert capacitance == pytest.approx(c[k], rel=1e-12, abs=1e-30)


def test_pnjlim_equals_the_family_s():
    rng = np.random.default_rng(1)
    vnew, vold = rng.uniform(-20, 20, 5000), rng.uniform(-5, 5, 5000)
    vt, vcrit = 0.0259, 0.62
    for a, b in zip(vnew, vold, strict=True):
        expected, limited = pnjlim(np.array([a]), np.array([b]), np.array([vt]), np.array([vcrit]))
        value, was = diode_kernel.pnjlim(a, b, vt, vcrit)
        assert value == pytest.approx(expected[0], rel=1e-14, abs=1e-15)
        assert was == limited


def test_linearize_junction_is_the_family_s_port_load_with_integration():
    """One iteration of DiodeFamily.port_load, charge integrated as a0 q + history."""
    family = _diodes()
    data = family.kernel_data()
    jp, cp = data["params"], data["charge"]
    a0, history = 2.0e5, np.array([0.0, 3e-7, -2e-6])
    v_old = np.array([0.3, -1.0, 0.65])
    v = np.array([0.9, -4.0, 0.66])  # the first and second are limited, the third is not
    limited, _ = pnjlim(v, v_old, family.vte, family.vcrit)
    free = np.abs(v - v_old) <= family.free_step
    vd = np.where(free, v, limited)
    cd, gd = family._current(vd)
    q, c = family._charge(vd, cd, gd)
    for k in range(3):
        charged = bool(cp[k, diode_kernel.CJO] != 0 or cp[k, diode_kernel.TT] != 0)
        out = diode_kernel.linearize_junction(jp, cp, k, v[k], v_old[k], charged, a0, history[k])
        vk, was, current, conductance, charge, charge_current = out
        assert vk == pytest.approx(vd[k], rel=1e-15)
        assert was == (not free[k] and vd[k] != v[k])
        if charged:
            assert charge == pytest.approx(q[k], rel=1e-13)
            assert charge_current == pytest.approx(a0 * q[k] + history[k], rel=1e-12)
            assert current == pytest.approx(cd[k] + a0 * q[k] + history[k], rel=1e-12)
            assert conductance == pytest.approx(gd[k] + a0 * c[k], rel=1e-12)
        else:
            assert (charge, charge_current) == (0.0, 0.0)
            assert (current, conductance) == (cd[k], gd[k])


def test_source_value_equals_the_family_s_on_every_kind():
    elements = [
        VoltageSource("V1", "a", "0", dc=0.3),
        VoltageSource("V2", "a", "0", waveform=Sin(0.1, 2.0, 50.0, 1e-3, 20.0, 30.0)),
        VoltageSource("V3", "a", "0", waveform=Pulse(-1.0, 2.0, 1e-3, 1e-4, 2e-4, 3e-3, 8e-3)),
        VoltageSource("V4", "a", "0", waveform=Pwl(((0.0, 0.0), (2e-3, 1.0), (5e-3, -0.5)))),
    ]
    values = SourceValues(elements)
    values.set_timing(1e-5, 2e-2)
    kind, par, dc, tables = values.kernel_arrays()
    assert list(kind) == [source_kernel.DC, source_kernel.SIN, source_kernel.PULSE,
                          source_kernel.PWL]  # fmt: skip
    start = np.concatenate([[0], np.cumsum([t.shape[1] for t in tables])]).astype(np.int64)
    pwl_t = np.concatenate([t[0] for t in tables])
    pwl_v = np.concatenate([t[1] for t in tables])
    for t in np.linspace(0.0, 2e-2, 997):
        expected = values.values(t)
        for k in range(4):
            got = source_kernel.source_value(t, k, kind, par, dc, start, pwl_t, pwl_v)
            assert got == pytest.approx(expected[k], rel=1e-12, abs=1e-14), (k, t)


@pytest.mark.parametrize("keep", [False, True])
def test_next_state_is_the_hysteresis_rule(keep):
    on_above, off_below = 0.7, 0.3
    for control in (-1.0, 0.3, 0.5, 0.7, 0.7000001, 2.0):
        expected = (keep or control > on_above) and control >= off_below
        assert switch_kernel.next_state(control, keep, on_above, off_below) == expected


def test_transition_retry_is_the_family_s_rule():
    for fraction, h, h_last in [(1.0, 1e-3, 1e-3), (0.5, 1e-3, 1e-3), (0.001, 1e-3, 1e-3)]:
        expected = transition_retry(fraction, h, h_last, 1e-12)
        assert switch_kernel.transition_retry(fraction, h, h_last, 1e-12) == expected
