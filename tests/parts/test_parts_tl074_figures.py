"""The TL074-like macromodel meets its datasheet figures, measured on test benches.

Reference: the datasheet typicals in ``partbench.DESIGN`` (not parts.lib's numbers); each
figure is measured from a simulation of the shipped library file, on ngspice and on our
solver, and must be within 10 % of the design value; the two engines within 2 % of each other.
"""

import functools

import numpy as np
import partbench
import pytest

from circuitsim.interop.ngspice import run_ngspice

D = partbench.DESIGN
ENGINES = [
    pytest.param("ngspice", marks=partbench.requires_ngspice),
    pytest.param("builtin"),
]
RUN = {"ngspice": run_ngspice, "builtin": partbench.run_builtin}


@functools.cache
def measured(engine: str) -> dict[str, float]:
    return partbench.figures(RUN[engine])


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("figure", list(D))
def test_figure_within_10_percent_of_design(engine, figure):
    assert measured(engine)[figure] == pytest.approx(D[figure], rel=0.10)


@partbench.requires_ngspice
@pytest.mark.parametrize("figure", list(D))
def test_engines_agree_within_2_percent(figure):
    assert measured("builtin")[figure] == pytest.approx(measured("ngspice")[figure], rel=0.02)


@pytest.mark.parametrize("engine", ENGINES)
def test_slew_is_symmetric(engine):
    rising, falling = partbench.slew_rate(RUN[engine])
    assert rising == pytest.approx(falling, rel=0.02)


@pytest.mark.parametrize("engine", ENGINES)
def test_swing_follows_the_supplies(engine):
    # The clamps are referenced to the supply pins: 3 V less supply, 3 V less swing.
    body = "VCC vcc 0 12\nVEE vee 0 -12\nVP p 0 1\nXU p 0 vcc vee out TL074\nRL out 0 10k\n"
    low_supply = float(RUN[engine](partbench.deck(body, ".op"))["v(out)"][0])
    assert measured(engine)["swing_pos_v"] - low_supply == pytest.approx(
        3.0 * 10e3 / (10e3 + D["output_ohm"]), rel=0.02
    )


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("vos", [3e-3, -3e-3])
def test_offset_parameter_appears_at_a_follower_output(engine, vos):
    # A follower with grounded input shows the offset at its output (times A0/(1+A0)).
    assert partbench.offset_output(RUN[engine], vos) == pytest.approx(vos, abs=1e-6)


@partbench.requires_ngspice
def test_small_signal_ac_agrees_with_the_step_measurements(tmp_path):
    # An independent method: the open-loop frequency response (ngspice .ac) must show the same
    # DC gain and unity-gain frequency as the .op and step-response benches.
    f, magnitude = partbench.ngspice_open_loop_magnitude(tmp_path)
    assert magnitude[0] == pytest.approx(measured("ngspice")["dc_gain"], rel=0.01)
    i = int(np.argmax(magnitude < 1.0))
    # log-log interpolation of the 0 dB crossing
    lf = np.interp(0.0, np.log(magnitude[[i, i - 1]]), np.log(f[[i, i - 1]]))
    assert np.exp(lf) == pytest.approx(measured("ngspice")["unity_gain_hz"], rel=0.02)
    # one pole: -20 dB/decade between the pole (15 Hz) and the crossing
    decade = (f > 1e3) & (f < 1e5)
    slope = np.polyfit(np.log10(f[decade]), np.log10(magnitude[decade]), 1)[0]
    assert slope == pytest.approx(-1.0, abs=0.01)


@partbench.requires_ngspice
def test_our_small_signal_ac_of_the_macromodel_is_ngspice_s(tmp_path):
    f, magnitude = partbench.builtin_open_loop_magnitude()
    f_ng, magnitude_ng = partbench.ngspice_open_loop_magnitude(tmp_path)
    assert np.allclose(f, f_ng, rtol=1e-6)  # wrdata prints 15 digits
    assert np.max(np.abs(20 * np.log10(magnitude / magnitude_ng))) < 1e-3
    assert magnitude[0] == pytest.approx(measured("builtin")["dc_gain"], rel=0.01)
