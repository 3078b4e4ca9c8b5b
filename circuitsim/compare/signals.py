"""Scalar measures of one trace or of a pair of traces on a common uniform grid.

All functions take ``t`` (seconds, uniform, shape (n,)) and values of shape (n,) in any unit.
They are plain functions of arrays so that they apply to any model's states and any engine.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import minimize_scalar


def nrmsd_percent(reference: np.ndarray, candidate: np.ndarray) -> float:
    """Normalized RMS deviation: RMS(candidate - reference) / range(reference) x 100.

    Returns 0 for identical traces and inf when the reference is constant but the traces differ
    (no range to normalize by).
    """
    reference, candidate = np.asarray(reference, float), np.asarray(candidate, float)
    with np.errstate(over="ignore", invalid="ignore"):  # a difference past the float range
        difference = candidate - reference
        scale = float(np.max(np.abs(difference), initial=0.0))
        if 0.0 < scale < np.inf:  # the RMS at unit peak: no square overflows
            rms = scale * float(np.sqrt(np.mean((difference / scale) ** 2)))
        else:
            rms = scale
        span = float(np.ptp(reference))
    if span == 0.0:
        return 0.0 if rms == 0.0 else float("inf")
    return 100.0 * rms / span


def max_abs_error(reference: np.ndarray, candidate: np.ndarray) -> float:
    """Largest ``|candidate - reference|``, in the traces' unit."""
    return float(np.max(np.abs(np.asarray(candidate, float) - np.asarray(reference, float))))


def peak_ratio(reference: np.ndarray, candidate: np.ndarray) -> float:
    """``max|candidate| / max|reference|`` (NaN when the reference is identically zero)."""
    top = float(np.max(np.abs(reference)))
    if top == 0.0:
        return float("nan")
    return float(np.max(np.abs(candidate))) / top


def _unit_peak(values: np.ndarray) -> np.ndarray:
    """``values`` divided by their largest magnitude (unchanged if all zero or not finite).

    Frequencies and correlations do not depend on a trace's scale, but their sums of squares
    overflow for values past about 1e154 (a raw file's 1e300 V): measured at unit peak they
    are exact for every finite trace.
    """
    values = np.asarray(values, float)
    peak = float(np.max(np.abs(values), initial=0.0))
    return values / peak if 0.0 < peak < np.inf else values


def dominant_frequency(t: np.ndarray, values: np.ndarray, zero_pad: int = 8) -> float:
    """Frequency (Hz) of the largest spectral peak, interpolated between FFT bins.

    The trace is linearly detrended (a drifting mean is not an oscillation), Hann-windowed (so a
    non-integer number of periods leaks little), zero-padded ``zero_pad`` times, and the peak is
    located by fitting a parabola through the log magnitudes of the largest bin and its two
    neighbours. With the Hann window's near-Gaussian main lobe that fit is accurate to a small
    fraction of a bin even on records only a few periods long. The zero-frequency bin is never
    chosen. Returns NaN for a trace with no variation.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Uniform time points, seconds.
    values : ndarray, shape (n,)
        The trace.
    zero_pad : int
        Transform length as a multiple of n.
    """
    t, values = np.asarray(t, float), _unit_peak(values)
    n = values.size
    dt = (t[-1] - t[0]) / (n - 1)
    from scipy import signal  # here, not at the top: importing it takes 0.5 s (sweeps need none)

    x = signal.detrend(values, type="linear") * signal.windows.hann(n, sym=False)
    n_fft = int(zero_pad) * n
    magnitude = np.abs(np.fft.rfft(x, n=n_fft))
    if not np.any(magnitude[1:] > 0.0):
        return float("nan")
    k = int(np.argmax(magnitude[1:])) + 1
    df = 1.0 / (n_fft * dt)
    if k + 1 >= magnitude.size:
        return k * df
    a, b, c = np.log(magnitude[k - 1 : k + 2] + np.finfo(float).tiny)
    denominator = a - 2.0 * b + c
    shift = 0.5 * (a - c) / denominator if denominator < 0.0 else 0.0
    return (k + shift) * df


def phase_lag(
    t: np.ndarray,
    reference: np.ndarray,
    candidate: np.ndarray,
    max_lag: float | None = None,
) -> float:
    """Time (s) by which ``candidate`` lags ``reference``: positive when the candidate is late.

    Convention: if ``candidate(t) = g * reference(t - tau) + offset`` then the result is
    ``tau`` (so a circuit whose trace arrives late has a positive lag).

    Method: the Pearson correlation between a fixed interior window of the candidate and the
    reference shifted by each whole number of samples (edges excluded so that every lag is
    judged on the same number of points; Pearson so that gain and offset do not move the peak),
    then a sub-sample refinement maximizing the same correlation over a continuous shift, the
    reference being shifted by cubic-spline interpolation. For identical but shifted traces the
    correlation is exactly 1 at the true lag, so the answer is limited only by the spline's
    accuracy, far below one sample.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Uniform time points, seconds.
    reference, candidate : ndarray, shape (n,)
        The two traces.
    max_lag : float, optional
        Largest lag searched (s). Default: half the reference's dominant period (a periodic
        signal's lag is ambiguous beyond that), at most a quarter of the record.

    Returns
    -------
    float
        Seconds; NaN when either trace has no variation.
    """
    t = np.asarray(t, float)
    r = _unit_peak(reference)  # Pearson correlations do not depend on the scale
    c = _unit_peak(candidate)
    n = t.size
    dt = (t[-1] - t[0]) / (n - 1)
    if np.ptp(r) == 0.0 or np.ptp(c) == 0.0:
        return float("nan")
    if max_lag is None:
        frequency = dominant_frequency(t, r)
        max_lag = 0.5 / frequency if np.isfinite(frequency) and frequency > 0 else np.inf
    max_lag = min(max_lag, 0.25 * (t[-1] - t[0]))
    lags = max(1, int(np.ceil(max_lag / dt)))
    window = slice(lags, n - lags)
    c_win = c[window] - np.mean(c[window])
    m = c_win.size
    # Sum over the window of c' * r shifted by j - lags samples, for j = 0 .. 2 lags.
    from scipy import signal  # (see dominant_frequency)

    products = signal.correlate(r, c_win, mode="valid")
    cumulative = np.concatenate(([0.0], np.cumsum(r)))
    cumulative_sq = np.concatenate(([0.0], np.cumsum(r * r)))
    sums = cumulative[m:] - cumulative[:-m]
    sums_sq = cumulative_sq[m:] - cumulative_sq[:-m]
    variances = np.maximum(sums_sq - sums * sums / m, 0.0)
    norm = np.sqrt(variances * np.sum(c_win * c_win))
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.where(norm > 0.0, products / norm, -np.inf)
    j_best = int(np.argmax(rho))
    coarse = (lags - j_best) * dt

    spline = CubicSpline(t, r)
    t_win = t[window]

    def negative_correlation(tau: float) -> float:
        shifted = spline(t_win - tau)
        shifted = shifted - np.mean(shifted)
        denominator = np.sqrt(np.sum(shifted * shifted) * np.sum(c_win * c_win))
        return -float(np.sum(shifted * c_win) / denominator) if denominator > 0 else 0.0

    best = minimize_scalar(
        negative_correlation,
        bounds=(coarse - dt, coarse + dt),
        method="bounded",
        options={"xatol": 1e-7 * dt},
    )
    return float(best.x)
