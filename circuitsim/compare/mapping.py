"""From circuit waveforms to physical states, and two traces onto one time grid.

A circuit runs ``time_scale`` times faster than the model and carries each state as a node
voltage ``volts_per_unit`` times the physical value (negative when the node carries -x). The
:class:`~circuitsim.synthesis.scalemap.ScaleMap` written beside each netlist says both, so
mapping back needs nothing but the waveforms and that map - whichever engine produced them.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from circuitsim.compare.errors import ComparisonError
from circuitsim.solver.waveforms import Waveforms
from circuitsim.synthesis.scalemap import ScaleMap

Trace = tuple[np.ndarray, np.ndarray]
"""``(t, values)``: model seconds, shape (m,), and the state's physical values, shape (m,)."""


def map_waveforms(
    waveforms: Waveforms, scale_map: ScaleMap, states: list[str] | None = None
) -> dict[str, Trace]:
    """Circuit waveforms as physical state traces on the model's time axis.

    Parameters
    ----------
    waveforms : Waveforms
        Any engine's transient result; must hold ``v(node)`` for every mapped state.
    scale_map : ScaleMap
        The netlist's scale file: ``state(t) = v(node)(t / K) / G``.
    states : list of str, optional
        Which states to map (default: every state of the scale map, in its order).

    Returns
    -------
    dict of str to (ndarray, ndarray)
        Per state ``(t_model, values)``: model seconds (circuit seconds times K), shape (m,),
        and physical values in the state's unit, shape (m,).

    Raises
    ------
    ComparisonError
        A requested state is not in the scale map, or its node is not in the waveforms.
    """
    chosen = list(scale_map.states) if states is None else list(states)
    t_model = np.asarray(scale_map.model_time(np.asarray(waveforms.time, dtype=float)))
    traces: dict[str, Trace] = {}
    for state in chosen:
        if state not in scale_map.states:
            raise ComparisonError(
                f"state {state!r} is not in the scale map (it has {', '.join(scale_map.states)})"
            )
        node = scale_map.states[state].node
        if node not in waveforms:
            raise ComparisonError(
                f"state {state!r}: node {node!r} is not in the {waveforms.engine or 'engine'}"
                f" waveforms (signals: {', '.join(waveforms.names)})"
            )
        volts = np.asarray(waveforms[node], dtype=float)
        traces[state] = (t_model, np.asarray(scale_map.to_state(state, volts)))
    return traces


def common_grid(reference: Trace, candidate: Trace, n_points: int = 4096) -> np.ndarray:
    """A uniform grid over the overlap of two traces' time ranges.

    Parameters
    ----------
    reference, candidate : (ndarray, ndarray)
        ``(t, values)`` traces; t in seconds, increasing.
    n_points : int
        Number of grid points (at least 16).

    Returns
    -------
    ndarray, shape (n_points,)
        Seconds, from ``max(t0)`` to ``min(t_end)``.

    Raises
    ------
    ComparisonError
        Empty traces, or time ranges that do not overlap.
    """
    if n_points < 16:
        raise ComparisonError(f"n_points must be at least 16, got {n_points}")
    t_ref, t_cand = np.asarray(reference[0]), np.asarray(candidate[0])
    if t_ref.size < 2 or t_cand.size < 2:
        raise ComparisonError("a trace has fewer than two time points")
    start = max(t_ref[0], t_cand[0])
    stop = min(t_ref[-1], t_cand[-1])
    if not stop > start:
        raise ComparisonError(
            f"time ranges do not overlap: reference {t_ref[0]:g}..{t_ref[-1]:g} s, "
            f"circuit {t_cand[0]:g}..{t_cand[-1]:g} s"
        )
    return np.linspace(start, stop, n_points)


def resample(trace: Trace, grid: np.ndarray) -> np.ndarray:
    """``trace`` interpolated onto ``grid`` (s) by a cubic spline; shape (len(grid),).

    A cubic spline rather than straight lines: engines save points only where their step
    control put them (ngspice a few dozen per period), and linear interpolation between them
    would add an error of order (omega h)^2 / 8 - hundredths of a percent, not negligible beside
    a 0.5 % threshold - that belongs to neither trace. The spline's error is of order h^4.
    Repeated time points (some engines write a breakpoint twice) keep their last value.
    """
    t, values = np.asarray(trace[0], dtype=float), np.asarray(trace[1], dtype=float)
    if t.shape != values.shape or t.ndim != 1:
        raise ComparisonError(f"time and values differ in shape: {t.shape} vs {values.shape}")
    if not (np.all(np.isfinite(values)) and np.all(np.isfinite(t))):
        raise ComparisonError("trace has non-finite values (NaN or inf)")
    keep = np.append(np.diff(t) > 0.0, True)
    t, values = t[keep], values[keep]
    if np.any(np.diff(t) < 0.0):
        raise ComparisonError("trace time points are not increasing")
    if t.size < 4:
        return np.interp(grid, t, values)
    return CubicSpline(t, values)(np.clip(grid, t[0], t[-1]))
