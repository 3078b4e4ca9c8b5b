"""The translator's circuit against hand-derived values (the reference numbers of
docs/model.md, 1/(R C) = g).

In unity scaling (1 V = 1 SI unit) the paper's equation (7) fixes every product R C:
R1 C1 = 1 s (y' into y), R31 C3 = m / k_y, R32 C3 = m / |k_ypsi|, R33 C3 = m V / 7.24e6,
R41 C4 = I / k_psiy, R42 C4 = I / k_psi, R44 C4 = I V / 4.36e6, R17 = R31 (the generator
enters like y), (R3 + Ron) C3 = m / k (the flange signal is y - (|y+eta| - |y-eta|)/2 volts).
"""

import math

import numpy as np
import pytest

from circuitsim.mechanics import load_model
from circuitsim.netlist.circuit import Capacitor, Resistor, Sin, SubcircuitCall, Switch
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.eseries import E96
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.translator import synthesize

M, I, V, K_FLANGE = 1500.0, 1200.0, 55.0, 1.7e7


@pytest.fixture(scope="module")
def wheelset():
    return load_model().system(parameters={"V": V, "f": 3.0, "a": 0.04})


@pytest.fixture(scope="module")
def unity(wheelset):
    return synthesize(wheelset, SynthesisOptions(scaling="unity", series="exact"))


def value(circuit, name):
    e = circuit.element(name)
    return float(e.resistance if isinstance(e, Resistor) else e.capacitance)


def ohms(circuit, name):
    """A resistor's value, or the sum of its series pair (name + A, name + B)."""
    names = {e.name for e in circuit.elements}
    if name in names:
        return value(circuit, name)
    return value(circuit, name + "A") + value(circuit, name + "B")


@pytest.mark.parametrize(
    ("resistor", "capacitor", "product"),
    [
        ("R1", "C1", 1.0),
        ("R2", "C2", 1.0),
        ("R31", "C3", M / 4.81e6),
        ("R32", "C3", M / 7.24e6),
        ("R33", "C3", M * V / 7.24e6),
        ("R17", "C3", M / 4.81e6),
        ("R41", "C4", I / 4.02e6),
        ("R42", "C4", I / 3.07e6),
        ("R44", "C4", I * V / 4.36e6),
    ],
)
def test_unity_rc_products_are_the_papers_coefficients(unity, resistor, capacitor, product):
    c = unity.circuit
    assert value(c, resistor) * value(c, capacitor) == pytest.approx(product, rel=1e-9)


def test_flange_path_and_switch(unity):
    c = unity.circuit
    switch = c.element("S1")
    assert isinstance(switch, Switch)
    ron = float(c.models[switch.model.lower()].params["ron"])
    assert (value(c, "R3") + ron) * value(c, "C3") == pytest.approx(M / K_FLANGE, rel=1e-9)
    # R3 connects the switch to the y' integrator's summing junction
    assert set(c.element("R3").nodes) == {switch.negative, "y_dot_sum"}


def test_generator_is_the_papers_xfg1(unity, wheelset):
    source = unity.circuit.element("VXFG1")
    assert isinstance(source.waveform, Sin)
    assert float(source.waveform.amplitude) == pytest.approx(0.040)  # 40 mV: a = 0.040 m
    assert float(source.waveform.frequency) == 3.0
    assert value(unity.circuit, "R17") == value(unity.circuit, "R31")
    # auto scaling: the generator is scaled like y, so R17 = R31 still (E96-rounded alike,
    # as series pairs where one value is more than 0.1 % off)
    auto = synthesize(wheelset, SynthesisOptions())
    assert ohms(auto.circuit, "R17") == ohms(auto.circuit, "R31")
    amplitude = float(auto.circuit.element("VXFG1").waveform.amplitude)
    assert amplitude == pytest.approx(auto.scale_map.states["y"].volts_per_unit * 0.040)


def test_op_amp_sections_follow_the_paper(unity):
    # reference: U1A/U1B realize y1, U2A/U2B y2, U1C/U1D y3, U2C/U2D y4 (integrator, inverter)
    c = unity.circuit
    expected = {
        "XU1A": "y_neg", "XU1B": "y", "XU2A": "psi_neg", "XU2B": "psi",
        "XU1C": "y_dot_neg", "XU1D": "y_dot", "XU2C": "psi_dot_neg", "XU2D": "psi_dot",
    }  # fmt: skip
    for name, output in expected.items():
        call = c.element(name)
        assert isinstance(call, SubcircuitCall)
        assert call.connections[-1] == output
    for n, state in enumerate(("y", "psi", "y_dot", "psi_dot"), start=1):
        cap = c.element(f"C{n}")
        assert isinstance(cap, Capacitor) and set(cap.nodes) == {f"{state}_neg", f"{state}_sum"}


def test_signs_are_picked_by_wiring(unity):
    # A[y_dot, y] < 0 -> from -y; A[y_dot, psi] > 0 -> from +psi; damping from -y_dot
    c = unity.circuit
    assert c.element("R31").positive == "y_neg"
    assert c.element("R32").positive == "psi"
    assert c.element("R33").positive == "y_dot_neg"
    assert c.element("R1").positive == "y_dot"


def test_unity_scale_map_and_transient(unity):
    assert {s.volts_per_unit for s in unity.scale_map.states.values()} == {1.0}
    assert unity.scale_map.states["y"].node == "y"
    tran = unity.circuit.transient
    assert tran.uic and tran.tstop == pytest.approx(5.0)
    assert tran.tmax <= 1.0 / (200 * 8.0)  # >= 200 points per period of the ~8.5 Hz mode


def test_auto_scaling_reaches_the_swing(wheelset):
    s = synthesize(wheelset, SynthesisOptions(swing=5.0))
    # reference, f = 3 Hz with flange: max|y| = 14.265 mm, max|y'| = 0.4772 m/s
    for state, peak in (("y", 14.265e-3), ("y_dot", 0.4772)):
        volts = s.scale_map.states[state].volts_per_unit * peak
        assert 5.0 * 0.9 <= volts <= 5.0 * 1.001


def test_e96_values_are_standard(wheelset):
    s = synthesize(wheelset, SynthesisOptions(series="E96"))
    members = set(E96)
    for entry in s.bom:
        if entry.series == "E96":
            mantissa = entry.value / 10 ** math.floor(math.log10(entry.value))
            assert round(mantissa, 2) in members
            if math.isnan(entry.error):  # the second part of a series pair sets none alone
                assert entry.part.endswith("B") and "series pair with" in entry.role
            else:  # one value within 0.1 %, else a pair within it
                assert abs(entry.error) <= 1e-3


def test_initial_conditions_on_integrator_outputs(wheelset):
    from dataclasses import replace

    started = replace(wheelset, x0=np.array([0.005, 0.0, 0.0, 0.0]))
    s = synthesize(started, SynthesisOptions(scaling="unity"))
    assert s.circuit.initial_conditions["y_neg"] == pytest.approx(-0.005)
    assert s.circuit.element("C1").ic == pytest.approx(-0.005)


def test_time_scale(wheelset):
    s = synthesize(wheelset, SynthesisOptions(time_scale=1000.0))
    assert s.circuit.transient.tstop == pytest.approx(5e-3)
    assert float(s.circuit.element("VXFG1").waveform.frequency) == pytest.approx(3000.0)
    assert s.scale_map.time_scale == 1000.0


def test_tl074_has_supplies_and_warns_on_clipping(wheelset):
    s = synthesize(wheelset, SynthesisOptions(opamp="tl074", swing=20.0))
    assert float(s.circuit.element("VCC").dc) == 15.0
    assert any("clip" in w for w in s.warnings)
    ideal = synthesize(wheelset, SynthesisOptions(swing=20.0))
    assert not any("clip" in w for w in ideal.warnings)
    with pytest.raises(KeyError):
        ideal.circuit.element("VCC")


def test_dead_zone_option_uses_one_block(wheelset):
    s = synthesize(wheelset, SynthesisOptions(nonlinear="deadzone"))
    names = {e.name for e in s.circuit.elements}
    assert "XFLANGE_DZC" in names and not any("ABS" in n for n in names)


def test_linear_model_has_no_switch():
    system = load_model().system(parameters={"V": V}, nonlinear={"flange": False})
    s = synthesize(system)
    assert not any(isinstance(e, Switch) for e in s.circuit.elements)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (SynthesisOptions(opamp="lm741"), "opamp"),
        (SynthesisOptions(series="E12"), "series"),
        (SynthesisOptions(swing=-1.0), "swing"),
        (SynthesisOptions(ranges={"nope": 1.0}), "nope"),
    ],
)
def test_bad_options_are_named(wheelset, options, message):
    with pytest.raises(SynthesisError, match=message):
        synthesize(wheelset, options)


@pytest.mark.parametrize("opamp", ["ideal", "tl074"])
@pytest.mark.parametrize("nonlinear", ["abs", "deadzone"])
def test_element_names_are_unique(wheelset, opamp, nonlinear):
    s = synthesize(wheelset, SynthesisOptions(opamp=opamp, nonlinear=nonlinear))
    names = [e.name.lower() for e in s.circuit.elements]
    assert len(names) == len(set(names))
    assert len(s.bom) == len({entry.part.lower() for entry in s.bom})


def test_flange_signal_peak_is_predicted(wheelset):
    # v_sig = -G_y * deadzone(y, eta): peak G_y (max|y| - eta), reference max|y| = 14.265 mm
    s = synthesize(wheelset, SynthesisOptions())
    G = s.scale_map.states["y"].volts_per_unit
    assert s.node_peaks["flange_sig"] == pytest.approx(G * (14.265e-3 - 0.009), rel=2e-3)


def test_without_peaks_the_circuit_is_the_same_and_no_direct_solution_is_run(wheelset, monkeypatch):
    from circuitsim.netlist.writer import write_netlist
    from circuitsim.synthesis import translator

    ranges = {"y": 0.02, "psi": 0.01, "y_dot": 0.3, "psi_dot": 0.2}
    options = SynthesisOptions(ranges=ranges, series="exact")
    with_peaks = synthesize(wheelset, options)
    assert with_peaks.node_peaks

    def refuse(*args, **kwargs):
        raise AssertionError("direct solution run")

    monkeypatch.setattr(translator, "direct_solution", refuse)
    without = synthesize(wheelset, options, peaks=False)
    assert write_netlist(without.circuit) == write_netlist(with_peaks.circuit)
    assert without.node_peaks == {}
    # the scaling still needs it when a range is missing
    with pytest.raises(AssertionError, match="direct solution run"):
        synthesize(wheelset, SynthesisOptions(ranges={"y": 0.02}), peaks=False)
