"""Compiled transient loop: the reference engine's step control (solver/transient.py), in numba.

Same breakpoints, order changes, truncation-error rule (ngspice's CKTterr), Newton-failure
and switch-transition handling as ``run_transient``; the differences are only in how the
linear systems are solved (lowrank.py: one factorization, low-rank updates) and that the loop
runs until ``t_until`` and returns, so that the caller can report progress and grow the
output arrays. Every scalar of the loop lives in ``st.fs`` / ``st.ints`` between calls.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from circuitsim.solver.compiled.lowrank import add_u_columns, csr_matvec
from circuitsim.solver.compiled.mna_newton import CONVERGED, REORDER, mna_newton
from circuitsim.solver.compiled.mna_newton import REPIVOT as NEWTON_REPIVOT
from circuitsim.solver.compiled.newton import (
    ACCEPTED,
    AT_BREAK,
    ATTEMPTS,
    BI,
    COUNT,
    FACTOR_A0,
    FIRST,
    IN_ITERATION,
    LAST_A0,
    NEWTON,
    NHIST,
    NOT_RESUMING,
    ORDER,
    PAUSE_ATTEMPTS,
    REJECTED,
    RESUME_AT,
    RESUME_ITERATION,
    RESUME_NONCON,
    RESUME_RETRY,
    SAME_A0,
    SAVED_H,
    H,
    T,
    extend,
    resumed_step,
    wait_for_factor,
)
from circuitsim.solver.compiled.slots import (
    ABSTOL,
    CHGTOL,
    ERROR_ORDER1,
    ERROR_ORDER2,
    FIXED_STEP,
    MAX_STEP,
    MAX_STEPS,
    MAXORD,
    METHOD,
    MIN_STEP,
    RELTOL,
    REPIVOT_A0,
    TRAP,
    TRTOL,
    TSTOP,
    UIC,
)
from circuitsim.solver.devices.source_kernel import source_value
from circuitsim.solver.devices.switch_kernel import (
    switch_transition,
    switch_truncate,
    transition_retry,
)

REBASE_STEPS = 8  # refactor when this many accepted steps in a row used one new a0
# A Newton failure at an a0 this far from the factorization's is retried once on a
# factorization at this a0 before the step is cut: with the charge columns' update
# d = a0 - a0_ref dominating B (steps far shorter than the factored one, right after a
# breakpoint or a switch transition), the Woodbury solve can lose the digits that Newton's
# branch-current tolerance (abstol 1e-12 A) needs, where an exact solve converges
# (measured: the wheelset at reltol 1e-6 with uic failed at t = 6e-16 s without it).
RETRY_RATIO = 16.0

# return codes
PAUSED, FINISHED, FULL, REPIVOT = 0, 1, 2, 3
NEWTON_FAILED_FIXED, STEP_TOO_SMALL, STEP_TOO_SMALL_LTE, TOO_MANY_STEPS = -1, -2, -3, -4


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
def source_rhs(t, rhs_const, kind, par, dc, pwl_start, pwl_t, pwl_v, rows, signs):
    """Right-hand side of the independent sources at time t (transient values), and the
    time-dependent sources' values."""
    rhs = rhs_const.copy()
    values = np.empty(kind.size)
    for k in range(kind.size):
        value = source_value(t, k, kind, par, dc, pwl_start, pwl_t, pwl_v)
        values[k] = value
        for j in range(2):
            row = rows[k, j]
            if row >= 0:
                rhs[row] += signs[k, j] * value
    return rhs, values


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


@njit(cache=True)
def run(plan, st, t_until, mid):
    """Integrate from st.fs[T] until t_until (or tstop); returns a status code. REPIVOT: the
    pivot order no longer suits the matrix at a0 = st.fs[REPIVOT_A0] and the devices' present
    state; the step is undone (the scalars restored), to be attempted again on a new order.
    newton.FACTOR: a pivot became too small; a new order at a0 = st.fs[FACTOR_A0] and the
    present state, then re-entered where it stopped (``mid``: a newton.MidStep)."""
    real, ints = plan.real, plan.ints
    method, maxord, max_steps = ints[METHOD], ints[MAXORD], ints[MAX_STEPS]
    fixed, max_step = real[FIXED_STEP], real[MAX_STEP]
    min_step, tstop = real[MIN_STEP], real[TSTOP]
    md, ms = plan.jp.shape[0], plan.sw.shape[0]
    nports = md + ms
    lin = plan.lin_slots
    n, nq = plan.abs_tol.size, st.hq.shape[1]
    fs, si = st.fs, st.ints
    fs_start, si_start = mid.fs_start, mid.ints_start
    breaks = plan.breaks
    x_ext = np.empty(n + 1)
    vt = (plan.VT_ptr, plan.VT_idx, plan.VT_val)
    ut = (plan.UT_ptr, plan.UT_idx, plan.UT_val)
    # every array the loop touches, taken out of the tuples once: each access to a tuple's
    # array member inside the loop would cost a reference-count update (an atomic operation)
    ht, hx, hq, hi = st.ht, st.hx, st.hq, st.hi
    x_prev_ext, state, accepted, vd_accepted = st.x_prev_ext, st.state, st.accepted, st.vd_accepted
    out_t, out_x, fail_x, fail_prev = st.out_t, st.out_x, st.fail_x, st.fail_prev
    port_p, port_n, sw, approach = plan.port_p, plan.port_n, plan.sw, plan.approach
    rhs_const, src_kind, src_par, src_dc = plan.rhs_const, plan.src_kind, plan.src_par, plan.src_dc
    pwl_start, pwl_t, pwl_v = plan.pwl_start, plan.pwl_t, plan.pwl_v
    src_rows, src_signs = plan.src_rows, plan.src_signs
    live, zeros = charge_slots(nq, plan.jslot, plan.charged, plan.has_charge)
    hist = np.empty(nq)
    x_guess = np.empty(n)
    x_new, rows = mid.x_new, mid.rows
    b = np.empty(n)
    g_sw = np.empty(ms)
    q, qdot = mid.q, mid.qdot
    times = np.empty(4)
    charges_lin = np.empty(nports + lin.size)
    resume = si[RESUME_AT]  # back from a new pivot order: where the step was
    si[RESUME_AT] = NOT_RESUMING
    while tstop - fs[T] > min_step:
        if resume != NOT_RESUMING:
            t, next_break, h, order, landing = resumed_step(fs, si, breaks)
        else:
            if fs[T] >= t_until or si[ATTEMPTS] >= si[PAUSE_ATTEMPTS]:
                return PAUSED
            if si[COUNT] >= out_t.size:
                return FULL
            fs_start[:] = fs
            si_start[:] = si
            t, next_break, h, order, landing = step_start(fs, si, breaks, fixed, max_step, min_step)
        nh = si[NHIST]
        # a failed attempt's last iterate is in fail_x (solver/transient.py)
        retry_from = resume != NOT_RESUMING and si[RESUME_RETRY] != 0
        while True:
            if resume == NOT_RESUMING:
                si[ATTEMPTS] += 1
            if si[ATTEMPTS] > max_steps:
                fs[H] = h
                return TOO_MANY_STEPS
            h_prev = ht[0] - ht[1] if nh > 1 else h
            a0, a1, a2, b1 = coefficients(method, order, h, h_prev)
            for j in range(nq):
                hist[j] = a1 * hq[0, j] + b1 * hi[0, j] + a2 * hq[1, j]
            rhs0, src_values = source_rhs(
                t + h, rhs_const, src_kind, src_par, src_dc, pwl_start, pwl_t, pwl_v,
                src_rows, src_signs,
            )  # fmt: skip
            if lin.size:
                add_u_columns(ut, -hist[lin], nports, rhs0)
            ratio = h / h_prev if nh > 1 else 0.0
            for i in range(n):
                x_guess[i] = hx[0, i] + ratio * (hx[0, i] - hx[1, i])
            if nh == 1 and retry_from:  # go on from where the failed attempt got to
                x_guess[:] = fail_x
            for j in range(nq if resume == NOT_RESUMING else 0):
                q[j] = 0.0
                qdot[j] = 0.0
            outcome, iterations, x_before = mna_newton(
                plan, st, x_guess, a0, hist, rhs0, q, qdot, g_sw, x_new, b,
                si[RESUME_ITERATION] if resume != NOT_RESUMING else 0,
            )  # fmt: skip
            resume = NOT_RESUMING
            if outcome == REORDER:
                si[RESUME_RETRY] = 1 if retry_from else 0
                fs[FACTOR_A0] = a0
                return wait_for_factor(
                    fs, si, IN_ITERATION, h, order, landing, 0, iterations, si[RESUME_NONCON]
                )
            if outcome == NEWTON_REPIVOT:
                fs[:] = fs_start
                si[:] = si_start
                fs[REPIVOT_A0] = a0
                return REPIVOT
            si[NEWTON] += iterations
            if outcome != CONVERGED:
                si[REJECTED] += 1
                fail_x[:] = x_new
                fail_prev[:] = x_before
                retry_from = np.all(np.isfinite(x_new))
                fs[H] = h
                if fixed > 0:
                    return NEWTON_FAILED_FIXED
                h /= 8
                order = 1
                landing = False
                if h < min_step:
                    fs[H] = h
                    return STEP_TOO_SMALL
                continue
            if lin.size:
                csr_matvec(vt[0], vt[1], vt[2], x_new, charges_lin)
                for j in range(lin.size):
                    ql = charges_lin[nports + j]
                    q[lin[j]] = ql
                    qdot[lin[j]] = a0 * ql + hist[lin[j]]
            extend(x_new, x_ext)
            transition = False
            if fixed == 0 and ms and not (ints[UIC] and si[FIRST]):  # uic: solver/transient.py
                fraction = switch_transition(x_ext, x_prev_ext, sw, state, accepted, approach)
                retry = transition_retry(fraction, h, ht[0] - ht[1] if nh > 1 else h, min_step)
                if retry > 0:  # cut short of the crossing, then just past it (devices/switch.py)
                    si[REJECTED] += 1
                    h = retry
                    landing = False
                    continue
                transition = fraction < 1.0  # a breakpoint: no truncation-error rejection
            new_h = h if fixed > 0 else 2 * h
            if fixed == 0 and not si[FIRST]:
                times[0] = t + h
                for j in range(3):
                    times[j + 1] = ht[j]
                npoints = nh + 1
                charges = charges2 = switches = np.inf
                if npoints >= order + 2 and nq:
                    charges = truncation_step(real, order, times, q, qdot, hq, hi, live)
                    if zeros:
                        charges = min(charges, zero_charge_step(real, order, times[0] - times[1]))
                if order == 1 and maxord > 1 and npoints >= 4 and nq:
                    charges2 = truncation_step(real, 2, times, q, qdot, hq, hi, live)
                    if zeros:
                        charges2 = min(charges2, zero_charge_step(real, 2, times[0] - times[1]))
                if ms:
                    switches = switch_truncate(x_ext, x_prev_ext, h, sw, accepted, approach)
                new_h, order, good = next_step(
                    real, maxord, npoints, order, h, transition, charges, charges2, switches
                )
                if not good:
                    si[REJECTED] += 1
                    h = new_h
                    landing = False
                    if h < min_step:
                        fail_x[:] = x_new
                        fail_prev[:] = x_before
                        fs[H] = h
                        return STEP_TOO_SMALL_LTE
                    continue
            break

        # accept
        t = next_break if landing else t + h
        for i in range(n + 1):
            x_prev_ext[i] = x_ext[i]
        toggled = False
        for k in range(md):
            vd_accepted[k] = x_ext[port_p[k]] - x_ext[port_n[k]]
        for k in range(ms):
            if state[k] != accepted[k]:
                toggled = True
            accepted[k] = state[k]
        # history, newest first (element loops: a row view would cost a reference count)
        for j in range(3, 0, -1):
            ht[j] = ht[j - 1]
            for i in range(n):
                hx[j, i] = hx[j - 1, i]
            for i in range(nq):
                hq[j, i] = hq[j - 1, i]
        ht[0] = t
        row = si[COUNT]
        out_t[row] = t
        for i in range(n):
            hx[0, i] = x_new[i]
        for k in range(rows.size):
            out_x[row, k] = x_new[rows[k]]
        for i in range(nq):
            hi[1, i] = hi[0, i]
            hi[0, i] = qdot[i]
            hq[0, i] = q[i]
        finish_step(fs, si, t, new_h, a0, order, landing, toggled, fixed, maxord, nh)
    return FINISHED
