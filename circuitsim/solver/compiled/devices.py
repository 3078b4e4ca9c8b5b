"""Compiled (numba) device evaluations for the fast transient kernel, one element at a time.

These are the scalar forms of the numpy families in ``solver/devices/``: the same equations,
written for one element so that the kernel loops over elements without allocating. Each
function names the family method it mirrors; the kernel's agreement with the reference engine
is tested in tests/solver/test_compiled_kernel.py.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from circuitsim.solver.devices import switch as switch_rules

# source kinds (plan.SOURCE_KINDS)
DC, SIN, PULSE, PWL = 0, 1, 2, 3


@njit(cache=True)
def pnjlim(vnew: float, vold: float, vt: float, vcrit: float) -> tuple[float, bool]:
    """SPICE's junction-voltage limiting of one junction (diode.pnjlim); (volts, limited)."""
    if vnew > vcrit and abs(vnew - vold) > 2 * vt:
        if vold > 0:
            arg = 1 + (vnew - vold) / vt
            if arg > 0:
                return vold + vt * math.log(arg), True
            return vcrit, True
        return vt * math.log(max(vnew, vt) / vt), True
    floor = -vold - 1 if vold > 0 else 2 * vold - 1
    if vnew < floor:
        return floor, True
    return vnew, False


@njit(cache=True)
def junction_current(vd, isat, inv_vte, is_over_vte, knee, cubic_scale, three_vte, gmin):
    """Static current (A) and conductance (S) of one junction with gmin
    (DiodeFamily._current). Scalars only: an array argument costs a reference-count update
    per call, and this runs for every junction at every Newton iteration."""
    if vd < knee:
        arg = (cubic_scale / vd) ** 3
        return isat * (-arg - 1.0) + gmin * vd, is_over_vte * (three_vte * arg / vd) + gmin
    ex = math.exp(min(vd * inv_vte, 700.0))
    return isat * (ex - 1.0) + gmin * vd, is_over_vte * ex + gmin


@njit(cache=True)
def junction_charge(
    vd, cd, gd, knee, inv_vj, neg_m, q_scale, ext_offset, ext_quadratic, ext_slope, cjo, tt
):
    """Depletion plus diffusion charge (C) and capacitance (F) of one junction
    (DiodeFamily._charge); scalars only, as junction_current."""
    arg = 1.0 - min(vd, knee) * inv_vj
    sarg = arg**neg_m
    excess = max(vd - knee, 0.0)
    q = q_scale * (1.0 - arg * sarg) + excess * (ext_offset + ext_quadratic * vd)
    c = cjo * sarg + ext_slope * excess
    return q + tt * cd, c + tt * gd


@njit(cache=True, inline="always")
def source_value(
    t: float,
    k: int,
    kind: np.ndarray,
    par: np.ndarray,
    dc: np.ndarray,
    pwl_start: np.ndarray,
    pwl_t: np.ndarray,
    pwl_v: np.ndarray,
) -> float:
    """Value of independent source k at time t, seconds (SourceValues.values, transient)."""
    what = kind[k]
    if what == DC:
        return dc[k]
    p = par[k]
    if what == SIN:
        # offset, amplitude, omega, delay, damping, phase
        tau = max(t - p[3], 0.0)
        return p[0] + p[1] * math.sin(p[2] * tau + p[5]) * math.exp(-p[4] * tau)
    if what == PULSE:
        # initial, pulsed, delay, rise, fall, width, period
        v1, v2, tr, tf, pw, per = p[0], p[1], p[3], p[4], p[5], p[6]
        tau = t - p[2]
        if tau > per:
            tau -= per * math.floor(tau / per)
        if tau <= 0 or tau >= tr + pw + tf:
            return v1
        if tau >= tr and tau <= tr + pw:
            return v2
        if tau < tr:
            return v1 + (v2 - v1) * tau / tr
        return v2 + (v1 - v2) * (tau - tr - pw) / tf
    a, b = pwl_start[k], pwl_start[k + 1]
    return np.interp(t, pwl_t[a:b], pwl_v[a:b])


@njit(cache=True, inline="always")
def switch_truncate(x_ext, x_prev_ext, h_prev, sw, accepted, approach) -> float:
    """Largest next step (s) the switches allow (SwitchFamily.truncate).

    ``sw`` rows: p, n, cp, cn (node indices, -1 = ground, as the last entry of x_ext);
    ``approach`` columns: on_above, off_below, APPROACH_FRACTION, APPROACH_FLOOR.
    """
    allowed = np.inf
    for k in range(sw.shape[0]):
        vc = x_ext[sw[k, 2]] - x_ext[sw[k, 3]]
        rate = (vc - (x_prev_ext[sw[k, 2]] - x_prev_ext[sw[k, 3]])) / h_prev
        threshold = approach[k, 1] if accepted[k] else approach[k, 0]
        distance = threshold - vc
        if rate * distance > 0 and distance != 0:
            step = (approach[k, 2] * abs(distance) + approach[k, 3]) / abs(rate)
            allowed = min(allowed, step)
    return allowed


@njit(cache=True, inline="always")
def switch_transition(x_ext, x_prev_ext, sw, state, accepted, approach) -> float:
    """Where in the last step (0..1) the first toggled switch crossed its threshold
    (SwitchFamily.transition_fraction)."""
    fraction = 1.0
    for k in range(sw.shape[0]):
        if state[k] == accepted[k]:
            continue
        vc = x_ext[sw[k, 2]] - x_ext[sw[k, 3]]
        vc_prev = x_prev_ext[sw[k, 2]] - x_prev_ext[sw[k, 3]]
        threshold = approach[k, 0] if state[k] else approach[k, 1]
        f = 1.0
        if vc != vc_prev:
            f = (threshold - vc_prev) / (vc - vc_prev)
            f = min(max(f, 0.0), 1.0) if math.isfinite(f) else 1.0
        fraction = min(fraction, f)
    return fraction


# the switch family's rule (devices/switch.py), compiled: written once, there
transition_retry = njit(cache=True)(switch_rules.transition_retry)
