"""Compiled transient loop: the reference engine's step control (solver/transient.py), in numba.

Same breakpoints, order changes, truncation-error rule (ngspice's CKTterr), Newton-failure
and switch-transition handling as ``run_transient`` (the rules in step_control.py, shared with
the ports loop); the differences are only in how the linear systems are solved (mna_newton.py,
sparse_lu.py) and that the loop runs until ``t_until`` and returns, so that the caller can
report progress and grow the output arrays. Every scalar of the loop lives in ``st.fs`` /
``st.ints`` between calls.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from circuitsim.solver.compiled.lowrank import add_u_columns, csr_matvec
from circuitsim.solver.compiled.mna_newton import CONVERGED, REORDER, mna_newton
from circuitsim.solver.compiled.mna_newton import REPIVOT as NEWTON_REPIVOT
from circuitsim.solver.compiled.newton import (
    ATTEMPTS,
    COUNT,
    FACTOR_A0,
    FIRST,
    IN_ITERATION,
    NEWTON,
    NHIST,
    NOT_RESUMING,
    PAUSE_ATTEMPTS,
    REJECTED,
    RESUME_AT,
    RESUME_ITERATION,
    RESUME_NONCON,
    RESUME_RETRY,
    H,
    T,
    extend,
    resumed_step,
    wait_for_factor,
)
from circuitsim.solver.compiled.slots import (
    FIXED_STEP,
    MAX_STEP,
    MAX_STEPS,
    MAXORD,
    METHOD,
    MIN_STEP,
    REPIVOT_A0,
    TSTOP,
    UIC,
)
from circuitsim.solver.compiled.step_control import (
    FINISHED,
    FULL,
    GOOD_STEP,
    NEWTON_FAILED_FIXED,
    PAUSED,
    REPIVOT,
    STEP_TOO_SMALL,
    STEP_TOO_SMALL_LTE,
    TOO_MANY_STEPS,
    TRUNCATION_REJECTED,
    charge_slots,
    coefficients,
    finish_step,
    judge_step,
    step_start,
)
from circuitsim.solver.devices.source_kernel import source_value


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


@njit(cache=True, _nrt=False, forceinline=True)
def record_point(
    t, x_new, x_ext, x_prev_ext, port_p, port_n, vd_accepted, state, accepted, t_history,
    x_history, q_history, qdot_history, q, qdot, out_t, out_x, rows, row,
):  # fmt: skip
    """The converged point at t (s) accepted: the junction voltages and switch states it
    leaves, the histories (newest first), the output ``row`` (the unknowns ``rows``); returns
    whether a switch toggled in the step. Allocates nothing (compiled as
    step_control.judge_step)."""
    n, n_charges = x_new.size, q_history.shape[1]
    for i in range(n + 1):
        x_prev_ext[i] = x_ext[i]
    toggled = False
    for k in range(vd_accepted.size):  # the junctions: the ports' first md
        vd_accepted[k] = x_ext[port_p[k]] - x_ext[port_n[k]]
    for k in range(state.size):
        if state[k] != accepted[k]:
            toggled = True
        accepted[k] = state[k]
    # element loops: a row view would cost a reference count
    for j in range(3, 0, -1):
        t_history[j] = t_history[j - 1]
        for i in range(n):
            x_history[j, i] = x_history[j - 1, i]
        for i in range(n_charges):
            q_history[j, i] = q_history[j - 1, i]
    t_history[0] = t
    out_t[row] = t
    for i in range(n):
        x_history[0, i] = x_new[i]
    for k in range(rows.size):
        out_x[row, k] = x_new[rows[k]]
    for i in range(n_charges):
        qdot_history[1, i] = qdot_history[0, i]
        qdot_history[0, i] = qdot[i]
        q_history[0, i] = q[i]
    return toggled


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
            verdict, new_h, order = judge_step(
                real, maxord, si[FIRST], ints[UIC], t, h, order, nh, ht, x_ext, x_prev_ext, sw,
                state, accepted, approach, q, qdot, hq, hi, times, live, zeros,
            )  # fmt: skip
            if verdict == GOOD_STEP:
                break
            si[REJECTED] += 1
            h = new_h
            landing = False
            if verdict == TRUNCATION_REJECTED and h < min_step:
                fail_x[:] = x_new
                fail_prev[:] = x_before
                fs[H] = h
                return STEP_TOO_SMALL_LTE

        # accept
        t = next_break if landing else t + h
        toggled = record_point(
            t, x_new, x_ext, x_prev_ext, port_p, port_n, vd_accepted, state, accepted, ht, hx,
            hq, hi, q, qdot, out_t, out_x, rows, si[COUNT],
        )  # fmt: skip
        finish_step(fs, si, t, new_h, a0, order, landing, toggled, fixed, maxord, nh)
    return FINISHED
