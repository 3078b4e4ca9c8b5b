"""The MNA kernel's steps in the time loop (time_loop.py): an attempt at a time point, the
record of an accepted one.

The attempt forms the sources' right-hand side and the charges' history, extrapolates the
iterate and runs Newton on every unknown (mna_newton.py, sparse_lu.py); what the loop keeps
between calls is the state ``st`` (plan.LoopState) and ``mid`` (newton.MidStep), what it
needs only within one call is :class:`MnaWork`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from circuitsim.solver.compiled.lowrank import add_u_columns, csr_matvec
from circuitsim.solver.compiled.mna_newton import CONVERGED, REORDER, mna_newton
from circuitsim.solver.compiled.mna_newton import REPIVOT as NEWTON_REPIVOT
from circuitsim.solver.compiled.newton import (
    COUNT,
    FACTOR_A0,
    IN_ITERATION,
    NEWTON,
    NOT_RESUMING,
    RESUME_ITERATION,
    RESUME_NONCON,
    RESUME_RETRY,
    copy_into,
    extend,
    wait_for_factor,
)
from circuitsim.solver.compiled.slots import REPIVOT_A0
from circuitsim.solver.compiled.step_control import CONTINUE, REPIVOT
from circuitsim.solver.devices.source_kernel import source_value
from circuitsim.solver.jit import njit


@njit(cache=True, inline="always")
def source_rhs(t, rhs_const, kind, par, dc, pwl_start, pwl_t, pwl_v, rows, signs, rhs, values):
    """Right-hand side ``rhs`` of the independent sources at time t (transient values), and
    the time-dependent sources' ``values``, written in place."""
    copy_into(rhs, rhs_const)
    for k in range(kind.size):
        value = source_value(t, k, kind, par, dc, pwl_start, pwl_t, pwl_v)
        values[k] = value
        for j in range(2):
            row = rows[k, j]
            if row >= 0:
                rhs[row] += signs[k, j] * value


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


class MnaWork(NamedTuple):
    """The MNA loop's arrays within one call (shapes: n unknowns, nq charge slots, ms
    switches, r ports plus linear charges)."""

    x_ext: np.ndarray  # (n + 1,) the converged iterate, ground last
    hist: np.ndarray  # (nq,) the charges' history term of the attempt
    x_guess: np.ndarray  # (n,) the attempt's first iterate
    b: np.ndarray  # (n,) Newton's right-hand side
    g_sw: np.ndarray  # (ms,) the switches' conductances
    charges_lin: np.ndarray  # (r,) port values and the linear charges of the iterate
    retry_from: np.ndarray  # (1,) bool: the attempt goes on from the failed one's iterate
    q: np.ndarray  # (nq,) the time point's charges (mid.q: they outlive a return)
    qdot: np.ndarray  # (nq,) their currents
    rhs0: np.ndarray  # (n,) the sources' right-hand side at the attempt's time
    src_values: np.ndarray  # (number of sources,) their values there
    u_weights: np.ndarray  # (linear charge slots,) minus their history terms
    x_iterate: np.ndarray  # (n,) Newton's iterate (mna_newton)
    x_iterate_ext: np.ndarray  # (n + 1,) it, ground last


@njit(cache=True, inline="always")
def all_finite(x) -> bool:
    """Whether every entry of x is finite (np.isfinite allocates)."""
    for value in x:
        if not math.isfinite(value):
            return False
    return True


@njit(cache=True, inline="always")
def mna_workspace(plan, st, mid):
    """The MNA loop's MnaWork for one call."""
    n, n_charges = plan.abs_tol.size, st.hq.shape[1]
    n_ports = plan.jp.shape[0] + plan.sw.shape[0]
    return MnaWork(
        np.empty(n + 1), np.empty(n_charges), np.empty(n), np.empty(n),
        np.empty(plan.sw.shape[0]), np.empty(n_ports + plan.lin_slots.size),
        np.zeros(1, dtype=np.bool_), mid.q, mid.qdot, np.empty(n), np.empty(plan.src_kind.size),
        np.empty(plan.lin_slots.size), np.empty(n), np.empty(n + 1),
    )  # fmt: skip


@njit(cache=True, inline="always")
def mna_step_begins(st, mid, work, resume):
    """At a step's start: the state kept for a step undone (REPIVOT), unless the step is
    resumed; whether its first attempt goes on from a failed one's iterate (kept over a
    return to Python)."""
    if resume == NOT_RESUMING:
        copy_into(mid.fs_start, st.fs)
        copy_into(mid.ints_start, st.ints)
    work.retry_from[0] = resume != NOT_RESUMING and st.ints[RESUME_RETRY] != 0


@njit(cache=True, inline="always")
def mna_attempt(plan, st, mid, work, t, h, order, landing, coefficients, ratio, n_history,
                resume):  # fmt: skip
    """Newton on every unknown at t + h (s) with the step's integration ``coefficients``
    (a0, a1, a2, b1) and ``ratio`` = h / h_prev (0: one point known); ``resume``: the step
    re-entered after a new pivot order (newton.IN_ITERATION) or not. Returns (status,
    converged, x_before): time_loop.CONTINUE or a code to return (newton.FACTOR: a new
    pivot order; step_control.REPIVOT: the step undone); ``x_before``: Newton's iterate
    before the last. A failed attempt's iterates are kept (st.fail_x, st.fail_prev), a
    converged one's unknowns are in work.x_ext and its charges in work.q, work.qdot."""
    fs, si = st.fs, st.ints
    a0, a1, a2, b1 = coefficients
    hq, hi, hx = st.hq, st.hi, st.hx
    hist, x_guess, retry_from = work.hist, work.x_guess, work.retry_from
    q, qdot, x_new = work.q, work.qdot, mid.x_new
    linear_slots = plan.lin_slots
    n, n_charges = x_guess.size, hq.shape[1]
    n_ports = plan.jp.shape[0] + plan.sw.shape[0]
    for j in range(n_charges):
        hist[j] = a1 * hq[0, j] + b1 * hi[0, j] + a2 * hq[1, j]
    rhs0, u_weights = work.rhs0, work.u_weights
    source_rhs(
        t + h, plan.rhs_const, plan.src_kind, plan.src_par, plan.src_dc, plan.pwl_start,
        plan.pwl_t, plan.pwl_v, plan.src_rows, plan.src_signs, rhs0, work.src_values,
    )  # fmt: skip
    if linear_slots.size:
        for j in range(linear_slots.size):
            u_weights[j] = -hist[linear_slots[j]]
        add_u_columns((plan.UT_ptr, plan.UT_idx, plan.UT_val), u_weights, n_ports, rhs0)
    for i in range(n):
        x_guess[i] = hx[0, i] + ratio * (hx[0, i] - hx[1, i])
    if n_history == 1 and retry_from[0]:  # go on from where the failed attempt got to
        copy_into(x_guess, st.fail_x)
    for j in range(n_charges if resume == NOT_RESUMING else 0):
        q[j] = 0.0
        qdot[j] = 0.0
    outcome, iterations, x_before = mna_newton(
        plan, st, x_guess, a0, hist, rhs0, q, qdot, work.g_sw, x_new, work.b,
        si[RESUME_ITERATION] if resume != NOT_RESUMING else 0, work.x_iterate,
        work.x_iterate_ext,
    )  # fmt: skip
    if outcome == REORDER:
        si[RESUME_RETRY] = 1 if retry_from[0] else 0
        fs[FACTOR_A0] = a0
        status = wait_for_factor(
            fs, si, IN_ITERATION, h, order, landing, 0, iterations, si[RESUME_NONCON]
        )
        return status, False, x_before
    if outcome == NEWTON_REPIVOT:
        copy_into(fs, mid.fs_start)
        copy_into(si, mid.ints_start)
        fs[REPIVOT_A0] = a0
        return REPIVOT, False, x_before
    si[NEWTON] += iterations
    if outcome != CONVERGED:
        copy_into(st.fail_x, x_new)
        copy_into(st.fail_prev, x_before)
        retry_from[0] = all_finite(x_new)
        return CONTINUE, False, x_before
    if linear_slots.size:
        charges_lin = work.charges_lin
        csr_matvec(plan.VT_ptr, plan.VT_idx, plan.VT_val, x_new, charges_lin)
        for j in range(linear_slots.size):
            charge = charges_lin[n_ports + j]
            q[linear_slots[j]] = charge
            qdot[linear_slots[j]] = a0 * charge + hist[linear_slots[j]]
    extend(x_new, work.x_ext)
    return CONTINUE, True, x_before


@njit(cache=True, inline="always")
def mna_accept(plan, st, mid, work, t):
    """The converged point at t (s) accepted (:func:`record_point`); returns whether a
    switch toggled in the step."""
    return record_point(
        t, mid.x_new, work.x_ext, st.x_prev_ext, plan.port_p, plan.port_n, st.vd_accepted,
        st.state, st.accepted, st.ht, st.hx, st.hq, st.hi, work.q, work.qdot, st.out_t,
        st.out_x, mid.rows, st.ints[COUNT],
    )  # fmt: skip
