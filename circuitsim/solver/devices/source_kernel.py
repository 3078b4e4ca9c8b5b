"""The independent sources' kernel twin: source_waveforms.py's transient values, compiled.

:class:`~circuitsim.solver.devices.source_waveforms.SourceValues` evaluates all sources of a
family at once with numpy (the reference engine) and describes them to the compiled loops by
:meth:`~circuitsim.solver.devices.source_waveforms.SourceValues.kernel_arrays`, whose kinds and
parameter columns are named here; :func:`source_value` is the one source's value the compiled
loops (solver/compiled/) compute at every time point. Agreement:
tests/solver/test_compiled_kernel.py and tests/solver/test_waveforms.py.
"""

from __future__ import annotations

import math

import numpy as np

from circuitsim.solver.jit import njit

# source kinds (SourceValues.kernel_arrays, KernelPlan.src_kind)
DC, SIN, PULSE, PWL = range(4)
# columns of KernelPlan.src_par for a SIN source: offset (V or A), amplitude, angular frequency
# (rad/s), delay (s), damping (1/s), phase (rad)
OFFSET, AMPLITUDE, OMEGA, SIN_DELAY, DAMPING, PHASE = range(6)
# ... for a PULSE source: initial and pulsed value, delay, rise, fall, width, period (s)
INITIAL, PULSED, PULSE_DELAY, RISE, FALL, WIDTH, PERIOD = range(7)
PARAM_COLUMNS = 8


@njit(cache=True, inline="always")
def source_value(t, k, kind, par, dc, pwl_start, pwl_t, pwl_v) -> float:
    """Value of source k at time t (s) in its transient (SourceValues.values); ``pwl_t``,
    ``pwl_v``: every PWL table's times and values, source k's from ``pwl_start[k]`` to
    ``pwl_start[k + 1]``."""
    what = kind[k]
    if what == DC:
        return dc[k]
    if what == SIN:
        tau = max(t - par[k, SIN_DELAY], 0.0)
        return par[k, OFFSET] + par[k, AMPLITUDE] * math.sin(
            par[k, OMEGA] * tau + par[k, PHASE]
        ) * math.exp(-par[k, DAMPING] * tau)
    if what == PULSE:
        v1, v2 = par[k, INITIAL], par[k, PULSED]
        tr, tf, pw, per = par[k, RISE], par[k, FALL], par[k, WIDTH], par[k, PERIOD]
        tau = t - par[k, PULSE_DELAY]
        if tau > per:
            tau -= per * math.floor(tau / per)
        if tau <= 0 or tau >= tr + pw + tf:
            return v1
        if tau >= tr and tau <= tr + pw:
            return v2
        if tau < tr:
            return v1 + (v2 - v1) * tau / tr
        return v2 + (v1 - v2) * (tau - tr - pw) / tf
    return pwl_value(t, k, pwl_start, pwl_t, pwl_v)


@njit(cache=True, _nrt=True)
def pwl_value(t, k, pwl_start, pwl_t, pwl_v) -> float:
    """Value of PWL source k at time t (s). A call, compiled with numba's reference counting
    whatever its caller's flags (np.interp allocates), so that the time loop, compiled
    without it (solver/compiled/time_loop.march), may inline :func:`source_value`."""
    a, b = pwl_start[k], pwl_start[k + 1]
    return np.interp(t, pwl_t[a:b], pwl_v[a:b])
