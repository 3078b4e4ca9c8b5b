"""The TL074-like macromodel meets its datasheet figures, measured on test benches.

Reference: the datasheet typicals in ``partbench.DESIGN`` (not parts.lib's numbers); each
figure is measured from a simulation of the shipped library file and must be within 10 %.
"""

import partbench
import pytest

from circuitsim.interop.ngspice import run_ngspice

pytestmark = partbench.requires_ngspice

D = partbench.DESIGN


def test_dc_gain():
    assert partbench.dc_gain(run_ngspice) == pytest.approx(D["dc_gain"], rel=0.10)


def test_unity_gain_frequency():
    f_u = partbench.unity_gain_frequency(run_ngspice)
    assert f_u == pytest.approx(D["unity_gain_hz"], rel=0.10)


def test_slew_rate_both_directions():
    rising, falling = partbench.slew_rate(run_ngspice)
    assert rising == pytest.approx(D["slew_v_per_us"], rel=0.10)
    assert falling == pytest.approx(D["slew_v_per_us"], rel=0.10)


def test_output_swing_into_10k():
    high, low = partbench.swing(run_ngspice)
    assert high == pytest.approx(D["swing_pos_v"], rel=0.10)
    assert low == pytest.approx(D["swing_neg_v"], rel=0.10)


def test_swing_follows_the_supplies():
    # The clamps are referenced to the supply pins: 3 V less supply, 3 V less swing.
    body = "VCC vcc 0 12\nVEE vee 0 -12\nVP p 0 1\nXU p 0 vcc vee out TL074\nRL out 0 10k\n"
    low_supply = float(run_ngspice(partbench.deck(body, ".op"))["v(out)"][0])
    high, _ = partbench.swing(run_ngspice)
    assert high - low_supply == pytest.approx(3.0 * 10e3 / (10e3 + D["output_ohm"]), rel=0.02)


def test_output_resistance():
    r_out = partbench.output_resistance(run_ngspice)
    assert r_out == pytest.approx(D["output_ohm"], rel=0.10)


def test_input_resistance():
    assert partbench.input_resistance(run_ngspice) == pytest.approx(D["input_ohm"], rel=0.10)


@pytest.mark.parametrize("vos", [0.0, 3e-3, -3e-3])
def test_offset_parameter_appears_at_a_follower_output(vos):
    # A follower with grounded input shows the offset at its output (times A0/(1+A0)).
    assert partbench.offset_output(run_ngspice, vos) == pytest.approx(vos, abs=1e-6)
