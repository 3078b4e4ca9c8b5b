"""The voltage-controlled switch's kernel twin: switch.py's rules, compiled by numba.

:class:`~circuitsim.solver.devices.switch.SwitchFamily` decides all switches at once with
numpy (the reference engine); the compiled loops (solver/compiled/) use these functions, written
once here. The transition rule itself (:func:`transition_retry`) is plain arithmetic in
switch.py, compiled here as it is. Agreement: tests/solver/test_compiled_kernel.py and
tests/solver/test_switch_transition.py run both engines on the same circuits.
"""

from __future__ import annotations

import math

import numpy as np

from circuitsim.solver.devices import switch as switch_rules
from circuitsim.solver.jit import njit

# columns of the switch nodes (KernelPlan.sw; -1 = ground, the last entry of x_ext): the
# switched terminals, the control voltage's + and - nodes
POSITIVE, NEGATIVE, CONTROL_POSITIVE, CONTROL_NEGATIVE = range(4)
NODE_COLUMNS = 4
# columns of KernelPlan.approach: thresholds VT + VH and VT - VH (V), the truncation rule's
# APPROACH_FRACTION and APPROACH_FLOOR (V)
ON_ABOVE, OFF_BELOW, FRACTION, FLOOR = range(4)
APPROACH_COLUMNS = 4
# columns of KernelPlan.g_switch: conductance on, off (S)
G_ON, G_OFF = range(2)


@njit(cache=True, inline="always")
def next_state(control, keep, on_above, off_below) -> bool:
    """The switch's state at control voltage ``control`` (V) when ``keep`` is the state it
    keeps inside the hysteresis band (SwitchFamily.update_state)."""
    return (keep or control > on_above) and control >= off_below


@njit(cache=True, inline="always")
def switch_truncate(x_ext, x_prev_ext, h_prev, sw, accepted, approach) -> float:
    """Largest next step (s) the switches allow (SwitchFamily.truncate); x_ext, x_prev_ext:
    the solutions at the new and the last accepted point with ground appended, shape (n + 1,);
    h_prev: the step between them (s)."""
    allowed = np.inf
    for k in range(sw.shape[0]):
        p, n = sw[k, CONTROL_POSITIVE], sw[k, CONTROL_NEGATIVE]
        vc = x_ext[p] - x_ext[n]
        rate = (vc - (x_prev_ext[p] - x_prev_ext[n])) / h_prev
        threshold = approach[k, OFF_BELOW] if accepted[k] else approach[k, ON_ABOVE]
        distance = threshold - vc
        if rate * distance > 0 and distance != 0:
            step = (approach[k, FRACTION] * abs(distance) + approach[k, FLOOR]) / abs(rate)
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
        p, n = sw[k, CONTROL_POSITIVE], sw[k, CONTROL_NEGATIVE]
        vc = x_ext[p] - x_ext[n]
        vc_prev = x_prev_ext[p] - x_prev_ext[n]
        threshold = approach[k, ON_ABOVE] if state[k] else approach[k, OFF_BELOW]
        f = 1.0
        if vc != vc_prev:
            f = (threshold - vc_prev) / (vc - vc_prev)
            f = min(max(f, 0.0), 1.0) if math.isfinite(f) else 1.0
        fraction = min(fraction, f)
    return fraction


# the family's rule, compiled: written once, in switch.py
transition_retry = njit(cache=True)(switch_rules.transition_retry)
