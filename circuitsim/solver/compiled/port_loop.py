"""The ports kernel's time loop: transient.py's step control around a Newton on the junction
voltages alone (port_newton.py, on ports.py's factorization).

Breakpoints, order changes, the truncation-error rule, Newton-failure and switch-transition
handling, re-factoring after a new step size has settled: all as compiled/transient.py. What
differs is Newton's unknowns and its convergence test (port_newton.py). The recorded unknowns
are formed once per accepted point.

The steps (``refactor_wanted``, ``port_newton.newton_at``, ``judge_step``, ``accept``) are
compiled without numba's reference counting and inlined by LLVM (``_nrt=False``,
``forceinline=True``): they allocate nothing, and ``run`` holds every array they read. So
they cost nothing over a loop written out in one function (docs/solver.md, "The ports
kernel's loop in named steps").
"""

from __future__ import annotations

import numpy as np
from numba import njit

from circuitsim.solver.compiled.newton import (
    AFTER_REFACTOR,
    AT_REFACTOR_TEST,
    AT_SECOND_ATTEMPT,
    ATTEMPTS,
    COUNT,
    FACTOR,
    FACTOR_A0,
    FIRST,
    FIRST_FACTOR,
    IN_ITERATION,
    LAST_A0,
    MEASURED_VERSION,
    NEWTON,
    NHIST,
    NOT_RESUMING,
    PAUSE_ATTEMPTS,
    REJECTED,
    RESUME_AT,
    RESUME_ATTEMPT,
    RESUME_ITERATION,
    RESUME_NONCON,
    SAME_A0,
    VERSION,
    H,
    T,
    factor_now,
    rebase_wanted,
    resumed_step,
    wait_for_factor,
)
from circuitsim.solver.compiled.port_newton import CONVERGED, NOT_CONVERGED, REFACTOR, newton_at
from circuitsim.solver.compiled.ports import all_unknowns, unknown
from circuitsim.solver.compiled.slots import (
    ACTIVE_STREAK,
    FIXED_STEP,
    MAX_STEP,
    MAX_STEPS,
    MAXORD,
    METHOD,
    MIN_STEP,
    NEW_H_MATRIX,
    TSTOP,
    UIC,
    Y_VERSION,
)
from circuitsim.solver.compiled.transient import (
    FINISHED,
    FULL,
    NEWTON_FAILED_FIXED,
    PAUSED,
    REBASE_STEPS,
    RETRY_RATIO,
    STEP_TOO_SMALL,
    STEP_TOO_SMALL_LTE,
    TOO_MANY_STEPS,
    charge_slots,
    coefficients,
    finish_step,
    next_step,
    step_start,
    truncation_step,
    zero_charge_step,
)
from circuitsim.solver.devices.source_kernel import source_value
from circuitsim.solver.devices.switch_kernel import (
    CONTROL_NEGATIVE,
    CONTROL_POSITIVE,
    switch_transition,
    switch_truncate,
    transition_retry,
)

# judge_step's verdicts on a converged step
ACCEPTED, CUT_AT_TRANSITION, TRUNCATION_REJECTED = 0, 1, 2


@njit(cache=True, nogil=True)
def run(plan, st, t_until):
    """Integrate from st.fs[T] until t_until (or tstop); returns compiled/transient.py's
    status codes, or newton.FACTOR (then re-entered where it stopped, newton.RESUME_AT)."""
    real, ints = plan.real, plan.ints
    method, max_order, max_steps = ints[METHOD], ints[MAXORD], ints[MAX_STEPS]
    fixed, max_step = real[FIXED_STEP], real[MAX_STEP]
    min_step, tstop = real[MIN_STEP], real[TSTOP]
    n_junctions, n_switches = plan.jp.shape[0], plan.sw.shape[0]
    n_ports = n_junctions + n_switches
    linear_slots = plan.lin_slots
    n_linear = linear_slots.size
    n_charges = st.q_history.shape[1]
    floats, counters, breaks = st.fs, st.ints, plan.breaks
    t_history, q_history, qdot_history = st.t_history, st.q_history, st.qdot_history
    v_history, control_history = st.v_history, st.control_history
    v_junction, v_control, out_t = st.v_junction, st.v_control, st.out_t
    ref = st.fac.ref  # the factorization is rebuilt in place
    src_kind, src_par, src_dc = plan.src_kind, plan.src_par, plan.src_dc
    pwl_start, pwl_t, pwl_v = plan.pwl_start, plan.pwl_t, plan.pwl_v
    src_values = np.empty(src_kind.size)
    hist = np.empty(n_charges)
    hist_lin = np.empty(n_linear)
    q = np.zeros(n_charges)
    qdot = np.zeros(n_charges)
    times = np.empty(4)
    live, zeros = charge_slots(n_charges, plan.jslot, plan.charged, plan.has_charge)
    # many recorded unknowns: form them all column by column (ports.all_unknowns)
    record_all = st.rows.size * 4 > st.fac.yc.size
    x_all = np.empty(st.fac.yc.size)
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
            if counters[COUNT] >= out_t.size:
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
            for k in range(n_charges):
                hist[k] = a1 * q_history[0, k] + b1 * qdot_history[0, k] + a2 * q_history[1, k]
            for k in range(n_linear):
                hist_lin[k] = hist[linear_slots[k]]
            if resume == NOT_RESUMING and refactor_wanted(
                floats, counters, ref, n_ports, n_linear, a0
            ):
                counters[ACTIVE_STREAK] = 0
                if not factor_now(plan, st, a0):
                    return wait_for_factor(
                        floats, counters, AT_REFACTOR_TEST, h, order, landing, 0, 0, 0
                    )
            if resume == AT_REFACTOR_TEST:
                resume = NOT_RESUMING
            for k in range(src_kind.size):
                src_values[k] = source_value(
                    t + h, k, src_kind, src_par, src_dc, pwl_start, pwl_t, pwl_v
                )
            ratio = h / h_prev if n_history > 1 else 0.0
            outcome = NOT_CONVERGED
            first_attempt = counters[RESUME_ATTEMPT] if resume != NOT_RESUMING else 0
            if resume == AT_SECOND_ATTEMPT:
                resume = NOT_RESUMING
            for attempt in range(first_attempt, 2):
                if resume == NOT_RESUMING:
                    predict(v_history, control_history, ratio, v_junction, v_control)
                for k in range(n_charges):
                    q[k] = 0.0
                    qdot[k] = 0.0
                resumed = (0, 0)  # or the iteration (and its nonconverged count) to go on from
                if resume == IN_ITERATION:
                    resumed = (counters[RESUME_ITERATION], counters[RESUME_NONCON])
                resume = NOT_RESUMING
                while True:
                    outcome, iterations, noncon, last_active = newton_at(
                        plan, st, a0, hist, hist_lin, src_values, q, qdot, resumed, last_active
                    )
                    if outcome != REFACTOR:
                        break
                    if not factor_now(plan, st, a0):
                        return wait_for_factor(
                            floats, counters, IN_ITERATION, h, order, landing, attempt,
                            iterations, noncon,
                        )  # fmt: skip
                    resumed = (iterations, noncon)
                counters[NEWTON] += iterations
                # the update's round-off, not the step, may be what failed (RETRY_RATIO)
                far = n_linear and not (a0 / RETRY_RATIO < ref[n_ports] < RETRY_RATIO * a0)
                if outcome == CONVERGED or attempt == 1 or not far:
                    break
                if not factor_now(plan, st, a0):
                    return wait_for_factor(
                        floats, counters, AT_SECOND_ATTEMPT, h, order, landing, 1, 0, 0
                    )
            if outcome != CONVERGED:
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
            verdict, new_h, order = judge_step(
                plan, st, t, h, order, n_history, a0, hist, q, qdot, times, live, zeros
            )
            if verdict != ACCEPTED:
                counters[REJECTED] += 1
                h = new_h
                landing = False
                if verdict == TRUNCATION_REJECTED and h < min_step:
                    floats[H] = h
                    return STEP_TOO_SMALL_LTE
                continue
            break

        t = next_break if landing else t + h
        toggled = accept(plan, st, t, q, qdot, src_values, hist_lin, record_all, x_all, last_active)
        finish_step(
            floats, counters, t, new_h, a0, order, landing, toggled, fixed, max_order, n_history
        )
    return FINISHED


@njit(cache=True, _nrt=False, forceinline=True)
def refactor_wanted(fs, counters, ref, n_ports, n_linear, a0):
    """Whether to refactor before a step at a0 (1/s): the linear charges' a0 has settled at a
    value other than the factored one, or the junctions have left the conductances factored
    (a uic start factors all of them at 0 V; then the op-amps' output stages settle far from
    there): each iteration then eliminates many active columns, which a refactor makes few."""
    ref_a0 = ref[n_ports] if n_linear else a0
    settled = a0 != ref_a0 and a0 == fs[LAST_A0] and counters[SAME_A0] >= REBASE_STEPS
    stale = counters[ACTIVE_STREAK] >= REBASE_STEPS
    return (n_linear > 0 and settled) or stale


@njit(cache=True)
def predict(v_history, control_history, ratio, v_junction, v_control):
    """The Newton iterate's start: the junction and control voltages (V) extrapolated from
    the last two accepted points (``ratio``: this step over the last one; 0 at the start)."""
    for k in range(v_junction.size):
        v_junction[k] = v_history[0, k] + ratio * (v_history[0, k] - v_history[1, k])
    for k in range(v_control.size):
        v_control[k] = control_history[0, k] + ratio * (
            control_history[0, k] - control_history[1, k]
        )


@njit(cache=True, _nrt=False, forceinline=True)
def judge_step(plan, st, t, h, order, n_history, a0, hist, q, qdot, times, live, zeros):
    """A step to t + h (s) whose Newton converged, judged: the linear charges into q and
    qdot, then the switches' transitions (devices/switch.py) and the truncation error
    (solver/transient.py's rules). Returns (ACCEPTED, the next step proposed, order), or
    (CUT_AT_TRANSITION or TRUNCATION_REJECTED, the step to retry, order). Without numba's
    reference counting, as port_newton.newton_at."""
    real, ints, counters, linear_slots = plan.real, plan.ints, st.ints, plan.lin_slots
    sw, approach, accepted = plan.sw, plan.approach, st.accepted
    x_ext, x_prev_ext, t_history = st.x_ext, st.x_prev_ext, st.t_history
    fixed, n_switches = real[FIXED_STEP], sw.shape[0]
    for k in range(linear_slots.size):
        charge = st.p_eliminated[n_switches + k]
        q[linear_slots[k]] = charge
        qdot[linear_slots[k]] = a0 * charge + hist[linear_slots[k]]
    transition = False
    if fixed == 0 and n_switches and not (ints[UIC] and counters[FIRST]):  # uic: transient.py
        fraction = switch_transition(x_ext, x_prev_ext, sw, st.state, accepted, approach)
        retry = transition_retry(
            fraction, h, t_history[0] - t_history[1] if n_history > 1 else h, real[MIN_STEP]
        )
        if retry > 0:  # cut short of the crossing, then just past it (devices/switch.py)
            return CUT_AT_TRANSITION, retry, order
        transition = fraction < 1.0
    new_h = h if fixed > 0 else 2 * h
    if fixed == 0 and not counters[FIRST]:
        times[0] = t + h
        for k in range(3):
            times[k + 1] = t_history[k]
        n_points = n_history + 1
        max_order = ints[MAXORD]
        charges = charges2 = switches = np.inf
        if n_points >= order + 2 and q.size:
            charges = truncation_step(
                real, order, times, q, qdot, st.q_history, st.qdot_history, live
            )
            if zeros:
                charges = min(charges, zero_charge_step(real, order, times[0] - times[1]))
        if order == 1 and max_order > 1 and n_points >= 4 and q.size:
            charges2 = truncation_step(real, 2, times, q, qdot, st.q_history, st.qdot_history, live)
            if zeros:
                charges2 = min(charges2, zero_charge_step(real, 2, times[0] - times[1]))
        if n_switches:
            switches = switch_truncate(x_ext, x_prev_ext, h, sw, accepted, approach)
        new_h, order, good = next_step(
            real, max_order, n_points, order, h, transition, charges, charges2, switches
        )
        if not good:
            return TRUNCATION_REJECTED, new_h, order
    return ACCEPTED, new_h, order


@njit(cache=True, _nrt=False, forceinline=True)
def accept(plan, st, t, q, qdot, src_values, hist_lin, record_all, x_all, last_active):
    """The converged point at t (s) accepted: the streak of steps with many active junctions
    (``last_active`` in the last iteration; newton.rebase_wanted), switch states, histories,
    the recorded row (all unknowns formed column by column when ``record_all``); returns
    whether a switch toggled in the step."""
    counters, sw, fac = st.ints, plan.sw, st.fac
    state, accepted, x_ext, x_prev_ext = st.state, st.accepted, st.x_ext, st.x_prev_ext
    control_history, v_history, v_junction = st.control_history, st.v_history, st.v_junction
    t_history, q_history, qdot_history = st.t_history, st.q_history, st.qdot_history
    rows, out_x, current_dev, w = st.rows, st.out_x, st.current_dev, st.w
    if counters[VERSION] != counters[MEASURED_VERSION]:  # the first step on a new refactor
        counters[AFTER_REFACTOR] = last_active
        counters[MEASURED_VERSION] = counters[VERSION]
    if rebase_wanted(last_active, counters[AFTER_REFACTOR]):
        counters[ACTIVE_STREAK] += 1
    else:
        counters[ACTIVE_STREAK] = 0
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
        control_history[0, k] = st.v_control[k]
    for k in range(v_junction.size):
        st.vd_accepted[k] = v_junction[k]
        v_history[1, k] = v_history[0, k]
        v_history[0, k] = v_junction[k]
    for j in range(3, 0, -1):
        t_history[j] = t_history[j - 1]
        for i in range(q.size):
            q_history[j, i] = q_history[j - 1, i]
    t_history[0] = t
    row = counters[COUNT]
    st.out_t[row] = t
    if record_all:
        all_unknowns(
            x_all, fac.yc, fac.Yb, fac.ZT, src_values, hist_lin, current_dev, w,
            v_junction.size, st.y_junctions, st.current_applied, fac.zrel,
            counters[Y_VERSION] != counters[VERSION],
        )  # fmt: skip
        counters[Y_VERSION] = counters[VERSION]
        for k in range(rows.size):
            out_x[row, k] = x_all[rows[k]]
    else:
        for k in range(rows.size):
            out_x[row, k] = unknown(
                rows[k], fac.yc, fac.Yb, fac.Zq, fac.Z, src_values, hist_lin, current_dev, w
            )
    for i in range(q.size):
        qdot_history[1, i] = qdot_history[0, i]
        qdot_history[0, i] = qdot[i]
        q_history[0, i] = q[i]
    return toggled
