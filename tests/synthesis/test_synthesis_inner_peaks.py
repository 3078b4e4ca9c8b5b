"""The peaks of the nodes inside piecewise-linear blocks (|x| block outputs, argument summers)
are predicted like the states' and checked against the op-amps' swing: an |x| block's offset
can take it past the swing while every state is within."""

from dataclasses import replace

import numpy as np
import pytest

from circuitsim.mechanics import load_model
from circuitsim.solver import simulate
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.translator import synthesize

# a first-order oscillator whose u saturates at +-1 (offsets of 1 unit against a peak of 0.2)
SATURATION = """
[model]
name = "saturated"
kind = "first_order"

[states]
names = ["u", "w"]
units = ["V", "A"]

[parameters]
b = 2.0
g = 0.5

[matrices]
A = [[-0.1, "b"], ["-b", 0]]

[nonlinear.sat]
enters = { u = 1 }
abs = [
  { gain = "-g", row = { u = 1 }, offset = 1 },
  { gain = "g", row = { u = 1 }, offset = -1 },
]

[forcing.drive]
amplitude = 0.3
frequency = 1.5
enters = { w = 1 }

[initial]
u = 0.2
"""


def _simulated_peak(synthesis, node, after=0.0):
    w = simulate(synthesis.circuit)
    late = w.time >= after
    return float(np.max(np.abs(w[f"v({node})"][late])))


@pytest.fixture(scope="module")
def saturated(tmp_path_factory):
    path = tmp_path_factory.mktemp("model") / "saturated.toml"
    path.write_text(SATURATION)
    return load_model(path).system()


def test_auto_scaling_keeps_offset_blocks_within_the_swing(saturated):
    """5 V for u's peak of 0.2 would be 24 V per unit, and the offset of 1 alone 24 V at the
    blocks: auto scaling lowers u's scale until they fit in 0.9 of the TL074's 13 V, and
    says so; the circuit then follows the model (it clipped at 98 % NRMSD before)."""
    from circuitsim.compare.case import run_case

    tl074 = synthesize(saturated, SynthesisOptions(opamp="tl074", t_stop=5.0))
    G = tl074.scale_map.states["u"].volts_per_unit
    assert G < 13.0 * 0.9 / 1.2  # the block's peak |u + 1| is about 1.2
    assert any("state u scaled to" in w and "|x| blocks of sat" in w for w in tl074.warnings)
    assert not any("clip" in w for w in tl074.warnings)
    for m in (1, 2):
        assert tl074.node_peaks[f"sat_abs{m}"] <= 0.9 * 13.0
    # ideal op-amps have no swing, but a built circuit's +-15 V rails do (synthesis/bounds.py):
    # the same limit, 0.9 of 13 V
    ideal = synthesize(saturated, SynthesisOptions(t_stop=5.0))
    assert ideal.scale_map.states["u"].volts_per_unit == G
    assert any("state u scaled to" in w and "13 V" in w for w in ideal.warnings)
    case = run_case(saturated, SynthesisOptions(opamp="tl074", t_stop=5.0, series="exact"))
    assert case.comparison.states["w"].nrmsd_percent < 0.1


def test_a_block_past_the_swing_is_warned_of(saturated):
    """Unity scaling keeps 1 V per unit: an offset of 20 units is 20 V at the blocks."""
    terms = tuple(
        replace(t, abs_terms=tuple(replace(a, offset=20.0 * a.offset) for a in t.abs_terms))
        for t in saturated.nonlinear
    )
    far = replace(saturated, nonlinear=terms)
    tl074 = synthesize(far, SynthesisOptions(opamp="tl074", t_stop=5.0, scaling="unity"))
    for m in (1, 2):
        assert tl074.node_peaks[f"sat_abs{m}"] > 13.0
        assert any(f"|x| block {m} (sat_abs{m})" in w and "clip" in w for w in tl074.warnings)


def test_predicted_block_peaks_match_the_simulated_circuit(saturated):
    ideal = synthesize(saturated, SynthesisOptions(t_stop=5.0, series="exact"))
    for m in (1, 2):
        predicted = ideal.node_peaks[f"sat_abs{m}"]
        assert _simulated_peak(ideal, f"sat_abs{m}") == pytest.approx(predicted, rel=1e-2)


def test_wheelset_blocks_are_predicted_and_within_the_tl074_swing():
    wheelset = load_model().system(parameters={"V": 55.0, "f": 3.0, "a": 0.04})
    tl074 = synthesize(wheelset, SynthesisOptions(opamp="tl074"))
    assert not any("clip" in w for w in tl074.warnings)
    ideal = synthesize(wheelset, SynthesisOptions(series="exact"))
    for node in ("flange_abs1", "flange_abs2"):
        assert tl074.node_peaks[node] < 13.0
        predicted = ideal.node_peaks[node]
        assert _simulated_peak(ideal, node) == pytest.approx(predicted, rel=1e-2)
