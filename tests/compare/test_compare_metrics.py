"""The comparator's metrics against signals whose answers are known by construction."""

import math

import numpy as np
import pytest

from circuitsim.compare import (
    ComparisonError,
    Thresholds,
    compare_traces,
    map_waveforms,
)
from circuitsim.compare.signals import (
    dominant_frequency,
    nrmsd_percent,
    peak_ratio,
    phase_lag,
)
from circuitsim.solver.waveforms import Waveforms
from circuitsim.synthesis.scalemap import ScaleMap, StateScale

T = np.linspace(0.0, 5.0, 4096)
DT = T[1] - T[0]


def sine(t, f=3.0, amplitude=1.0):
    return amplitude * np.sin(2 * np.pi * f * t)


@pytest.mark.parametrize("lag", [0.0123, -0.0377, 0.37 * DT, 0.0])
def test_phase_lag_recovers_a_known_delay_to_far_below_one_sample(lag):
    reference = sine(T) * np.exp(-0.2 * T)
    # Gain and offset must not move the estimate: only the delay.
    late = 1.3 * sine(T - lag) * np.exp(-0.2 * (T - lag)) + 0.1
    assert phase_lag(T, reference, late) == pytest.approx(lag, abs=1e-3 * DT)


def test_phase_lag_sign_positive_when_candidate_is_late():
    reference = sine(T, f=5.0)
    assert phase_lag(T, reference, sine(T - 0.01, f=5.0)) > 0
    assert phase_lag(T, reference, sine(T + 0.01, f=5.0)) < 0


def test_peak_ratio_of_a_scaled_trace_is_the_scale():
    reference = sine(T) * np.exp(-0.3 * T)
    assert peak_ratio(reference, 0.987 * reference) == pytest.approx(0.987, rel=1e-12)


@pytest.mark.parametrize("f", [3.0, 5.0, 8.477, 10.0])
def test_dominant_frequency_and_ratio_on_a_short_record(f):
    # 5 s is only 15..50 periods, with a non-integer count: the bin spacing alone would be 0.2 Hz.
    assert dominant_frequency(T, sine(T, f)) == pytest.approx(f, rel=2e-5)
    ratio = dominant_frequency(T, sine(T, 1.01 * f)) / dominant_frequency(T, sine(T, f))
    assert ratio == pytest.approx(1.01, rel=1e-5)


def test_dominant_frequency_ignores_a_linear_drift():
    assert dominant_frequency(T, sine(T, 3.0) + 4.0 * T) == pytest.approx(3.0, rel=1e-4)


def test_nrmsd_of_a_constant_offset_by_hand():
    # One full period sampled so the peaks +1 and -1 are grid points: range 2, RMS error 0.01.
    t = np.linspace(0.0, 1.0, 4001)
    reference = np.sin(2 * np.pi * t)
    assert nrmsd_percent(reference, reference + 0.01) == pytest.approx(0.01 / 2 * 100, rel=1e-9)


def test_compare_traces_passes_and_fails_on_the_nrmsd_threshold():
    t = np.linspace(0.0, 1.0, 4001)
    reference = {"y": (t, np.sin(2 * np.pi * 4 * t))}
    close = {"y": (t, np.sin(2 * np.pi * 4 * t) + 0.008)}  # 0.4 %
    far = {"y": (t, np.sin(2 * np.pi * 4 * t) + 0.012)}  # 0.6 %, and the peak 1.012
    good = compare_traces(reference, close, Thresholds(nrmsd_percent=0.5), n_points=4001)
    bad = compare_traces(reference, far, Thresholds(nrmsd_percent=0.5), n_points=4001)
    assert good.states["y"].nrmsd_percent == pytest.approx(0.4, rel=1e-6)
    assert good.passed
    assert bad.states["y"].nrmsd_percent == pytest.approx(0.6, rel=1e-6)
    assert not bad.passed
    assert bad.states["y"].peak_ratio == pytest.approx(1.012, rel=1e-9)
    assert bad.failures() == ["y: nrmsd_percent", "y: peak_ratio"]
    assert "FAIL" in bad.table()


def test_compare_traces_judges_peak_and_frequency_ratios():
    reference = {"x": (T, sine(T, 5.0))}
    louder = compare_traces(reference, {"x": (T, sine(T, 5.0, amplitude=1.02))})
    faster = compare_traces(reference, {"x": (T, sine(T, 5.0 * 1.02))})
    assert louder.states["x"].peak_ratio == pytest.approx(1.02, rel=1e-4)
    assert "peak_ratio" in louder.states["x"].failures
    assert faster.states["x"].frequency_ratio == pytest.approx(1.02, rel=1e-4)
    assert "frequency_ratio" in faster.states["x"].failures


def test_compare_traces_uses_the_overlap_of_time_ranges():
    reference = {"x": (np.linspace(0, 5, 1001), np.zeros(1001) + 1.0)}
    circuit = {"x": (np.linspace(1, 7, 1001), np.zeros(1001) + 1.0)}
    result = compare_traces(reference, circuit, n_points=100)
    assert (result.t_start, result.t_stop) == (1.0, 5.0)


def test_flat_reference_leaves_ratios_unjudged_not_passed_by_a_made_up_number():
    t = np.linspace(0, 1, 200)
    result = compare_traces({"x": (t, np.zeros(200))}, {"x": (t, np.zeros(200))})
    metrics = result.states["x"]
    assert math.isnan(metrics.peak_ratio) and math.isnan(metrics.frequency_ratio)
    assert result.to_json()["states"]["x"]["peak_ratio"] is None


def test_map_waveforms_through_time_scale_1000_and_negative_volts_per_unit():
    # The circuit runs 1000 times faster and its node carries -2 V per metre.
    t_circuit = np.linspace(0.0, 5e-3, 2001)
    y_model = lambda t: 0.03 * np.sin(2 * np.pi * 3.0 * t) * np.exp(-0.1 * t)  # noqa: E731
    waves = Waveforms(
        time=t_circuit,
        signals={"v(ny)": -2.0 * y_model(t_circuit * 1000.0), "v(other)": t_circuit},
        engine="test",
    )
    scale = ScaleMap(time_scale=1000.0, states={"y": StateScale("ny", -2.0, "m")})
    traces = map_waveforms(waves, scale)
    t_model, y = traces["y"]
    assert t_model[-1] == pytest.approx(5.0)
    np.testing.assert_allclose(y, y_model(t_model), rtol=0, atol=1e-15)
    # And the whole chain: compared with the model's own trace, the circuit is perfect.
    t_ref = np.linspace(0.0, 5.0, 3001)
    result = compare_traces({"y": (t_ref, y_model(t_ref))}, traces)
    # Only the cubic-spline resampling error remains: order (omega h)^4, about 1e-7 here.
    assert result.states["y"].nrmsd_percent < 1e-4
    assert result.states["y"].phase_lag_s == pytest.approx(0.0, abs=1e-6)
    assert result.passed


def test_map_waveforms_names_a_missing_node():
    waves = Waveforms(time=np.array([0.0, 1.0]), signals={"v(a)": np.zeros(2)})
    scale = ScaleMap(time_scale=1.0, states={"y": StateScale("b", 1.0, "m")})
    with pytest.raises(ComparisonError, match="node 'b'"):
        map_waveforms(waves, scale)


def test_disjoint_time_ranges_are_an_error():
    with pytest.raises(ComparisonError, match="do not overlap"):
        compare_traces(
            {"x": (np.array([0.0, 1.0]), np.zeros(2))}, {"x": (np.array([2.0, 3.0]), np.zeros(2))}
        )


def test_error_frequency_names_the_motion_the_difference_is_made_of():
    reference = sine(T, 3.0)
    circuit = reference + 0.01 * np.sin(2 * np.pi * 8.477 * T) * np.exp(-0.3 * T)
    result = compare_traces({"y": (T, reference)}, {"y": (T, circuit)}, n_points=T.size)
    assert result.states["y"].error_frequency_hz == pytest.approx(8.477, rel=1e-3)
    assert result.states["y"].reference_frequency_hz == pytest.approx(3.0, rel=1e-4)
