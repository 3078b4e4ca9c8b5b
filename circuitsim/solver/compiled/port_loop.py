"""The ports kernel's time loop: transient.py's step control around a Newton on the junction
voltages alone (ports.py).

Breakpoints, order changes, the truncation-error rule, Newton-failure and switch-transition
handling, re-factoring after a new step size has settled: all as compiled/transient.py. What
differs is Newton's unknowns and its convergence test. The iterate is the junction voltages
(and the switches' control voltages); an iteration converges when nothing was limited or
toggled, every junction voltage moved by less than reltol * |v| + vntol and every junction
passes SPICE's current check. The other unknowns are affine in the junction currents, so they
have converged with them; the reference engine also tests each of them, which can ask for one
more iteration. Nothing of size n is formed inside Newton; the recorded unknowns are formed
once per accepted point.
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
    RELTOL,
    TSTOP,
    UIC,
    VNTOL,
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
from circuitsim.solver.devices.diode_kernel import linearize_junction
from circuitsim.solver.devices.source_kernel import source_value
from circuitsim.solver.devices.switch_kernel import (
    switch_transition,
    switch_truncate,
    transition_retry,
)


@njit(cache=True, nogil=True)
def run(plan, st, t_until):
    """Integrate from st.fs[T] until t_until (or tstop); returns compiled/transient.py's
    status codes, or newton.FACTOR (then re-entered where it stopped, newton.RESUME_AT)."""
    real, ints = plan.real, plan.ints
    method, maxord, max_steps = ints[METHOD], ints[MAXORD], ints[MAX_STEPS]
    fixed, max_step = real[FIXED_STEP], real[MAX_STEP]
    min_step, tstop = real[MIN_STEP], real[TSTOP]
    md, ms = plan.jp.shape[0], plan.sw.shape[0]
    nports = md + ms
    lin = plan.lin_slots
    nl = lin.size
    nq = st.hq.shape[1]
    fs, si = st.fs, st.ints
    breaks = plan.breaks
    ht, hq, hi, hv, hc = st.ht, st.hq, st.hi, st.hv, st.hc
    x_ext, x_prev_ext, state, accepted = st.x_ext, st.x_prev_ext, st.state, st.accepted
    vd_accepted, pJ, vc, pR = st.vd_accepted, st.pJ, st.vc, st.pR
    sw, approach = plan.sw, plan.approach
    rows, out_t, out_x, fail_v = st.rows, st.out_t, st.out_x, st.fail_v
    # every array taken out of the tuples once (the factorization is rebuilt in place)
    fac = st.fac
    ref, K, cc, Cb, Kq = fac.ref, fac.K, fac.cc, fac.Cb, fac.Kq
    yc, Yb, Zq, Z = fac.yc, fac.Yb, fac.Zq, fac.Z
    vd, cd, gd, ieq, pJ_new, dJ = st.vd, st.cd, st.gd, st.ieq, st.pJ_new, st.dJ
    dR, F, G, Hj, bound, colv = st.dR, st.F, st.G, st.H, st.bound, st.colv
    tr, tr2 = st.tr, st.tr2
    c0, e0, Fc0, A, b, jv, w = st.c0, st.e0, st.Fc0, st.A, st.b, st.j, st.w
    hcol, Hieq, applied, act, xa = st.hcol, st.Hieq, st.ieq_applied, st.act, st.xa
    new_h_matrix = True  # H changed: H ieq to be recomputed in full
    # many recorded unknowns: form them all column by column (ports.all_unknowns)
    every = rows.size * 4 > fac.yc.size
    ZT, zrel = fac.ZT, fac.zrel
    x_all = np.empty(fac.yc.size)
    yJ = np.empty(fac.yc.size)
    j_applied = np.zeros(md)
    yj_version = -1
    reltol, abstol, vntol = real[RELTOL], real[ABSTOL], real[VNTOL]
    itl4 = ints[ITL4]
    jp, cp, jslot, has_charge, charged = plan.jp, plan.cp, plan.jslot, plan.has_charge, plan.charged
    g_switch = plan.g_switch
    linear = md == 0 and ms == 0
    src_kind, src_par, src_dc = plan.src_kind, plan.src_par, plan.src_dc
    pwl_start, pwl_t, pwl_v = plan.pwl_start, plan.pwl_t, plan.pwl_v
    ns = src_kind.size
    rR = ms + nl
    r = md + rR
    src_values = np.empty(ns)
    hist = np.empty(nq)
    hist_lin = np.empty(nl)
    q = np.zeros(nq)
    qdot = np.zeros(nq)
    times = np.empty(4)
    live, zeros = charge_slots(nq, jslot, charged, has_charge)
    negligible_v = JUNCTION_NEGLIGIBLE * vntol
    m_last = 0  # active junctions in the last Newton iteration
    resume = si[RESUME_AT]  # back from a factorization made in Python: where the step was
    si[RESUME_AT] = NOT_RESUMING
    if resume == FIRST_FACTOR:
        resume = NOT_RESUMING
        if not factor_now(plan, st, fs[FACTOR_A0]):
            return FACTOR  # then re-entered at the first step
    while tstop - fs[T] > min_step:
        if resume != NOT_RESUMING:
            t, next_break, h, order, landing = resumed_step(fs, si, breaks)
        else:
            if fs[T] >= t_until or si[ATTEMPTS] >= si[PAUSE_ATTEMPTS]:
                return PAUSED
            if si[COUNT] >= out_t.size:
                return FULL
            t, next_break, h, order, landing = step_start(fs, si, breaks, fixed, max_step, min_step)
        nh = si[NHIST]
        while True:
            if resume == NOT_RESUMING:
                si[ATTEMPTS] += 1
            if si[ATTEMPTS] > max_steps:
                fs[H] = h
                return TOO_MANY_STEPS
            h_prev = ht[0] - ht[1] if nh > 1 else h
            a0, a1, a2, b1 = coefficients(method, order, h, h_prev)
            for k in range(nq):
                hist[k] = a1 * hq[0, k] + b1 * hi[0, k] + a2 * hq[1, k]
            for k in range(nl):
                hist_lin[k] = hist[lin[k]]
            ref_a0 = ref[nports] if nl else a0
            settled = a0 != ref_a0 and a0 == fs[LAST_A0] and si[SAME_A0] >= REBASE_STEPS
            # or the junctions have left the conductances factored (a uic start factors all
            # of them at 0 V; then the op-amps' output stages settle far from there): each
            # iteration then eliminates many active columns, which a refactor makes few
            stale = si[ACTIVE_STREAK] >= REBASE_STEPS
            if resume == NOT_RESUMING and ((nl and settled) or stale):
                si[ACTIVE_STREAK] = 0
                if not factor_now(plan, st, a0):
                    return wait_for_factor(fs, si, AT_REFACTOR_TEST, h, order, landing, 0, 0, 0)
            if resume == AT_REFACTOR_TEST:
                resume = NOT_RESUMING
            for k in range(ns):
                src_values[k] = source_value(
                    t + h, k, src_kind, src_par, src_dc, pwl_start, pwl_t, pwl_v
                )
            ratio = h / h_prev if nh > 1 else 0.0
            ok = False
            first_attempt = si[RESUME_ATTEMPT] if resume != NOT_RESUMING else 0
            if resume == AT_SECOND_ATTEMPT:
                resume = NOT_RESUMING
            for attempt in range(first_attempt, 2):
                for k in range(md if resume == NOT_RESUMING else 0):  # the predictor
                    pJ[k] = hv[0, k] + ratio * (hv[0, k] - hv[1, k])
                for k in range(ms if resume == NOT_RESUMING else 0):
                    vc[k] = hc[0, k] + ratio * (hc[0, k] - hc[1, k])
                for k in range(nq):
                    q[k] = 0.0
                    qdot[k] = 0.0
                # Newton at this time point, written out rather than called: a call, or a
                # tuple of arrays unpacked per call, costs reference-count updates (atomic
                # operations) that measured more than the arithmetic of an iteration here
                ok = False
                iterations = 0
                fresh = True  # the time point's responses are to be (re)computed
                first_iteration = si[RESUME_ITERATION] if resume == IN_ITERATION else 1
                for iteration in range(first_iteration, itl4 + 1):
                    iterations = iteration
                    first = iteration == 1
                    noncon = 0
                    first_again = 0
                    if resume == IN_ITERATION:  # linearized before the factorization
                        noncon = si[RESUME_NONCON]
                        junction_charges(vd, a0, hist, jp, cp, jslot, has_charge, charged, q, qdot)
                        first_again = 1
                    for k in range(ms if resume == NOT_RESUMING else 0):  # update_state
                        keep = accepted[k] if first else state[k]
                        new = (keep or vc[k] > approach[k, 0]) and vc[k] >= approach[k, 1]
                        if new != state[k]:
                            state[k] = new
                            noncon += 1
                            si[CFG_STALE] = 1
                    for k in range(md if resume == NOT_RESUMING else 0):  # DiodeFamily.port_load
                        charged_k = has_charge and charged[k]
                        slot = jslot[k]
                        v, limited, current, conductance, charge, charge_current = (
                            linearize_junction(
                                jp, cp, k, pJ[k], vd_accepted[k] if first else vd[k], charged_k,
                                a0, hist[slot] if charged_k else 0.0,
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
                        if si[CFG_STALE] == 1 or si[CFG_VERSION] != si[VERSION] or fs[CFG_A0] != a0:
                            # eliminate the switch and charge ports at a0 and the switch states
                            for k in range(ms):
                                on = g_switch[k, 0] if state[k] else g_switch[k, 1]
                                dR[k] = on - ref[md + k]
                            for k in range(ms, dR.size):
                                dR[k] = a0 - ref[md + k]
                            if not configure(K, md, dR, F, G, bound):
                                if again == 1:
                                    break
                                if not factor_now(plan, st, a0):
                                    return wait_for_factor(
                                        fs, si, IN_ITERATION, h, order, landing, attempt,
                                        iteration, noncon,
                                    )  # fmt: skip
                                continue
                            fs[CFG_A0] = a0
                            si[CFG_VERSION] = si[VERSION]
                            si[CFG_STALE] = 0
                            si[CFG_COUNT] += 1  # every column of H to be formed anew
                            fresh = True
                            new_h_matrix = True
                        if fresh:  # the time point's port responses (ports.py: c0, e0, F c0_R)
                            for i in range(r):
                                acc = cc[i]
                                for k in range(ns):
                                    acc += Cb[i, k] * src_values[k]
                                for k in range(nl):
                                    acc -= Kq[i, k] * hist_lin[k]
                                c0[i] = acc
                            for i in range(rR):  # tr = G c0_R, Fc0 = F c0_R
                                acc = 0.0
                                acc2 = 0.0
                                for k in range(rR):
                                    acc += G[i, k] * c0[md + k]
                                    acc2 += F[i, k] * c0[md + k]
                                tr[i] = acc
                                Fc0[i] = acc2
                            for i in range(md):  # e0 = c0_J - K_JR G c0_R
                                acc = c0[i]
                                for k in range(rR):
                                    acc -= K[i, md + k] * tr[k]
                                e0[i] = acc
                            fresh = False
                        for k in range(md):
                            dJ[k] = gd[k] - ref[k]
                        # (I + H D_J) p_J = e0 - H ieq, for the *active* junctions only: those
                        # whose conductance change moves the solution, |dJ_k| max_i |H_ik| >
                        # NEGLIGIBLE (as lowrank.active_columns). The others' columns of
                        # I + H D_J are unit columns to round-off (an op-amp macromodel's clamp
                        # diodes, far in reverse, keep their factorization's conductance), so
                        # their p follows by one product. H ieq is kept up to date by the
                        # columns whose companion current changed (by more than negligibly,
                        # below). (Written out, not called: see the Newton comment above.)
                        count = si[CFG_COUNT]
                        if new_h_matrix:  # H ieq = K_JJ ieq - K_JR G (K_RJ ieq), no H formed
                            for s_ in range(rR):
                                acc = 0.0
                                for k in range(md):
                                    acc += K[md + s_, k] * ieq[k]
                                tr2[s_] = acc
                            for s_ in range(rR):
                                acc = 0.0
                                for q_ in range(rR):
                                    acc += G[s_, q_] * tr2[q_]
                                tr[s_] = acc
                            for i in range(md):
                                acc = 0.0
                                for k in range(md):
                                    acc += K[i, k] * ieq[k]
                                for s_ in range(rR):
                                    acc -= K[i, md + s_] * tr[s_]
                                Hieq[i] = acc
                            for k in range(md):
                                applied[k] = ieq[k]
                            new_h_matrix = False
                        # A change that moves no junction voltage by more than
                        # JUNCTION_NEGLIGIBLE vntol (bound: max_i |H_ik| or more) waits until it
                        # grows, as in newton.junction_response: the companion currents of clamp
                        # diodes far in reverse change by round-off at every iteration (42 of the
                        # TL074 wheelset's 56; applying them took a third of its step).
                        for k in range(md):
                            change = ieq[k] - applied[k]
                            if change != 0.0 and abs(change) * bound[k] > negligible_v:
                                if colv[k] != count:
                                    h_column(K, G, md, k, Hj, hcol, tr)
                                    colv[k] = count
                                for i in range(md):
                                    Hieq[i] += Hj[i, k] * change
                                applied[k] = ieq[k]
                        m = 0
                        for k in range(md):
                            if dJ[k] != 0.0 and abs(dJ[k]) * bound[k] > NEGLIGIBLE:
                                if colv[k] != count:
                                    h_column(K, G, md, k, Hj, hcol, tr)
                                    colv[k] = count
                                if abs(dJ[k]) * hcol[k] > NEGLIGIBLE:
                                    act[m] = k
                                    m += 1
                        m_last = m
                        for a in range(m):
                            i = act[a]
                            for c in range(m):
                                A[a, c] = Hj[i, act[c]] * dJ[act[c]]
                            A[a, a] += 1.0
                            b[a] = e0[i] - Hieq[i]
                        # A xa = b (m x m, partial pivoting), written out as well
                        solved = True
                        for k in range(m):
                            p_ = k
                            big = abs(A[k, k])
                            for i in range(k + 1, m):
                                if abs(A[i, k]) > big:
                                    big = abs(A[i, k])
                                    p_ = i
                            if big == 0.0:
                                solved = False
                                break
                            if p_ != k:
                                for c in range(m):
                                    A[k, c], A[p_, c] = A[p_, c], A[k, c]
                                b[k], b[p_] = b[p_], b[k]
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
                                    acc -= A[k, c] * xa[c]
                                xa[k] = acc / A[k, k]
                                if not np.isfinite(xa[k]):
                                    solved = False
                        if solved:
                            for i in range(md):
                                acc = e0[i] - Hieq[i]
                                for c in range(m):
                                    acc -= Hj[i, act[c]] * dJ[act[c]] * xa[c]
                                pJ_new[i] = acc
                            for c in range(m):
                                pJ_new[act[c]] = xa[c]
                        if solved or again == 1:
                            break
                        if not factor_now(plan, st, a0):
                            return wait_for_factor(
                                fs, si, IN_ITERATION, h, order, landing, attempt, iteration, noncon
                            )
                    if not solved:
                        break
                    # j = ieq + D_J p_J, p_R = F c0_R - F K_RJ j, w = D_R p_R (ports.py)
                    for k in range(md):
                        jv[k] = ieq[k] + dJ[k] * pJ_new[k]
                    for s_ in range(rR):  # tr = K_RJ j
                        acc = 0.0
                        for k in range(md):
                            acc += K[md + s_, k] * jv[k]
                        tr[s_] = acc
                    for i in range(rR):
                        acc = Fc0[i]
                        for k in range(rR):
                            acc -= F[i, k] * tr[k]
                        pR[i] = acc
                        w[i] = dR[i] * acc
                    for k in range(ms):  # the control nodes of this iterate
                        for side in (2, 3):
                            node = sw[k, side]
                            if node >= 0:
                                x_ext[node] = unknown(
                                    node, yc, Yb, Zq, Z, src_values, hist_lin, jv, w
                                )
                        vc[k] = x_ext[sw[k, 2]] - x_ext[sw[k, 3]]
                    done = noncon == 0 and (iteration > 1 or linear)
                    for k in range(md if done else 0):
                        change = abs(pJ_new[k] - pJ[k])
                        if change > reltol * max(abs(pJ_new[k]), abs(pJ[k])) + vntol:
                            done = False
                            break
                    for k in range(md if done else 0):  # DiodeFamily.port_converged
                        delta = gd[k] * (pJ_new[k] - vd[k])
                        if abs(delta) > reltol * max(abs(cd[k] + delta), abs(cd[k])) + abstol:
                            done = False
                            break
                    for k in range(md):
                        fail_v[0, k] = pJ_new[k]
                        fail_v[1, k] = pJ[k]
                        pJ[k] = pJ_new[k]
                    if done:
                        ok = True
                        break
                si[NEWTON] += iterations
                # the update's round-off, not the step, may be what failed (RETRY_RATIO)
                far = nl and not (a0 / RETRY_RATIO < ref[nports] < RETRY_RATIO * a0)
                if ok or attempt == 1 or not far:
                    break
                if not factor_now(plan, st, a0):
                    return wait_for_factor(fs, si, AT_SECOND_ATTEMPT, h, order, landing, 1, 0, 0)
            if not ok:
                si[REJECTED] += 1
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
            for k in range(nl):
                qk = pR[ms + k]
                q[lin[k]] = qk
                qdot[lin[k]] = a0 * qk + hist[lin[k]]
            transition = False
            if fixed == 0 and ms and not (ints[UIC] and si[FIRST]):  # uic: solver/transient.py
                fraction = switch_transition(x_ext, x_prev_ext, sw, state, accepted, approach)
                retry = transition_retry(fraction, h, ht[0] - ht[1] if nh > 1 else h, min_step)
                if retry > 0:  # cut short of the crossing, then just past it (devices/switch.py)
                    si[REJECTED] += 1
                    h = retry
                    landing = False
                    continue
                transition = fraction < 1.0
            new_h = h if fixed > 0 else 2 * h
            if fixed == 0 and not si[FIRST]:
                times[0] = t + h
                for k in range(3):
                    times[k + 1] = ht[k]
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
                        fs[H] = h
                        return STEP_TOO_SMALL_LTE
                    continue
            break

        # accept
        if si[VERSION] != si[MEASURED_VERSION]:  # the first accepted step on a new refactor
            si[AFTER_REFACTOR] = m_last
            si[MEASURED_VERSION] = si[VERSION]
        if rebase_wanted(m_last, si[AFTER_REFACTOR]):
            si[ACTIVE_STREAK] += 1
        else:
            si[ACTIVE_STREAK] = 0
        t = next_break if landing else t + h
        toggled = False
        for k in range(ms):
            if state[k] != accepted[k]:
                toggled = True
            accepted[k] = state[k]
            for side in (2, 3):
                node = sw[k, side]
                if node >= 0:
                    x_prev_ext[node] = x_ext[node]
            hc[1, k] = hc[0, k]
            hc[0, k] = vc[k]
        for k in range(md):
            vd_accepted[k] = pJ[k]
            hv[1, k] = hv[0, k]
            hv[0, k] = pJ[k]
        for j in range(3, 0, -1):
            ht[j] = ht[j - 1]
            for i in range(nq):
                hq[j, i] = hq[j - 1, i]
        ht[0] = t
        row = si[COUNT]
        out_t[row] = t
        if every:
            all_unknowns(
                x_all, yc, Yb, ZT, src_values, hist_lin, jv, w, md, yJ, j_applied, zrel,
                yj_version != si[VERSION],
            )  # fmt: skip
            yj_version = si[VERSION]
            for k in range(rows.size):
                out_x[row, k] = x_all[rows[k]]
        else:
            for k in range(rows.size):
                out_x[row, k] = unknown(rows[k], yc, Yb, Zq, Z, src_values, hist_lin, jv, w)
        for i in range(nq):
            hi[1, i] = hi[0, i]
            hi[0, i] = qdot[i]
            hq[0, i] = q[i]
        finish_step(fs, si, t, new_h, a0, order, landing, toggled, fixed, maxord, nh)
    return FINISHED
