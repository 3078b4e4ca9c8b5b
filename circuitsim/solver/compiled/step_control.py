"""Step control of the compiled time loop (time_loop.py): the reference engine's rules
(solver/transient.py) for one step, in numba.

The integration coefficients, where a step starts (breakpoints, order 1 after them, TMAX), the
truncation-error limit of the charges (ngspice's CKTterr), the judgement of a step whose Newton
converged (switch transitions, truncation error) and the scalars of an accepted step. The loop
calls these once per attempted step; what each kernel does per Newton iteration is in its steps
(port_steps.py, mna_steps.py).
"""

from __future__ import annotations

import math

import numpy as np

from circuitsim.solver.compiled.slots import (
    ABSTOL,
    ACCEPTED,
    AT_BREAK,
    BI,
    CHGTOL,
    COUNT,
    ERROR_ORDER1,
    ERROR_ORDER2,
    FIRST,
    FIXED_STEP,
    LAST_A0,
    MIN_STEP,
    NHIST,
    ORDER,
    RELTOL,
    SAME_A0,
    SAVED_H,
    TRAP,
    TRTOL,
    H,
    T,
)
from circuitsim.solver.devices.switch_kernel import (
    switch_transition,
    switch_truncate,
    transition_retry,
)
from circuitsim.solver.jit import njit

# the loops' return codes (compiled/failures.py turns the negative ones into errors)
PAUSED, FINISHED, FULL, REPIVOT = 0, 1, 2, 3
NEWTON_FAILED_FIXED, STEP_TOO_SMALL, STEP_TOO_SMALL_LTE, TOO_MANY_STEPS = -1, -2, -3, -4
# an attempt's status when the loop goes on (never returned by a loop)
CONTINUE = 9

# judge_step's verdicts on a step whose Newton converged
GOOD_STEP, CUT_AT_TRANSITION, TRUNCATION_REJECTED = 0, 1, 2


@njit(cache=True)
def coefficients(method, order, h, h_prev):
    """(a0, a1, a2, b1) of trap / Gear-2 (integration.Method.coefficients)."""
    if order == 1:
        return 1.0 / h, -1.0 / h, 0.0, 0.0
    if method == TRAP:
        return 2.0 / h, -2.0 / h, 0.0, -1.0
    a0 = (2 * h + h_prev) / (h * (h + h_prev))
    a1 = -(h + h_prev) / (h * h_prev)
    a2 = h / (h_prev * (h + h_prev))
    return a0, a1, a2, 0.0


@njit(cache=True)
def charge_slots(nq, jslot, charged, has_charge):
    """The charge slots that can be nonzero (every slot but those of junctions without CJO
    and TT, ``charged`` False, whose charge, its derivative and history are exactly 0), and
    whether any slot is such a zero."""
    zero = np.zeros(nq, dtype=np.bool_)
    if has_charge:
        for k in range(jslot.size):
            if not charged[k]:
                zero[jslot[k]] = True
    live = np.empty(nq - np.count_nonzero(zero), dtype=np.int64)
    count = 0
    for i in range(nq):
        if not zero[i]:
            live[count] = i
            count += 1
    return live, count < nq


@njit(cache=True, inline="always")
def truncation_step(real, order, times, q_new, qdot_new, hq, hi, live):
    """Largest step the charges allow (integration.truncation_step, ngspice's CKTterr).

    ``times`` = (t_new, t_n, t_n-1, t_n-2); charges: q_new then the rows of hq, newest first;
    their derivatives qdot_new and hi[0]. Only the slots ``live`` are read: the others'
    charges are exactly 0 (:func:`charge_slots`), and what they allow is
    :func:`zero_charge_step` (52 of the TL074 wheelset's 73 slots).
    """
    reltol, abstol, chgtol, trtol = real[RELTOL], real[ABSTOL], real[CHGTOL], real[TRTOL]
    factor = real[ERROR_ORDER1] if order == 1 else real[ERROR_ORDER2]
    t0, t1, t2 = times[0], times[1], times[2]
    h = t0 - t1
    step = np.inf
    for j in range(live.size):
        i = live[j]
        q0, q1, q2 = q_new[i], hq[0, i], hq[1, i]
        d1a = (q0 - q1) * (1.0 / h)
        d1b = (q1 - q2) * (1.0 / (t1 - t2))
        diff = (d1a - d1b) * (1.0 / (t0 - t2))
        if order == 2:
            t3 = times[3]
            d1c = (q2 - hq[2, i]) * (1.0 / (t2 - t3))
            diff = (diff - (d1b - d1c) * (1.0 / (t1 - t3))) * (1.0 / (t0 - t3))
        volttol = max(abs(qdot_new[i]), abs(hi[0, i])) * reltol + abstol
        chargetol = max(max(abs(q0), abs(q1)), chgtol) * (reltol / h)
        tol = max(volttol, chargetol)
        denominator = max(abs(diff) * factor, abstol)
        step = min(step, tol / denominator)
    step *= trtol
    return math.sqrt(step) if order == 2 else step


@njit(cache=True)
def zero_charge_step(real, order, h):
    """What :func:`truncation_step` gives for a slot whose charge, derivative and history are
    0, by the same operations (diff = 0, volttol = abstol): the minimum with it equals
    reading such slots, as the final scaling is monotonic. A separate call, not a branch in
    truncation_step's loop (that measured 9 % slower per step on the ideal wheelset)."""
    reltol, abstol, chgtol, trtol = real[RELTOL], real[ABSTOL], real[CHGTOL], real[TRTOL]
    factor = real[ERROR_ORDER1] if order == 1 else real[ERROR_ORDER2]
    tol = max(abstol, max(0.0, chgtol) * (reltol / h))
    step = min(np.inf, tol / max(0.0 * factor, abstol)) * trtol
    return math.sqrt(step) if order == 2 else step


@njit(cache=True, inline="always")
def step_start(fs, si, breaks, fixed, max_step, min_step):
    """The next step's start (solver/transient.py's rules): (t, next breakpoint, h, order,
    landing on the breakpoint). Advances past breakpoints already reached, drops to order 1
    and shortens h after a breakpoint, caps h at TMAX and lands exactly on the next one."""
    t = fs[T]
    while si[BI] < breaks.size - 1 and breaks[si[BI]] <= t + min_step:
        si[BI] += 1
    next_break = breaks[si[BI]]
    h = fs[H]
    order = si[ORDER]
    if fixed > 0:
        h = fixed
        if si[AT_BREAK]:
            order = 1
    elif si[AT_BREAK]:
        order = 1
        h = min(h, 0.1 * min(fs[SAVED_H], next_break - t))
        if si[FIRST]:
            h /= 10
    si[AT_BREAK] = 0
    if fixed == 0:
        h = min(h, max_step)
    landing = False
    if t + h >= next_break - min_step:
        fs[SAVED_H] = h
        h = next_break - t
        landing = True
    return t, next_break, h, order, landing


@njit(cache=True, inline="always")
def next_step(real, maxord, npoints, order, h, transition, charges, charges2, switches):
    """Truncation-error control of a converged step (solver/transient.py): (next h, order,
    accepted). ``charges``: the step the charges allow at this order (inf when not computed),
    ``charges2``: at order 2 (only asked for at order 1), ``switches``: what the switches
    allow. A switch transition is a breakpoint, never rejected. Scalars only: the loops
    compute the limits (a call taking their arrays measured 12 % slower per step)."""
    new_h = min(2 * h, charges, switches)
    if new_h > 0.9 * h or transition:
        if order == 1 and maxord > 1 and npoints >= 4:
            new_h = min(2 * h, charges2, switches)
            if new_h > 1.05 * h:
                order = 2
        return new_h, order, True
    return new_h, order, False


@njit(cache=True, _nrt=False, forceinline=True)
def judge_step(
    real, max_order, first, uic, t, h, order, n_history, t_history, x_ext, x_prev_ext, sw,
    state, accepted, approach, q, qdot, q_history, qdot_history, times, live, zeros,
):  # fmt: skip
    """A step from t to t + h (s) whose Newton converged, judged by the switches' transitions
    (devices/switch.py) and the charges' truncation error (solver/transient.py's rules):
    (GOOD_STEP, the next step proposed, order), or (CUT_AT_TRANSITION or
    TRUNCATION_REJECTED, the step to try instead, order).

    ``first``: the run's first step; ``uic``: the run started from initial conditions (then
    its first step ignores transitions); ``times``: (4,) work array. Allocates nothing, and is
    compiled without numba's reference counting and inlined by LLVM (``_nrt=False``,
    ``forceinline``), so that the ports loop's per-step call costs no atomic operations
    (docs/solver.md, "A numba detail that shaped both loops").
    """
    fixed, min_step = real[FIXED_STEP], real[MIN_STEP]
    n_switches, n_charges = sw.shape[0], q_history.shape[1]
    transition = False
    if fixed == 0 and n_switches and not (uic and first):  # uic: solver/transient.py
        fraction = switch_transition(x_ext, x_prev_ext, sw, state, accepted, approach)
        retry = transition_retry(
            fraction, h, t_history[0] - t_history[1] if n_history > 1 else h, min_step
        )
        if retry > 0:  # cut short of the crossing, then just past it (devices/switch.py)
            return CUT_AT_TRANSITION, retry, order
        transition = fraction < 1.0  # a breakpoint: no truncation-error rejection
    new_h = h if fixed > 0 else 2 * h
    if fixed == 0 and not first:
        times[0] = t + h
        for k in range(3):
            times[k + 1] = t_history[k]
        n_points = n_history + 1
        charges = charges2 = switches = np.inf
        if n_points >= order + 2 and n_charges:
            charges = truncation_step(real, order, times, q, qdot, q_history, qdot_history, live)
            if zeros:
                charges = min(charges, zero_charge_step(real, order, times[0] - times[1]))
        if order == 1 and max_order > 1 and n_points >= 4 and n_charges:
            charges2 = truncation_step(real, 2, times, q, qdot, q_history, qdot_history, live)
            if zeros:
                charges2 = min(charges2, zero_charge_step(real, 2, times[0] - times[1]))
        if n_switches:
            switches = switch_truncate(x_ext, x_prev_ext, h, sw, accepted, approach)
        new_h, order, good = next_step(
            real, max_order, n_points, order, h, transition, charges, charges2, switches
        )
        if not good:
            return TRUNCATION_REJECTED, new_h, order
    return GOOD_STEP, new_h, order


@njit(cache=True, inline="always")
def finish_step(fs, si, t, new_h, a0, order, landing, toggled, fixed, maxord, nh):
    """The counters and scalars of an accepted step: history length, output row, the a0
    streak (for refactoring at a settled step size), order, next breakpoint handling."""
    # a switch toggled: the charges' history before it does not extend past the jump in
    # their derivatives (solver/transient.py)
    si[NHIST] = 1 if toggled else min(nh + 1, 4)
    si[COUNT] += 1
    si[ACCEPTED] += 1
    if a0 == fs[LAST_A0]:
        si[SAME_A0] += 1
    else:
        fs[LAST_A0] = a0
        si[SAME_A0] = 1
    if fixed > 0 and order < maxord:
        order += 1
    if landing or toggled:
        si[AT_BREAK] = 1
    si[FIRST] = 0
    si[ORDER] = order
    fs[T] = t
    fs[H] = new_h
