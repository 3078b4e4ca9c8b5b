"""The ports kernel's time loop: transient.py's step control around a Newton on the junction
voltages alone (ports.py).

Breakpoints, order changes, the truncation-error rule, Newton-failure and switch-transition
handling, re-factoring after a new step size has settled: all as compiled/transient.py. The
iterate is the junction (and switch control) voltages; an iteration converges when nothing was
limited or toggled and every junction passes SPICE's voltage and current checks (the other
unknowns are affine in the junction currents: docs/solver.md, "The ports kernel"). Nothing of
size n is formed inside Newton; the recorded unknowns are formed once per accepted point.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from circuitsim.solver.compiled.newton import (
    AT_REFACTOR_TEST,
    AT_SECOND_ATTEMPT,
    ATTEMPTS,
    COUNT,
    FACTOR,
    FACTOR_A0,
    FIRST,
    FIRST_FACTOR,
    IN_ITERATION,
    JUNCTION_NEGLIGIBLE,
    LAST_A0,
    NEWTON,
    NHIST,
    NOT_RESUMING,
    PAUSE_ATTEMPTS,
    REBASE_STEPS,
    REJECTED,
    RESUME_AT,
    RESUME_ATTEMPT,
    RESUME_ITERATION,
    RETRY_RATIO,
    SAME_A0,
    VERSION,
    H,
    T,
    factor_now,
    resumed_step,
    wait_for_factor,
)
from circuitsim.solver.compiled.port_newton import (
    STEP,
    charge_history,
    configuration_stale,
    configure_ports,
    count_active,
    eliminated_ports,
    junction_system,
    junctions_converged,
    linearize_ports,
    port_responses,
    predict,
    relinearized,
    solve_active,
)
from circuitsim.solver.compiled.ports import all_unknowns, unknown
from circuitsim.solver.compiled.slots import (
    ACTIVE_STREAK,
    FIXED_STEP,
    ITL4,
    MAX_STEP,
    MAX_STEPS,
    MAXORD,
    METHOD,
    MIN_STEP,
    NEW_H_MATRIX,
    TSTOP,
    UIC,
    VNTOL,
    Y_VERSION,
)
from circuitsim.solver.compiled.step_control import (
    FINISHED,
    FULL,
    GOOD_STEP,
    NEWTON_FAILED_FIXED,
    PAUSED,
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
from circuitsim.solver.devices.switch_kernel import (
    CONTROL_NEGATIVE,
    CONTROL_POSITIVE,
)


@njit(**STEP)
def refactor_wanted(plan, st, a0):
    """Whether to refactor before the attempt: the step size has settled on an a0 other than
    the factorization's (REBASE_STEPS accepted steps in a row), or the junctions have left the
    conductances factored (a uic start factors all of them at 0 V; then the op-amps' output
    stages settle far from there): each iteration then eliminates many active columns, which a
    refactor makes few. Resets the active streak when it answers yes."""
    floats, counters = st.fs, st.ints
    n_linear, n_ports = plan.lin_slots.size, plan.jp.shape[0] + plan.sw.shape[0]
    ref_a0 = st.fac.ref[n_ports] if n_linear else a0
    settled = a0 != ref_a0 and a0 == floats[LAST_A0] and counters[SAME_A0] >= REBASE_STEPS
    stale = counters[ACTIVE_STREAK] >= REBASE_STEPS
    if (n_linear and settled) or stale:
        counters[ACTIVE_STREAK] = 0
        return True
    return False


@njit(**STEP)
def retry_wanted(plan, st, a0):
    """Whether a failed Newton is retried once on a refactor at a0 (1/s): a0 is this far from
    the factorization's, so the update's round-off, not the step, may be what failed
    (newton.RETRY_RATIO)."""
    n_linear, n_ports = plan.lin_slots.size, plan.jp.shape[0] + plan.sw.shape[0]
    if n_linear == 0:
        return False
    ref_a0 = st.fac.ref[n_ports]
    return not (a0 / RETRY_RATIO < ref_a0 < RETRY_RATIO * a0)


@njit(**STEP)
def converged_charges(plan, st, a0, hist, q, qdot):
    """The linear charges of the converged iterate (their eliminated ports' values) and their
    currents, into q and qdot."""
    linear_slots, p_eliminated = plan.lin_slots, st.p_eliminated
    n_switches = plan.sw.shape[0]
    for k in range(linear_slots.size):
        charge = p_eliminated[n_switches + k]
        q[linear_slots[k]] = charge
        qdot[linear_slots[k]] = a0 * charge + hist[linear_slots[k]]


@njit(**STEP)
def accept_point(plan, st, t, src_values, hist_lin, q, qdot, x_all, record_all):
    """The converged point at t (s) accepted: switch states and control nodes, junction
    voltages, the histories (newest first) and the output row of the recorded unknowns
    (formed all at once when many are recorded: ports.all_unknowns); returns whether a switch
    toggled in the step."""
    counters, fac = st.ints, st.fac
    yc, Yb, Zq, Z, ZT, zrel = fac.yc, fac.Yb, fac.Zq, fac.Z, fac.ZT, fac.zrel
    sw, state, accepted = plan.sw, st.state, st.accepted
    x_ext, x_prev_ext, v_control, control_history = (
        st.x_ext,
        st.x_prev_ext,
        st.v_control,
        st.control_history,
    )
    v_junction, vd_accepted, v_history = st.v_junction, st.vd_accepted, st.v_history
    t_history, q_history, qdot_history = st.t_history, st.q_history, st.qdot_history
    rows, out_t, out_x, current_dev, w = st.rows, st.out_t, st.out_x, st.current_dev, st.w
    n_junctions, n_charges = v_junction.size, q.size
    toggled = False
    for k in range(state.size):
        if state[k] != accepted[k]:
            toggled = True
        accepted[k] = state[k]
        for side in (CONTROL_POSITIVE, CONTROL_NEGATIVE):
            node = sw[k, side]
            if node >= 0:
                x_prev_ext[node] = x_ext[node]
        control_history[1, k] = control_history[0, k]
        control_history[0, k] = v_control[k]
    for k in range(n_junctions):
        vd_accepted[k] = v_junction[k]
        v_history[1, k] = v_history[0, k]
        v_history[0, k] = v_junction[k]
    for j in range(3, 0, -1):
        t_history[j] = t_history[j - 1]
        for i in range(n_charges):
            q_history[j, i] = q_history[j - 1, i]
    t_history[0] = t
    row = counters[COUNT]
    out_t[row] = t
    if record_all:
        all_unknowns(
            x_all, yc, Yb, ZT, src_values, hist_lin, current_dev, w, n_junctions,
            st.y_junctions, st.current_applied, zrel, counters[Y_VERSION] != counters[VERSION],
        )  # fmt: skip
        counters[Y_VERSION] = counters[VERSION]
        for k in range(rows.size):
            out_x[row, k] = x_all[rows[k]]
    else:
        for k in range(rows.size):
            out_x[row, k] = unknown(rows[k], yc, Yb, Zq, Z, src_values, hist_lin, current_dev, w)
    for i in range(n_charges):
        qdot_history[1, i] = qdot_history[0, i]
        qdot_history[0, i] = qdot[i]
        q_history[0, i] = q[i]
    return toggled


@njit(cache=True, nogil=True)
def run(plan, st, t_until):
    """Integrate from st.fs[T] until t_until (or tstop); returns compiled/transient.py's
    status codes, or newton.FACTOR (then re-entered where it stopped, newton.RESUME_AT)."""
    real, ints = plan.real, plan.ints
    method, max_order, max_steps = ints[METHOD], ints[MAXORD], ints[MAX_STEPS]
    fixed, max_step = real[FIXED_STEP], real[MAX_STEP]
    min_step, tstop = real[MIN_STEP], real[TSTOP]
    n_junctions, n_switches = plan.jp.shape[0], plan.sw.shape[0]
    n_charges = st.q_history.shape[1]
    floats, counters, breaks = st.fs, st.ints, plan.breaks
    t_history, q_history, qdot_history = st.t_history, st.q_history, st.qdot_history
    x_ext, x_prev_ext, state, accepted = st.x_ext, st.x_prev_ext, st.state, st.accepted
    sw, approach, itl4 = plan.sw, plan.approach, ints[ITL4]
    linear = n_junctions == 0 and n_switches == 0
    record_all = st.rows.size * 4 > st.fac.yc.size  # many recorded: ports.all_unknowns
    x_all = np.empty(st.fac.yc.size)
    src_kind, src_par, src_dc = plan.src_kind, plan.src_par, plan.src_dc
    pwl_start, pwl_t, pwl_v = plan.pwl_start, plan.pwl_t, plan.pwl_v
    n_sources = src_kind.size
    src_values = np.empty(n_sources)
    hist = np.empty(n_charges)
    hist_lin = np.empty(plan.lin_slots.size)
    q = np.zeros(n_charges)
    qdot = np.zeros(n_charges)
    times = np.empty(4)
    live, zeros = charge_slots(n_charges, plan.jslot, plan.charged, plan.has_charge)
    negligible_v = JUNCTION_NEGLIGIBLE * real[VNTOL]
    last_active = 0  # active junctions in the last Newton iteration
    resume = counters[RESUME_AT]  # back from a factorization made in Python: where the step was
    counters[RESUME_AT] = NOT_RESUMING
    if resume == FIRST_FACTOR:
        resume = NOT_RESUMING
        if not factor_now(plan, st, floats[FACTOR_A0]):
            return FACTOR  # then re-entered at the first step
    while tstop - floats[T] > min_step:
        if resume != NOT_RESUMING:
            t, next_break, h, order, landing = resumed_step(floats, counters, breaks)
        else:
            if floats[T] >= t_until:  # a tenth of the run, in model time: a fixed point
                # where the caches updated in place (H ieq, the recorded unknowns' junction
                # part) are formed anew, so that their round-off drift stays bounded
                counters[NEW_H_MATRIX] = 1
                counters[Y_VERSION] = -1
                return PAUSED
            if counters[ATTEMPTS] >= counters[PAUSE_ATTEMPTS]:
                return PAUSED  # for the wall clock (machine-dependent): changes nothing
            if counters[COUNT] >= st.out_t.size:
                return FULL
            t, next_break, h, order, landing = step_start(
                floats, counters, breaks, fixed, max_step, min_step
            )
        n_history = counters[NHIST]
        while True:
            if resume == NOT_RESUMING:
                counters[ATTEMPTS] += 1
            if counters[ATTEMPTS] > max_steps:
                floats[H] = h
                return TOO_MANY_STEPS
            h_prev = t_history[0] - t_history[1] if n_history > 1 else h
            a0, a1, a2, b1 = coefficients(method, order, h, h_prev)
            charge_history(plan, st, a1, a2, b1, hist, hist_lin)
            if resume == NOT_RESUMING and refactor_wanted(plan, st, a0):
                if not factor_now(plan, st, a0):
                    return wait_for_factor(floats, counters, AT_REFACTOR_TEST, h, order,
                                           landing, 0, 0, 0)  # fmt: skip
            if resume == AT_REFACTOR_TEST:
                resume = NOT_RESUMING
            for k in range(n_sources):  # (np.interp allocates: not in a step of port_newton)
                src_values[k] = source_value(
                    t + h, k, src_kind, src_par, src_dc, pwl_start, pwl_t, pwl_v
                )
            ratio = h / h_prev if n_history > 1 else 0.0
            ok = False
            first_attempt = counters[RESUME_ATTEMPT] if resume != NOT_RESUMING else 0
            if resume == AT_SECOND_ATTEMPT:
                resume = NOT_RESUMING
            for attempt in range(first_attempt, 2):
                predict(st, ratio, q, qdot, resume == NOT_RESUMING)  # else IN_ITERATION
                # Newton at this time point (port_newton.py)
                ok = False
                iterations = 0
                fresh = True  # the time point's responses are to be (re)computed
                first_iteration = counters[RESUME_ITERATION] if resume == IN_ITERATION else 1
                for iteration in range(first_iteration, itl4 + 1):
                    iterations = iteration
                    again_from = 1 if resume == IN_ITERATION else 0
                    if resume == IN_ITERATION:  # linearized before the factorization
                        noncon = relinearized(plan, st, a0, hist, q, qdot)
                    else:
                        noncon = linearize_ports(plan, st, iteration == 1, a0, hist, q, qdot)
                    resume = NOT_RESUMING
                    solved = False
                    for again in range(again_from, 2):  # the second on a refactor here
                        stale = configuration_stale(st, a0)
                        if not stale or configure_ports(plan, st, a0):  # else singular
                            if stale or fresh:
                                port_responses(st, src_values, hist_lin)
                                fresh = False
                            last_active = junction_system(st, negligible_v)
                            solved = solve_active(st, last_active)
                        if solved or again == 1:
                            break
                        if not factor_now(plan, st, a0):
                            return wait_for_factor(floats, counters, IN_ITERATION, h, order,
                                                   landing, attempt, iteration, noncon)  # fmt: skip
                    if not solved:
                        break
                    eliminated_ports(plan, st, src_values, hist_lin)
                    if junctions_converged(plan, st, noncon == 0 and (iteration > 1 or linear)):
                        ok = True
                        break
                counters[NEWTON] += iterations
                if ok or attempt == 1 or not retry_wanted(plan, st, a0):
                    break
                if not factor_now(plan, st, a0):
                    return wait_for_factor(floats, counters, AT_SECOND_ATTEMPT, h, order,
                                           landing, 1, 0, 0)  # fmt: skip
            if not ok:
                counters[REJECTED] += 1
                floats[H] = h
                if fixed > 0:
                    return NEWTON_FAILED_FIXED
                h /= 8
                order = 1
                landing = False
                if h < min_step:
                    floats[H] = h
                    return STEP_TOO_SMALL
                continue
            converged_charges(plan, st, a0, hist, q, qdot)
            verdict, new_h, order = judge_step(
                real, max_order, counters[FIRST], ints[UIC], t, h, order, n_history, t_history,
                x_ext, x_prev_ext, sw, state, accepted, approach, q, qdot, q_history,
                qdot_history, times, live, zeros,
            )  # fmt: skip
            if verdict == GOOD_STEP:
                break
            counters[REJECTED] += 1
            h = new_h
            landing = False
            if verdict == TRUNCATION_REJECTED and h < min_step:
                floats[H] = h
                return STEP_TOO_SMALL_LTE

        count_active(counters, last_active)
        t = next_break if landing else t + h
        toggled = accept_point(plan, st, t, src_values, hist_lin, q, qdot, x_all, record_all)
        finish_step(
            floats, counters, t, new_h, a0, order, landing, toggled, fixed, max_order, n_history
        )
    return FINISHED
