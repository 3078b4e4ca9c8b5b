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

from circuitsim.solver.compiled.lowrank import NEGLIGIBLE
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
    JUNCTION_NEGLIGIBLE,
    LAST_A0,
    MEASURED_VERSION,
    NEWTON,
    NHIST,
    NOT_RESUMING,
    PAUSE_ATTEMPTS,
    REBASE_STEPS,
    REJECTED,
    RESUME_AT,
    RESUME_ATTEMPT,
    RESUME_ITERATION,
    RESUME_NONCON,
    RETRY_RATIO,
    SAME_A0,
    VERSION,
    H,
    T,
    factor_now,
    junction_charges,
    rebase_wanted,
    resumed_step,
    wait_for_factor,
)
from circuitsim.solver.compiled.ports import (
    all_unknowns,
    configure,
    h_column,
    unknown,
)
from circuitsim.solver.compiled.slots import (
    ABSTOL,
    ACTIVE_STREAK,
    CFG_A0,
    CFG_COUNT,
    CFG_STALE,
    CFG_VERSION,
    FIXED_STEP,
    ITL4,
    MAX_STEP,
    MAX_STEPS,
    MAXORD,
    METHOD,
    MIN_STEP,
    NEW_H_MATRIX,
    RELTOL,
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
from circuitsim.solver.devices.diode_kernel import linearize_junction
from circuitsim.solver.devices.source_kernel import source_value
from circuitsim.solver.devices.switch_kernel import (
    CONTROL_NEGATIVE,
    CONTROL_POSITIVE,
    G_OFF,
    G_ON,
    OFF_BELOW,
    ON_ABOVE,
    next_state,
)


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
    floats, counters = st.fs, st.ints
    breaks = plan.breaks
    t_history, q_history, qdot_history = st.t_history, st.q_history, st.qdot_history
    v_history, control_history = st.v_history, st.control_history
    x_ext, x_prev_ext, state, accepted = st.x_ext, st.x_prev_ext, st.state, st.accepted
    vd_accepted, v_junction = st.vd_accepted, st.v_junction
    v_control, p_eliminated = st.v_control, st.p_eliminated
    sw, approach = plan.sw, plan.approach
    rows, out_t, out_x, fail_v = st.rows, st.out_t, st.out_x, st.fail_v
    # every array taken out of the tuples once (the factorization is rebuilt in place)
    fac = st.fac
    ref, K, cc, Cb, Kq = fac.ref, fac.K, fac.cc, fac.Cb, fac.Kq
    yc, Yb, Zq, Z = fac.yc, fac.Yb, fac.Zq, fac.Z
    vd, cd, gd, ieq, v_new, dg = st.vd, st.cd, st.gd, st.ieq, st.v_new, st.dg
    d_eliminated, F, G, h_matrix = st.d_eliminated, st.F, st.G, st.H
    bound, formed_at = st.bound, st.formed_at
    scratch, scratch2 = st.scratch, st.scratch2
    c0, e0, Fc0, A, b, current_dev, w = st.c0, st.e0, st.Fc0, st.A, st.b, st.current_dev, st.w
    h_max, h_ieq, ieq_applied = st.h_max, st.h_ieq, st.ieq_applied
    active, x_active = st.active, st.x_active
    # many recorded unknowns: form them all column by column (ports.all_unknowns)
    record_all = rows.size * 4 > fac.yc.size
    ZT, zrel = fac.ZT, fac.zrel
    x_all = np.empty(fac.yc.size)
    # kept in the state, so that a return to Python (a pause) changes nothing
    y_junctions, current_applied = st.y_junctions, st.current_applied
    reltol, abstol, vntol = real[RELTOL], real[ABSTOL], real[VNTOL]
    itl4 = ints[ITL4]
    jp, cp, jslot, has_charge, charged = plan.jp, plan.cp, plan.jslot, plan.has_charge, plan.charged
    g_switch = plan.g_switch
    linear = n_junctions == 0 and n_switches == 0
    src_kind, src_par, src_dc = plan.src_kind, plan.src_par, plan.src_dc
    pwl_start, pwl_t, pwl_v = plan.pwl_start, plan.pwl_t, plan.pwl_v
    n_sources = src_kind.size
    n_eliminated = n_switches + n_linear
    n_all_ports = n_junctions + n_eliminated
    src_values = np.empty(n_sources)
    hist = np.empty(n_charges)
    hist_lin = np.empty(n_linear)
    q = np.zeros(n_charges)
    qdot = np.zeros(n_charges)
    times = np.empty(4)
    live, zeros = charge_slots(n_charges, jslot, charged, has_charge)
    negligible_v = JUNCTION_NEGLIGIBLE * vntol
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
            ref_a0 = ref[n_ports] if n_linear else a0
            settled = a0 != ref_a0 and a0 == floats[LAST_A0] and counters[SAME_A0] >= REBASE_STEPS
            # or the junctions have left the conductances factored (a uic start factors all
            # of them at 0 V; then the op-amps' output stages settle far from there): each
            # iteration then eliminates many active columns, which a refactor makes few
            stale = counters[ACTIVE_STREAK] >= REBASE_STEPS
            if resume == NOT_RESUMING and ((n_linear and settled) or stale):
                counters[ACTIVE_STREAK] = 0
                if not factor_now(plan, st, a0):
                    return wait_for_factor(
                        floats, counters, AT_REFACTOR_TEST, h, order, landing, 0, 0, 0
                    )
            if resume == AT_REFACTOR_TEST:
                resume = NOT_RESUMING
            for k in range(n_sources):
                src_values[k] = source_value(
                    t + h, k, src_kind, src_par, src_dc, pwl_start, pwl_t, pwl_v
                )
            ratio = h / h_prev if n_history > 1 else 0.0
            ok = False
            first_attempt = counters[RESUME_ATTEMPT] if resume != NOT_RESUMING else 0
            if resume == AT_SECOND_ATTEMPT:
                resume = NOT_RESUMING
            for attempt in range(first_attempt, 2):
                for k in range(n_junctions if resume == NOT_RESUMING else 0):  # the predictor
                    v_junction[k] = v_history[0, k] + ratio * (v_history[0, k] - v_history[1, k])
                for k in range(n_switches if resume == NOT_RESUMING else 0):
                    v_control[k] = control_history[0, k] + ratio * (
                        control_history[0, k] - control_history[1, k]
                    )
                for k in range(n_charges):
                    q[k] = 0.0
                    qdot[k] = 0.0
                # Newton at this time point, written out rather than called (reference counts:
                # docs/solver.md, "A numba detail that shaped both loops")
                ok = False
                iterations = 0
                fresh = True  # the time point's responses are to be (re)computed
                first_iteration = counters[RESUME_ITERATION] if resume == IN_ITERATION else 1
                for iteration in range(first_iteration, itl4 + 1):
                    iterations = iteration
                    first = iteration == 1
                    noncon = 0
                    first_again = 0
                    if resume == IN_ITERATION:  # linearized before the factorization
                        noncon = counters[RESUME_NONCON]
                        junction_charges(vd, a0, hist, jp, cp, jslot, has_charge, charged, q, qdot)
                        first_again = 1
                    for k in range(n_switches if resume == NOT_RESUMING else 0):  # update_state
                        keep = accepted[k] if first else state[k]
                        new = next_state(
                            v_control[k], keep, approach[k, ON_ABOVE], approach[k, OFF_BELOW]
                        )
                        if new != state[k]:
                            state[k] = new
                            noncon += 1
                            counters[CFG_STALE] = 1
                    for k in range(
                        n_junctions if resume == NOT_RESUMING else 0
                    ):  # DiodeFamily.port_load
                        charged_k = has_charge and charged[k]
                        slot = jslot[k]
                        v, limited, current, conductance, charge, charge_current = (
                            linearize_junction(
                                jp, cp, k, v_junction[k], vd_accepted[k] if first else vd[k],
                                charged_k, a0, hist[slot] if charged_k else 0.0,
                            )
                        )  # fmt: skip
                        noncon += limited
                        if charged_k:
                            q[slot] = charge
                            qdot[slot] = charge_current
                        vd[k], cd[k], gd[k] = v, current, conductance
                        ieq[k] = current - conductance * v
                    resume = NOT_RESUMING
                    solved = False
                    for again in range(first_again, 2):  # the second on a refactor here
                        if (
                            counters[CFG_STALE] == 1
                            or counters[CFG_VERSION] != counters[VERSION]
                            or floats[CFG_A0] != a0
                        ):
                            # eliminate the switch and charge ports at a0 and the switch states
                            for k in range(n_switches):
                                on = g_switch[k, G_ON] if state[k] else g_switch[k, G_OFF]
                                d_eliminated[k] = on - ref[n_junctions + k]
                            for k in range(n_switches, d_eliminated.size):
                                d_eliminated[k] = a0 - ref[n_junctions + k]
                            if not configure(K, n_junctions, d_eliminated, F, G, bound):
                                if again == 1:
                                    break
                                if not factor_now(plan, st, a0):
                                    return wait_for_factor(
                                        floats, counters, IN_ITERATION, h, order, landing, attempt,
                                        iteration, noncon,
                                    )  # fmt: skip
                                continue
                            floats[CFG_A0] = a0
                            counters[CFG_VERSION] = counters[VERSION]
                            counters[CFG_STALE] = 0
                            counters[CFG_COUNT] += 1  # every column of H to be formed anew
                            fresh = True
                            counters[NEW_H_MATRIX] = 1
                        if fresh:  # the time point's port responses (ports.py: c0, e0, F c0_R)
                            for i in range(n_all_ports):
                                acc = cc[i]
                                for k in range(n_sources):
                                    acc += Cb[i, k] * src_values[k]
                                for k in range(n_linear):
                                    acc -= Kq[i, k] * hist_lin[k]
                                c0[i] = acc
                            for i in range(n_eliminated):  # tr = G c0_R, Fc0 = F c0_R
                                acc = 0.0
                                acc2 = 0.0
                                for k in range(n_eliminated):
                                    acc += G[i, k] * c0[n_junctions + k]
                                    acc2 += F[i, k] * c0[n_junctions + k]
                                scratch[i] = acc
                                Fc0[i] = acc2
                            for i in range(n_junctions):  # e0 = c0_J - K_JR G c0_R
                                acc = c0[i]
                                for k in range(n_eliminated):
                                    acc -= K[i, n_junctions + k] * scratch[k]
                                e0[i] = acc
                            fresh = False
                        for k in range(n_junctions):
                            dg[k] = gd[k] - ref[k]
                        # (I + H D_J) p_J = e0 - H ieq, for the *active* junctions only: those
                        # whose conductance change moves the solution, |dJ_k| max_i |H_ik| >
                        # NEGLIGIBLE (as lowrank.active_columns). The others' columns of
                        # I + H D_J are unit columns to round-off (an op-amp macromodel's clamp
                        # diodes, far in reverse, keep their factorization's conductance), so
                        # their p follows by one product. H ieq is kept up to date by the
                        # columns whose companion current changed (by more than negligibly,
                        # below). (Written out, not called: see the Newton comment above.)
                        count = counters[CFG_COUNT]
                        # H changed: H ieq = K_JJ ieq - K_JR G (K_RJ ieq) in full, no H formed
                        if counters[NEW_H_MATRIX] == 1:
                            for s in range(n_eliminated):
                                acc = 0.0
                                for k in range(n_junctions):
                                    acc += K[n_junctions + s, k] * ieq[k]
                                scratch2[s] = acc
                            for s in range(n_eliminated):
                                acc = 0.0
                                for p in range(n_eliminated):
                                    acc += G[s, p] * scratch2[p]
                                scratch[s] = acc
                            for i in range(n_junctions):
                                acc = 0.0
                                for k in range(n_junctions):
                                    acc += K[i, k] * ieq[k]
                                for s in range(n_eliminated):
                                    acc -= K[i, n_junctions + s] * scratch[s]
                                h_ieq[i] = acc
                            for k in range(n_junctions):
                                ieq_applied[k] = ieq[k]
                            counters[NEW_H_MATRIX] = 0
                        # A change that moves no junction voltage by more than
                        # JUNCTION_NEGLIGIBLE vntol (bound: max_i |H_ik| or more) waits until it
                        # grows, as in newton.junction_response: the companion currents of clamp
                        # diodes far in reverse change by round-off at every iteration (42 of the
                        # TL074 wheelset's 56; applying them took a third of its step).
                        for k in range(n_junctions):
                            change = ieq[k] - ieq_applied[k]
                            if change != 0.0 and abs(change) * bound[k] > negligible_v:
                                if formed_at[k] != count:
                                    h_column(K, G, n_junctions, k, h_matrix, h_max, scratch)
                                    formed_at[k] = count
                                for i in range(n_junctions):
                                    h_ieq[i] += h_matrix[i, k] * change
                                ieq_applied[k] = ieq[k]
                        m = 0
                        for k in range(n_junctions):
                            if dg[k] != 0.0 and abs(dg[k]) * bound[k] > NEGLIGIBLE:
                                if formed_at[k] != count:
                                    h_column(K, G, n_junctions, k, h_matrix, h_max, scratch)
                                    formed_at[k] = count
                                if abs(dg[k]) * h_max[k] > NEGLIGIBLE:
                                    active[m] = k
                                    m += 1
                        last_active = m
                        for a in range(m):
                            i = active[a]
                            for c in range(m):
                                A[a, c] = h_matrix[i, active[c]] * dg[active[c]]
                            A[a, a] += 1.0
                            b[a] = e0[i] - h_ieq[i]
                        # A xa = b (m x m, partial pivoting), written out as well
                        solved = True
                        for k in range(m):
                            pivot_row = k
                            big = abs(A[k, k])
                            for i in range(k + 1, m):
                                if abs(A[i, k]) > big:
                                    big = abs(A[i, k])
                                    pivot_row = i
                            if big == 0.0:
                                solved = False
                                break
                            if pivot_row != k:
                                for c in range(m):
                                    A[k, c], A[pivot_row, c] = A[pivot_row, c], A[k, c]
                                b[k], b[pivot_row] = b[pivot_row], b[k]
                            pivot = A[k, k]
                            for i in range(k + 1, m):
                                f = A[i, k] / pivot
                                for c in range(k + 1, m):
                                    A[i, c] -= f * A[k, c]
                                b[i] -= f * b[k]
                        if solved:
                            for k in range(m - 1, -1, -1):
                                acc = b[k]
                                for c in range(k + 1, m):
                                    acc -= A[k, c] * x_active[c]
                                x_active[k] = acc / A[k, k]
                                if not np.isfinite(x_active[k]):
                                    solved = False
                        if solved:
                            for i in range(n_junctions):
                                acc = e0[i] - h_ieq[i]
                                for c in range(m):
                                    acc -= h_matrix[i, active[c]] * dg[active[c]] * x_active[c]
                                v_new[i] = acc
                            for c in range(m):
                                v_new[active[c]] = x_active[c]
                        if solved or again == 1:
                            break
                        if not factor_now(plan, st, a0):
                            return wait_for_factor(
                                floats, counters, IN_ITERATION, h, order, landing, attempt,
                                iteration, noncon,
                            )  # fmt: skip
                    if not solved:
                        break
                    # j = ieq + D_J p_J, p_R = F c0_R - F K_RJ j, w = D_R p_R (ports.py)
                    for k in range(n_junctions):
                        current_dev[k] = ieq[k] + dg[k] * v_new[k]
                    for s in range(n_eliminated):  # tr = K_RJ j
                        acc = 0.0
                        for k in range(n_junctions):
                            acc += K[n_junctions + s, k] * current_dev[k]
                        scratch[s] = acc
                    for i in range(n_eliminated):
                        acc = Fc0[i]
                        for k in range(n_eliminated):
                            acc -= F[i, k] * scratch[k]
                        p_eliminated[i] = acc
                        w[i] = d_eliminated[i] * acc
                    for k in range(n_switches):  # the control nodes of this iterate
                        for side in (CONTROL_POSITIVE, CONTROL_NEGATIVE):
                            node = sw[k, side]
                            if node >= 0:
                                x_ext[node] = unknown(
                                    node, yc, Yb, Zq, Z, src_values, hist_lin, current_dev, w
                                )
                        v_control[k] = (
                            x_ext[sw[k, CONTROL_POSITIVE]] - x_ext[sw[k, CONTROL_NEGATIVE]]
                        )
                    done = noncon == 0 and (iteration > 1 or linear)
                    for k in range(n_junctions if done else 0):
                        change = abs(v_new[k] - v_junction[k])
                        if change > reltol * max(abs(v_new[k]), abs(v_junction[k])) + vntol:
                            done = False
                            break
                    for k in range(n_junctions if done else 0):  # DiodeFamily.port_converged
                        delta = gd[k] * (v_new[k] - vd[k])
                        if abs(delta) > reltol * max(abs(cd[k] + delta), abs(cd[k])) + abstol:
                            done = False
                            break
                    for k in range(n_junctions):
                        fail_v[0, k] = v_new[k]
                        fail_v[1, k] = v_junction[k]
                        v_junction[k] = v_new[k]
                    if done:
                        ok = True
                        break
                counters[NEWTON] += iterations
                # the update's round-off, not the step, may be what failed (RETRY_RATIO)
                far = n_linear and not (a0 / RETRY_RATIO < ref[n_ports] < RETRY_RATIO * a0)
                if ok or attempt == 1 or not far:
                    break
                if not factor_now(plan, st, a0):
                    return wait_for_factor(
                        floats, counters, AT_SECOND_ATTEMPT, h, order, landing, 1, 0, 0
                    )
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
            for k in range(n_linear):
                charge = p_eliminated[n_switches + k]
                q[linear_slots[k]] = charge
                qdot[linear_slots[k]] = a0 * charge + hist[linear_slots[k]]
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

        # accept
        if (
            counters[VERSION] != counters[MEASURED_VERSION]
        ):  # the first accepted step on a new refactor
            counters[AFTER_REFACTOR] = last_active
            counters[MEASURED_VERSION] = counters[VERSION]
        if rebase_wanted(last_active, counters[AFTER_REFACTOR]):
            counters[ACTIVE_STREAK] += 1
        else:
            counters[ACTIVE_STREAK] = 0
        t = next_break if landing else t + h
        toggled = False
        for k in range(n_switches):
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
                y_junctions, current_applied, zrel, counters[Y_VERSION] != counters[VERSION],
            )  # fmt: skip
            counters[Y_VERSION] = counters[VERSION]
            for k in range(rows.size):
                out_x[row, k] = x_all[rows[k]]
        else:
            for k in range(rows.size):
                out_x[row, k] = unknown(
                    rows[k], yc, Yb, Zq, Z, src_values, hist_lin, current_dev, w
                )
        for i in range(n_charges):
            qdot_history[1, i] = qdot_history[0, i]
            qdot_history[0, i] = qdot[i]
            q_history[0, i] = q[i]
        finish_step(
            floats, counters, t, new_h, a0, order, landing, toggled, fixed, max_order, n_history
        )
    return FINISHED
