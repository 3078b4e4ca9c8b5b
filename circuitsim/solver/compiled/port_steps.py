"""The ports kernel's steps in the time loop (time_loop.py): an attempt at a time point (Newton
on the junction voltages alone, port_newton.py's steps), the record of an accepted one.

Re-factoring after a new step size has settled or while many junctions stay active, a second
attempt on a refactor when the factorization's a0 is far: here. The iterate is the junction
(and switch control) voltages; an iteration converges when nothing was limited or toggled and
every junction passes SPICE's voltage and current checks (the other unknowns are affine in the
junction currents: docs/solver.md, "The ports kernel"). Nothing of size n is formed inside
Newton; the recorded unknowns are formed once per accepted point.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from circuitsim.solver.compiled.newton import (
    AT_REFACTOR_TEST,
    AT_SECOND_ATTEMPT,
    COUNT,
    FACTOR_A0,
    IN_ITERATION,
    JUNCTION_NEGLIGIBLE,
    LAST_A0,
    NEWTON,
    NOT_RESUMING,
    REBASE_STEPS,
    RESUME_ATTEMPT,
    RESUME_ITERATION,
    RETRY_RATIO,
    SAME_A0,
    VERSION,
    factor_now,
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
    ITL4,
    NEW_H_MATRIX,
    VNTOL,
    Y_VERSION,
)
from circuitsim.solver.compiled.step_control import (
    CONTINUE,
)
from circuitsim.solver.devices.source_kernel import source_value
from circuitsim.solver.devices.switch_kernel import (
    CONTROL_NEGATIVE,
    CONTROL_POSITIVE,
)
from circuitsim.solver.jit import njit


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


class PortWork(NamedTuple):
    """The ports loop's arrays within one call (shapes: n unknowns, nq charge slots, ns
    sources, nl linear charges)."""

    x_all: np.ndarray  # (n,) every unknown of an accepted point (ports.all_unknowns)
    src_values: np.ndarray  # (ns,) the sources' values at the time point
    hist: np.ndarray  # (nq,) the charges' history term of the attempt
    hist_lin: np.ndarray  # (nl,) the linear charges' part of it
    q: np.ndarray  # (nq,) the time point's charges
    qdot: np.ndarray  # (nq,) their currents
    last_active: np.ndarray  # (1,) int: active junctions in the last Newton iteration


@njit(cache=True, inline="always")
def port_workspace(plan, st):
    """The ports loop's PortWork for one call."""
    n_charges = st.q_history.shape[1]
    return PortWork(
        np.empty(st.fac.yc.size), np.empty(plan.src_kind.size), np.empty(n_charges),
        np.empty(plan.lin_slots.size), np.zeros(n_charges), np.zeros(n_charges),
        np.zeros(1, dtype=np.int64),
    )  # fmt: skip


@njit(cache=True, inline="always")
def port_first_factor(plan, st):
    """The run's first factorization (newton.FIRST_FACTOR), at fs[FACTOR_A0]; False when it
    is to be made in Python (newton.factor_now)."""
    return factor_now(plan, st, st.fs[FACTOR_A0])


@njit(**STEP)
def port_fixed_point(counters):
    """A pause at a tenth of the run, in model time: a fixed point where the caches updated
    in place (H ieq, the recorded unknowns' junction part) are formed anew, so that their
    round-off drift stays bounded."""
    counters[NEW_H_MATRIX] = 1
    counters[Y_VERSION] = -1


@njit(cache=True, inline="always")
def port_attempt(plan, st, work, t, h, order, landing, coefficients, ratio, resume):
    """Newton on the junction voltages at t + h (s) with the step's integration
    ``coefficients`` (a0, a1, a2, b1) and ``ratio`` = h / h_prev (0: one point known);
    ``resume``: where the step was re-entered after a factorization made in Python
    (newton.NOT_RESUMING, AT_REFACTOR_TEST, AT_SECOND_ATTEMPT, IN_ITERATION). A refactor
    first when :func:`refactor_wanted`; a second attempt on a refactor when the first failed
    and :func:`retry_wanted`. Returns (status, converged): step_control.CONTINUE or
    newton.FACTOR (the step's place kept); a converged point's charges in work.q,
    work.qdot."""
    floats, counters = st.fs, st.ints
    a0, a1, a2, b1 = coefficients
    hist, hist_lin, src_values = work.hist, work.hist_lin, work.src_values
    q, qdot = work.q, work.qdot
    src_kind, src_par, src_dc = plan.src_kind, plan.src_par, plan.src_dc
    pwl_start, pwl_t, pwl_v = plan.pwl_start, plan.pwl_t, plan.pwl_v
    linear = plan.jp.shape[0] == 0 and plan.sw.shape[0] == 0
    negligible_v = JUNCTION_NEGLIGIBLE * plan.real[VNTOL]
    itl4 = plan.ints[ITL4]
    charge_history(plan, st, a1, a2, b1, hist, hist_lin)
    if resume == NOT_RESUMING and refactor_wanted(plan, st, a0):
        if not factor_now(plan, st, a0):
            status = wait_for_factor(floats, counters, AT_REFACTOR_TEST, h, order, landing, 0, 0, 0)
            return status, False
    if resume == AT_REFACTOR_TEST:
        resume = NOT_RESUMING
    for k in range(src_kind.size):
        src_values[k] = source_value(t + h, k, src_kind, src_par, src_dc, pwl_start, pwl_t, pwl_v)
    ok = False
    first_attempt = counters[RESUME_ATTEMPT] if resume != NOT_RESUMING else 0
    if resume == AT_SECOND_ATTEMPT:
        resume = NOT_RESUMING
    for attempt in range(first_attempt, 2):
        predict(st, ratio, q, qdot, resume == NOT_RESUMING)  # else IN_ITERATION
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
                    work.last_active[0] = junction_system(st, negligible_v)
                    solved = solve_active(st, work.last_active[0])
                if solved or again == 1:
                    break
                if not factor_now(plan, st, a0):
                    status = wait_for_factor(floats, counters, IN_ITERATION, h, order, landing,
                                             attempt, iteration, noncon)  # fmt: skip
                    return status, False
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
            status = wait_for_factor(
                floats, counters, AT_SECOND_ATTEMPT, h, order, landing, 1, 0, 0
            )
            return status, False
    if ok:
        converged_charges(plan, st, a0, hist, q, qdot)
    return CONTINUE, ok


@njit(cache=True, inline="always")
def port_accept(plan, st, work, t):
    """The converged point at t (s) accepted (:func:`accept_point`, the active junctions
    counted first: newton.rebase_wanted); returns whether a switch toggled in the step."""
    count_active(st.ints, work.last_active[0])
    record_all = st.rows.size * 4 > st.fac.yc.size  # many recorded: ports.all_unknowns
    return accept_point(plan, st, t, work.src_values, work.hist_lin, work.q, work.qdot,
                        work.x_all, record_all)  # fmt: skip
