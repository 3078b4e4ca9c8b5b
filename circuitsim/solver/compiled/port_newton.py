"""The ports kernel's Newton at one time point (port_loop.py's step control calls it).

The iterate is the junction voltages (and the switches' control voltages); an iteration
linearizes the junctions, solves ``(I + H D_J) p_J = e0 - H ieq`` over the active junctions
(ports.py; docs/solver.md, "The ports kernel"), forms the eliminated ports and the switches'
control voltages from the junction currents, and converges when nothing was limited or
toggled, every junction voltage moved by less than reltol * |v| + vntol and every junction
passes SPICE's current check. The other unknowns are affine in the junction currents, so they
have converged with them. Nothing of size n is formed inside Newton.

The steps are inlined by numba into ``newton_at``, which is compiled without reference
counting and inlined by LLVM into port_loop.run (docs/solver.md, "The ports kernel's loop in
named steps"): nothing here may allocate.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from circuitsim.solver.compiled.lowrank import NEGLIGIBLE
from circuitsim.solver.compiled.newton import (
    JUNCTION_NEGLIGIBLE,
    VERSION,
    junction_charges,
)
from circuitsim.solver.compiled.ports import configure, h_column, unknown
from circuitsim.solver.compiled.slots import (
    ABSTOL,
    CFG_A0,
    CFG_COUNT,
    CFG_STALE,
    CFG_VERSION,
    ITL4,
    NEW_H_MATRIX,
    RELTOL,
    VNTOL,
)
from circuitsim.solver.devices.diode_kernel import linearize_junction
from circuitsim.solver.devices.switch_kernel import CONTROL_NEGATIVE, CONTROL_POSITIVE

# newton_at's outcomes: converged, not converged, or to be refactored at this iterate
CONVERGED, NOT_CONVERGED, REFACTOR = 0, 1, 2


@njit(cache=True, inline="always")
def update_switches(v_control, approach, accepted, state, first):
    """The switches' states at the iterate's control voltages (V), decided against the last
    accepted point's at the first iteration; returns how many toggled."""
    toggled = 0
    for k in range(state.size):
        keep = accepted[k] if first else state[k]
        new = (keep or v_control[k] > approach[k, 0]) and v_control[k] >= approach[k, 1]
        if new != state[k]:
            state[k] = new
            toggled += 1
    return toggled


@njit(cache=True, inline="always")
def linearize_junctions(jp, cp, jslot, has_charge, charged, a0, hist, first, lin, q, qdot):
    """Every junction linearized at the iterate ``lin.v_junction`` (DiodeFamily.port_load):
    its voltage, current, conductance and companion current into ``lin``, its charge and
    charge current into q and qdot; returns how many junctions limited their voltage."""
    v_junction, vd_accepted, vd, cd, gd, ieq = lin
    limited_count = 0
    for k in range(jp.shape[0]):
        charged_k = has_charge and charged[k]
        slot = jslot[k]
        v, limited, current, conductance, charge, charge_current = linearize_junction(
            jp, cp, k, v_junction[k], vd_accepted[k] if first else vd[k],
            charged_k, a0, hist[slot] if charged_k else 0.0,
        )  # fmt: skip
        limited_count += limited
        if charged_k:
            q[slot] = charge
            qdot[slot] = charge_current
        vd[k], cd[k], gd[k] = v, current, conductance
        ieq[k] = current - conductance * v
    return limited_count


@njit(cache=True, inline="always")
def eliminate_ports(K, ref, g_switch, state, a0, n_junctions, d_eliminated, F, G, st):
    """The configuration: the switch and charge ports eliminated at a0 (1/s) and the switch
    states (ports.configure, into F, G and st.bound); False when it is singular."""
    n_switches = state.size
    for k in range(n_switches):
        on = g_switch[k, 0] if state[k] else g_switch[k, 1]
        d_eliminated[k] = on - ref[n_junctions + k]
    for k in range(n_switches, d_eliminated.size):
        d_eliminated[k] = a0 - ref[n_junctions + k]
    return configure(K, n_junctions, d_eliminated, F, G, st.bound, st.elimination, st.bound_weights)


@njit(cache=True, inline="always")
def port_responses(K, cc, Cb, Kq, F, G, src_values, hist_lin, n_junctions, n_eliminated, rhs):
    """The time point's port responses (ports.py): c0 (the ports' response to the sources
    and the charge history), e0 = c0_J - K_JR G c0_R and F c0_R, into ``rhs``."""
    c0, e0, Fc0, scratch = rhs
    for i in range(n_junctions + n_eliminated):
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
    for i in range(n_junctions):
        acc = c0[i]
        for k in range(n_eliminated):
            acc -= K[i, n_junctions + k] * scratch[k]
        e0[i] = acc


@njit(cache=True, inline="always")
def h_times_ieq(K, G, ieq, n_junctions, n_eliminated, h_ieq, ieq_applied, scratch, scratch2):
    """H ieq after H changed, as K_JJ ieq - K_JR G (K_RJ ieq): no H formed."""
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


@njit(cache=True, inline="always")
def active_junctions(K, G, ref, gd, ieq, count, negligible_v, n_junctions, cols, active):
    """D_J (dg) at the iterate; H ieq updated by the companion currents that changed; the
    *active* junctions (|dJ_k| max_i |H_ik| > NEGLIGIBLE, as lowrank.active_columns) into
    ``active``, their columns of H formed when the configuration ``count`` has not yet;
    returns how many are active.

    The others' columns of I + H D_J are unit columns to round-off (an op-amp macromodel's
    clamp diodes, far in reverse, keep their factorization's conductance), so their p follows
    by one product. A companion current change that moves no junction voltage by more than
    ``negligible_v`` (V; bound: max_i |H_ik| or more) waits until it grows, as in
    newton.junction_response: the clamp diodes' companion currents change by round-off at
    every iteration (42 of the TL074 wheelset's 56; applying them took a third of its step).
    """
    dg, h_matrix, h_max, bound, formed_at, h_ieq, ieq_applied, scratch = cols
    for k in range(n_junctions):
        dg[k] = gd[k] - ref[k]
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
    return m


@njit(cache=True, inline="always")
def solve_active(h_matrix, dg, e0, h_ieq, active, m, A, b, x_active, v_new):
    """(I + H D_J) p_J = e0 - H ieq over the ``m`` active junctions (Gaussian elimination
    with partial pivoting), the others' p_J by one product, into v_new (V); False when the
    system is singular or its solution not finite."""
    for a in range(m):
        i = active[a]
        for c in range(m):
            A[a, c] = h_matrix[i, active[c]] * dg[active[c]]
        A[a, a] += 1.0
        b[a] = e0[i] - h_ieq[i]
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


@njit(cache=True, inline="always")
def eliminated_ports(K, F, Fc0, d_eliminated, ieq, dg, v_new, n_junctions, ports):
    """The junction current deviation j = ieq + D_J p_J (A), the eliminated ports
    p_R = F c0_R - F K_RJ j and w = D_R p_R (ports.py), into ``ports``."""
    current_dev, p_eliminated, w, scratch = ports
    for k in range(n_junctions):
        current_dev[k] = ieq[k] + dg[k] * v_new[k]
    for s in range(p_eliminated.size):  # tr = K_RJ j
        acc = 0.0
        for k in range(n_junctions):
            acc += K[n_junctions + s, k] * current_dev[k]
        scratch[s] = acc
    for i in range(p_eliminated.size):
        acc = Fc0[i]
        for k in range(p_eliminated.size):
            acc -= F[i, k] * scratch[k]
        p_eliminated[i] = acc
        w[i] = d_eliminated[i] * acc


@njit(cache=True, inline="always")
def control_voltages(sw, fac, src_values, hist_lin, current_dev, w, x_ext, v_control):
    """The switches' control nodes and voltages (V) of this iterate, into x_ext and
    v_control."""
    yc, Yb, Zq, Z = fac.yc, fac.Yb, fac.Zq, fac.Z
    for k in range(v_control.size):
        for side in (CONTROL_POSITIVE, CONTROL_NEGATIVE):
            node = sw[k, side]
            if node >= 0:
                x_ext[node] = unknown(node, yc, Yb, Zq, Z, src_values, hist_lin, current_dev, w)
        v_control[k] = x_ext[sw[k, CONTROL_POSITIVE]] - x_ext[sw[k, CONTROL_NEGATIVE]]


@njit(cache=True, inline="always")
def junctions_converged(v_new, v_junction, vd, cd, gd, reltol, abstol, vntol):
    """Every junction voltage moved by less than reltol |v| + vntol (V) and every junction
    passes SPICE's current check (DiodeFamily.port_converged)."""
    for k in range(v_new.size):
        change = abs(v_new[k] - v_junction[k])
        if change > reltol * max(abs(v_new[k]), abs(v_junction[k])) + vntol:
            return False
    for k in range(v_new.size):
        delta = gd[k] * (v_new[k] - vd[k])
        if abs(delta) > reltol * max(abs(cd[k] + delta), abs(cd[k])) + abstol:
            return False
    return True


@njit(cache=True, _nrt=False, forceinline=True)
def newton_at(plan, st, a0, hist, hist_lin, src_values, q, qdot, resumed, last_active):
    """Newton at one time point: iterations from the predicted ``st.v_junction``, or, with
    ``resumed`` = (iteration, nonconverged count) of an iteration that asked for a refactor
    (REFACTOR), on from that iteration after its linearization. a0 (1/s), the charge history
    ``hist`` and its linear slots ``hist_lin``, the sources' values at the time point; q and
    qdot receive the charges (C) and their currents (A). Returns (CONVERGED, NOT_CONVERGED or
    REFACTOR, iterations, the iteration's nonconverged count, active junctions of the last
    iteration that solved (``last_active`` when none did)).

    Compiled without numba's reference counting (``_nrt=False``): it allocates nothing and
    its caller holds every array it reads, and the counts of a function this large are not
    pruned (docs/solver.md, "A numba detail"). So it does not factor either (that allocates):
    the caller refactors on REFACTOR and calls it again with ``resumed``.
    """
    real, fs, counters, fac = plan.real, st.fs, st.ints, st.fac
    reltol, abstol, vntol = real[RELTOL], real[ABSTOL], real[VNTOL]
    jp, ref, K, F, G = plan.jp, fac.ref, fac.K, st.F, st.G
    n_junctions, n_switches = jp.shape[0], plan.sw.shape[0]
    n_eliminated = n_switches + plan.lin_slots.size
    linear = n_junctions == 0 and n_switches == 0
    negligible_v = JUNCTION_NEGLIGIBLE * vntol
    v_junction, v_new = st.v_junction, st.v_new
    lin = (v_junction, st.vd_accepted, st.vd, st.cd, st.gd, st.ieq)
    rhs = (st.c0, st.e0, st.Fc0, st.scratch)
    cols = (st.dg, st.H, st.h_max, st.bound, st.formed_at, st.h_ieq, st.ieq_applied, st.scratch)
    ports = (st.current_dev, st.p_eliminated, st.w, st.scratch)
    resuming = resumed[0] > 0
    outcome = NOT_CONVERGED
    iterations = noncon = 0
    fresh = True  # the time point's responses are to be (re)computed
    for iteration in range(resumed[0] if resuming else 1, plan.ints[ITL4] + 1):
        iterations = iteration
        first = iteration == 1
        if resuming:  # linearized before the refactor
            noncon = resumed[1]
            junction_charges(
                st.vd, a0, hist, jp, plan.cp, plan.jslot, plan.has_charge, plan.charged, q, qdot
            )
        else:
            noncon = update_switches(st.v_control, plan.approach, st.accepted, st.state, first)
            if noncon:
                counters[CFG_STALE] = 1
            noncon += linearize_junctions(
                jp, plan.cp, plan.jslot, plan.has_charge, plan.charged, a0, hist, first, lin, q,
                qdot,
            )  # fmt: skip
        solved = configured = True
        if (
            counters[CFG_STALE] == 1
            or counters[CFG_VERSION] != counters[VERSION]
            or fs[CFG_A0] != a0
        ):
            configured = eliminate_ports(
                K, ref, plan.g_switch, st.state, a0, n_junctions, st.d_eliminated, F, G, st
            )
            if configured:
                fs[CFG_A0] = a0
                counters[CFG_VERSION] = counters[VERSION]
                counters[CFG_STALE] = 0
                counters[CFG_COUNT] += 1  # every column of H to be formed anew
                fresh = True
                counters[NEW_H_MATRIX] = 1
        if configured:
            if fresh:
                port_responses(
                    K, fac.cc, fac.Cb, fac.Kq, F, G, src_values, hist_lin, n_junctions,
                    n_eliminated, rhs,
                )  # fmt: skip
                fresh = False
            if counters[NEW_H_MATRIX] == 1:
                h_times_ieq(
                    K, G, st.ieq, n_junctions, n_eliminated, st.h_ieq, st.ieq_applied,
                    st.scratch, st.scratch2,
                )  # fmt: skip
                counters[NEW_H_MATRIX] = 0
            m = active_junctions(
                K, G, ref, st.gd, st.ieq, counters[CFG_COUNT], negligible_v, n_junctions, cols,
                st.active,
            )  # fmt: skip
            last_active = m
            solved = solve_active(
                st.H, st.dg, st.e0, st.h_ieq, st.active, m, st.A, st.b, st.x_active, v_new
            )
        if not (configured and solved):
            if not resuming:  # a refactor here may cure it; after one, it has failed
                outcome = REFACTOR
            break
        resuming = False
        eliminated_ports(K, F, st.Fc0, st.d_eliminated, st.ieq, st.dg, v_new, n_junctions, ports)
        control_voltages(
            plan.sw, fac, src_values, hist_lin, st.current_dev, st.w, st.x_ext, st.v_control
        )
        done = noncon == 0 and (iteration > 1 or linear)
        if done:
            done = junctions_converged(
                v_new, v_junction, st.vd, st.cd, st.gd, reltol, abstol, vntol
            )
        fail_v = st.fail_v
        for k in range(n_junctions):
            fail_v[0, k] = v_new[k]
            fail_v[1, k] = v_junction[k]
            v_junction[k] = v_new[k]
        if done:
            outcome = CONVERGED
            break
    return outcome, iterations, noncon, last_active
