"""The ports kernel's Newton iteration in named steps (ports.py's algebra; port_steps.py runs them).

One iteration on the junction voltages: linearize the junctions and decide the switches
(:func:`linearize_ports`); make the configuration if a0, the switch states or the
factorization changed (:func:`configuration_stale`, :func:`configure_ports`); the time
point's port responses (:func:`port_responses`); the active junctions' system
(:func:`junction_system`) and its solve (:func:`solve_active`); then the eliminated ports and
control voltages that follow (:func:`eliminated_ports`) and SPICE's convergence test
(:func:`junctions_converged`).

Every step takes the loop's plan and state tuples (``plan``: plan.KernelPlan, ``st``:
port_state.PortState). All but the rare :func:`configure_ports` allocate nothing and are
compiled without numba's reference counting and inlined by LLVM (``_nrt=False,
forceinline=True``), so that the loop pays no atomic reference-count update for an array it
reaches through them (docs/solver.md, "A numba detail that shaped both loops"). Voltages are
in V, currents in A, conductances in S, a0 in 1/s.
"""

from __future__ import annotations

import numpy as np

from circuitsim.solver.compiled.lowrank import NEGLIGIBLE
from circuitsim.solver.compiled.newton import (
    AFTER_REFACTOR,
    MEASURED_VERSION,
    RESUME_NONCON,
    VERSION,
    junction_charges,
    rebase_wanted,
)
from circuitsim.solver.compiled.ports import configure, h_column, unknown
from circuitsim.solver.compiled.slots import (
    ABSTOL,
    ACTIVE_STREAK,
    CFG_A0,
    CFG_COUNT,
    CFG_STALE,
    CFG_VERSION,
    NEW_H_MATRIX,
    RELTOL,
    VNTOL,
)
from circuitsim.solver.devices.diode_kernel import linearize_junction
from circuitsim.solver.devices.switch_kernel import (
    CONTROL_NEGATIVE,
    CONTROL_POSITIVE,
    G_OFF,
    G_ON,
    OFF_BELOW,
    ON_ABOVE,
    next_state,
)
from circuitsim.solver.jit import njit

STEP = dict(cache=True, _nrt=False, forceinline=True)


@njit(**STEP)
def charge_history(plan, st, a1, a2, b1, hist, hist_lin):
    """An attempt's history term of the charges, ``hist`` = a1 q_n + b1 qdot_n + a2 q_n-1
    (the linear charges' in ``hist_lin``), from the step's coefficients (step_control)."""
    q_history, qdot_history = st.q_history, st.qdot_history
    linear_slots = plan.lin_slots
    for k in range(hist.size):
        hist[k] = a1 * q_history[0, k] + b1 * qdot_history[0, k] + a2 * q_history[1, k]
    for k in range(linear_slots.size):
        hist_lin[k] = hist[linear_slots[k]]


@njit(**STEP)
def predict(st, ratio, q, qdot, new_iterate):
    """The attempt's first iterate: junction and control voltages extrapolated from the last
    two accepted points (``ratio`` = h / h_prev, 0 with one point), unless not
    ``new_iterate`` (an iteration resumed: its iterate is kept); charges cleared."""
    v_history, v_junction = st.v_history, st.v_junction
    control_history, v_control = st.control_history, st.v_control
    for k in range(v_junction.size if new_iterate else 0):
        v_junction[k] = v_history[0, k] + ratio * (v_history[0, k] - v_history[1, k])
    for k in range(v_control.size if new_iterate else 0):
        v_control[k] = control_history[0, k] + ratio * (
            control_history[0, k] - control_history[1, k]
        )
    for k in range(q.size):
        q[k] = 0.0
        qdot[k] = 0.0


@njit(**STEP)
def linearize_ports(plan, st, first, a0, hist, q, qdot):
    """Decide the switches at the iterate's control voltages (SwitchFamily.update_state) and
    linearize every junction at its voltage (DiodeFamily.port_load: limited voltage,
    current, conductance, companion current ieq; the charges into q, qdot); returns the
    count of toggled switches and limited junctions (nonconvergence)."""
    counters = st.ints
    state, accepted, approach = st.state, st.accepted, plan.approach
    v_control, v_junction = st.v_control, st.v_junction
    vd, cd, gd, ieq, vd_accepted = st.vd, st.cd, st.gd, st.ieq, st.vd_accepted
    jp, cp, jslot, has_charge, charged = plan.jp, plan.cp, plan.jslot, plan.has_charge, plan.charged
    noncon = 0
    for k in range(state.size):
        keep = accepted[k] if first else state[k]
        new = next_state(v_control[k], keep, approach[k, ON_ABOVE], approach[k, OFF_BELOW])
        if new != state[k]:
            state[k] = new
            noncon += 1
            counters[CFG_STALE] = 1
    for k in range(vd.size):
        charged_k = has_charge and charged[k]
        slot = jslot[k]
        v, limited, current, conductance, charge, charge_current = linearize_junction(
            jp, cp, k, v_junction[k], vd_accepted[k] if first else vd[k], charged_k, a0,
            hist[slot] if charged_k else 0.0,
        )  # fmt: skip
        noncon += limited
        if charged_k:
            q[slot] = charge
            qdot[slot] = charge_current
        vd[k], cd[k], gd[k] = v, current, conductance
        ieq[k] = current - conductance * v
    return noncon


@njit(**STEP)
def relinearized(plan, st, a0, hist, q, qdot):
    """An iteration re-entered after its linearization (a factorization made in Python): the
    charged junctions' charges at the voltages it linearized at (newton.junction_charges);
    returns its nonconvergence count as kept (RESUME_NONCON)."""
    junction_charges(
        st.vd, a0, hist, plan.jp, plan.cp, plan.jslot, plan.has_charge, plan.charged, q, qdot
    )
    return st.ints[RESUME_NONCON]


@njit(**STEP)
def configuration_stale(st, a0):
    """Whether a0 (1/s), a switch state or the factorization changed since the present
    configuration (the switch and charge ports' elimination, :func:`configure_ports`)."""
    floats, counters = st.fs, st.ints
    return (
        counters[CFG_STALE] == 1
        or counters[CFG_VERSION] != counters[VERSION]
        or floats[CFG_A0] != a0
    )


@njit(cache=True, _nrt=True)
def configure_ports(plan, st, a0):
    """Eliminate the switch and charge ports at a0 (1/s) and the switch states
    (ports.configure; then every column of H is to be formed anew); False when the
    elimination is singular (a refactor is needed). Runs only when
    :func:`configuration_stale`, so it is a plain compiled call (it allocates)."""
    floats, counters = st.fs, st.ints
    fac, state, g_switch, d_eliminated = st.fac, st.state, plan.g_switch, st.d_eliminated
    ref = fac.ref
    n_junctions, n_switches = plan.jp.shape[0], state.size
    for k in range(n_switches):
        on = g_switch[k, G_ON] if state[k] else g_switch[k, G_OFF]
        d_eliminated[k] = on - ref[n_junctions + k]
    for k in range(n_switches, d_eliminated.size):
        d_eliminated[k] = a0 - ref[n_junctions + k]
    if not configure(fac.K, n_junctions, d_eliminated, st.F, st.G, st.bound):
        return False
    floats[CFG_A0] = a0
    counters[CFG_VERSION] = counters[VERSION]
    counters[CFG_STALE] = 0
    counters[CFG_COUNT] += 1  # every column of H to be formed anew
    counters[NEW_H_MATRIX] = 1
    return True


@njit(**STEP)
def port_responses(st, src_values, hist_lin):
    """The time point's port responses (ports.py): c0 of the sources and the charge history,
    Fc0 = F c0_R and e0 = c0_J - K_JR G c0_R."""
    fac = st.fac
    K, cc, Cb, Kq = fac.K, fac.cc, fac.Cb, fac.Kq
    c0, e0, Fc0, F, G, scratch = st.c0, st.e0, st.Fc0, st.F, st.G, st.scratch
    n_junctions, n_eliminated = e0.size, Fc0.size
    for i in range(c0.size):
        acc = cc[i]
        for k in range(src_values.size):
            acc += Cb[i, k] * src_values[k]
        for k in range(hist_lin.size):
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


@njit(**STEP)
def junction_system(st, negligible_v):
    """(I + H D_J) p_J = e0 - H ieq for the *active* junctions, into st.A and st.b; returns
    their count m (their indices: st.active[:m]).

    Active: those whose conductance change moves the solution, |dJ_k| max_i |H_ik| >
    NEGLIGIBLE (as lowrank.active_columns). The others' columns of I + H D_J are unit columns
    to round-off (an op-amp macromodel's clamp diodes, far in reverse, keep their
    factorization's conductance), so their p follows by one product. H ieq is kept up to date
    by the columns whose companion current changed by more than ``negligible_v`` (V) at most;
    a smaller change waits until it grows, as in newton.junction_response: the companion
    currents of clamp diodes far in reverse change by round-off at every iteration (42 of the
    TL074 wheelset's 56; applying them took a third of its step)."""
    counters, fac = st.ints, st.fac
    K, ref = fac.K, fac.ref
    G, h_matrix, h_max, bound, formed_at = st.G, st.H, st.h_max, st.bound, st.formed_at
    gd, ieq, dg, h_ieq, ieq_applied = st.gd, st.ieq, st.dg, st.h_ieq, st.ieq_applied
    scratch, scratch2, active, A, b, e0 = st.scratch, st.scratch2, st.active, st.A, st.b, st.e0
    n_junctions, n_eliminated = gd.size, scratch.size
    for k in range(n_junctions):
        dg[k] = gd[k] - ref[k]
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
    for a in range(m):
        i = active[a]
        for c in range(m):
            A[a, c] = h_matrix[i, active[c]] * dg[active[c]]
        A[a, a] += 1.0
        b[a] = e0[i] - h_ieq[i]
    return m


@njit(**STEP)
def solve_active(st, m):
    """Solve the m active junctions' system (Gaussian elimination with partial pivoting, in
    place in st.A, st.b) and form the next iterate's junction voltages st.v_new; False when
    the system is singular or its solution is not finite."""
    A, b, x_active, active = st.A, st.b, st.x_active, st.active
    h_matrix, dg, e0, h_ieq, v_new = st.H, st.dg, st.e0, st.h_ieq, st.v_new
    for k in range(m):
        pivot_row = k
        big = abs(A[k, k])
        for i in range(k + 1, m):
            if abs(A[i, k]) > big:
                big = abs(A[i, k])
                pivot_row = i
        if big == 0.0:
            return False
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
    solved = True
    for k in range(m - 1, -1, -1):
        acc = b[k]
        for c in range(k + 1, m):
            acc -= A[k, c] * x_active[c]
        x_active[k] = acc / A[k, k]
        if not np.isfinite(x_active[k]):
            solved = False
    if not solved:
        return False
    for i in range(v_new.size):
        acc = e0[i] - h_ieq[i]
        for c in range(m):
            acc -= h_matrix[i, active[c]] * dg[active[c]] * x_active[c]
        v_new[i] = acc
    for c in range(m):
        v_new[active[c]] = x_active[c]
    return True


@njit(**STEP)
def eliminated_ports(plan, st, src_values, hist_lin):
    """What follows from the new junction voltages (ports.py): the junction current deviation
    j = ieq + D_J p_J, the eliminated ports p_R = F c0_R - F K_RJ j and w = D_R p_R, and the
    switches' control nodes and voltages."""
    fac = st.fac
    K, yc, Yb, Zq, Z = fac.K, fac.yc, fac.Yb, fac.Zq, fac.Z
    ieq, dg, v_new, current_dev = st.ieq, st.dg, st.v_new, st.current_dev
    F, Fc0, scratch, d_eliminated = st.F, st.Fc0, st.scratch, st.d_eliminated
    p_eliminated, w, x_ext, v_control, sw = st.p_eliminated, st.w, st.x_ext, st.v_control, plan.sw
    n_junctions, n_eliminated = ieq.size, w.size
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
    for k in range(v_control.size):  # the control nodes of this iterate
        for side in (CONTROL_POSITIVE, CONTROL_NEGATIVE):
            node = sw[k, side]
            if node >= 0:
                x_ext[node] = unknown(node, yc, Yb, Zq, Z, src_values, hist_lin, current_dev, w)
        v_control[k] = x_ext[sw[k, CONTROL_POSITIVE]] - x_ext[sw[k, CONTROL_NEGATIVE]]


@njit(**STEP)
def junctions_converged(plan, st, may_converge):
    """SPICE's convergence test of the iteration (``may_converge``: nothing was limited or
    toggled and it is not the first iteration of a nonlinear circuit): every junction's
    voltage change and its current change (DiodeFamily.port_converged) within tolerance. The
    new voltages become the iterate (the last two kept in st.fail_v)."""
    real = plan.real
    reltol, abstol, vntol = real[RELTOL], real[ABSTOL], real[VNTOL]
    v_new, v_junction, gd, vd, cd, fail_v = st.v_new, st.v_junction, st.gd, st.vd, st.cd, st.fail_v
    n_junctions = v_new.size
    done = may_converge
    for k in range(n_junctions if done else 0):
        change = abs(v_new[k] - v_junction[k])
        if change > reltol * max(abs(v_new[k]), abs(v_junction[k])) + vntol:
            done = False
            break
    for k in range(n_junctions if done else 0):
        delta = gd[k] * (v_new[k] - vd[k])
        if abs(delta) > reltol * max(abs(cd[k] + delta), abs(cd[k])) + abstol:
            done = False
            break
    for k in range(n_junctions):
        fail_v[0, k] = v_new[k]
        fail_v[1, k] = v_junction[k]
        v_junction[k] = v_new[k]
    return done


@njit(**STEP)
def count_active(counters, last_active):
    """At an accepted step: the active junctions the first step on a new factorization left
    (AFTER_REFACTOR), and the streak of steps that ended with many more (ACTIVE_STREAK,
    newton.rebase_wanted)."""
    if counters[VERSION] != counters[MEASURED_VERSION]:
        counters[AFTER_REFACTOR] = last_active
        counters[MEASURED_VERSION] = counters[VERSION]
    if rebase_wanted(last_active, counters[AFTER_REFACTOR]):
        counters[ACTIVE_STREAK] += 1
    else:
        counters[ACTIVE_STREAK] = 0
