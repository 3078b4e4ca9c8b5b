"""The compiled time loop: the reference engine's step control (solver/transient.py), in numba,
around either kernel's attempt at a time point.

Same breakpoints, order changes, truncation-error rule (ngspice's CKTterr), Newton-failure
and switch-transition handling as ``run_transient`` (the rules in step_control.py). What a
kernel does at a time point is its steps: Newton on the junction voltages over a factored
linear part (the ports kernel, port_steps.py) or on every unknown with a sparse LU refactored
in part (the MNA kernel, mna_steps.py). :func:`march` is written once; numba compiles it
for each kernel's state with that kernel's steps inlined (kernel_steps.py chooses them by the
type of ``mid``: None for the ports kernel), so each kernel's loop is compiled as one
function, called once per chunk by its entry point (:func:`run_ports`, :func:`run_mna`).

:func:`march` is compiled without numba's reference counting (``_nrt=False``), and so is
every step it inlines: an inlined function's tuple arguments (the plan and state, about 150
arrays) are bound anew at each call, which numba counts as an atomic increment and decrement
per array. With the counting, those were about a third of the CPU samples of a process
running the ports kernel on the ideal wheelset (docs/solver.md, "One loop for both
kernels"). So the loop allocates nothing: its entry points make the arrays of a call (the
kernel's workspace, :func:`step_workspace`), and the few steps that allocate are calls
compiled with the counting (``_nrt=True``: newton.factor_now, port_newton.configure_ports,
source_kernel.pwl_value).

The loop runs until ``t_until`` and returns, so that the caller can report progress, grow the
output arrays or factor in Python; every scalar it keeps lives in ``st.fs`` / ``st.ints``
between calls.
"""

from __future__ import annotations

import numpy as np

from circuitsim.solver.compiled.kernel_steps import (
    accept,
    at_pause,
    attempt,
    loop_start,
    loop_views,
    step_begins,
    truncation_failure,
)
from circuitsim.solver.compiled.mna_steps import mna_workspace
from circuitsim.solver.compiled.newton import (
    ATTEMPTS,
    COUNT,
    FIRST,
    NHIST,
    NOT_RESUMING,
    PAUSE_ATTEMPTS,
    REJECTED,
    RESUME_AT,
    H,
    T,
    resumed_step,
)
from circuitsim.solver.compiled.port_steps import port_workspace
from circuitsim.solver.compiled.slots import (  # noqa: F401 (the runner reads REPIVOT_A0 here)
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
from circuitsim.solver.compiled.step_control import (  # noqa: F401 (the runner's codes)
    CONTINUE,
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
from circuitsim.solver.jit import njit


@njit(cache=True, nogil=True)
def run_ports(plan, st, t_until):
    """The ports kernel's loop (plan.KernelPlan with dense parts, port_state.PortState) from
    st.fs[T] until t_until (s) or tstop; returns a status code (:func:`march`)."""
    work = port_workspace(plan, st)
    return march(plan, st, t_until, None, work, step_workspace(plan, work.q.size))


@njit(cache=True)
def run_mna(plan, st, t_until, mid):
    """The MNA kernel's loop (plan.KernelPlan, plan.LoopState, newton.MidStep) from st.fs[T]
    until t_until (s) or tstop; returns a status code (:func:`march`)."""
    work = mna_workspace(plan, st, mid)
    return march(plan, st, t_until, mid, work, step_workspace(plan, work.q.size))


@njit(cache=True, inline="always")
def step_workspace(plan, n_charges):
    """The step control's arrays for one call of :func:`march`: (judge_step's (4,) times,
    the live charge slots, whether any slot is always zero: step_control.charge_slots)."""
    live, zeros = charge_slots(n_charges, plan.jslot, plan.charged, plan.has_charge)
    return np.empty(4), live, zeros


@njit(cache=True, _nrt=False)
def march(plan, st, t_until, mid, work, control):
    """Integrate from st.fs[T] until t_until (or tstop); returns a status code (PAUSED,
    FINISHED, FULL or a failure: step_control). ``mid`` None: the ports kernel, which may
    return newton.FACTOR (factor in Python at fs[FACTOR_A0], then re-enter where it stopped,
    newton.RESUME_AT). Else the MNA kernel's newton.MidStep: it may return REPIVOT (the pivot
    order no longer suits the matrix at a0 = fs[REPIVOT_A0]; the step undone, to be
    attempted again on a new order) or newton.FACTOR (a pivot became too small: a new order
    at a0 = fs[FACTOR_A0], then re-entered where it stopped). ``work``: the kernel's arrays
    for this call (port_steps.PortWork, mna_steps.MnaWork; an argument, not made here: numba
    0.68 inlined the kernel's steps wrongly reading a tuple made in this function);
    ``control``: :func:`step_workspace`'s. The kernel's own steps: kernel_steps.py."""
    real, ints = plan.real, plan.ints
    method, max_order, max_steps = ints[METHOD], ints[MAXORD], ints[MAX_STEPS]
    fixed, max_step = real[FIXED_STEP], real[MAX_STEP]
    min_step, tstop = real[MIN_STEP], real[TSTOP]
    floats, counters, breaks = st.fs, st.ints, plan.breaks
    x_prev_ext, out_t = st.x_prev_ext, st.out_t
    switch_state, switch_accepted = st.state, st.accepted
    switches, hysteresis = plan.sw, plan.approach
    t_history, q_history, qdot_history, x_iterate = loop_views(st, work, mid)
    charges, charge_currents = work.q, work.qdot
    judge_times, live, zeros = control
    resume = counters[RESUME_AT]  # back from a return to Python: where the step was
    counters[RESUME_AT] = NOT_RESUMING
    code, resume = loop_start(plan, st, mid, resume)
    if code != CONTINUE:
        return code
    while tstop - floats[T] > min_step:
        if resume != NOT_RESUMING:
            t, next_break, h, order, landing = resumed_step(floats, counters, breaks)
        else:
            if floats[T] >= t_until:  # a tenth of the run, in model time
                at_pause(counters, mid)
                return PAUSED
            if counters[ATTEMPTS] >= counters[PAUSE_ATTEMPTS]:
                return PAUSED  # for the wall clock (machine-dependent): changes nothing
            if counters[COUNT] >= out_t.size:
                return FULL
        step_begins(st, mid, work, resume)
        if resume == NOT_RESUMING:
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
            step = coefficients(method, order, h, h_prev)
            step_a0 = step[0]
            ratio = h / h_prev if n_history > 1 else 0.0
            code, ok, x_previous = attempt(
                plan, st, mid, work, t, h, order, landing, step, ratio, n_history, resume
            )
            resume = NOT_RESUMING
            if code != CONTINUE:
                return code
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
            verdict, new_h, order = judge_step(
                real, max_order, counters[FIRST], ints[UIC], t, h, order, n_history, t_history,
                x_iterate, x_prev_ext, switches, switch_state, switch_accepted, hysteresis,
                charges, charge_currents, q_history, qdot_history, judge_times, live, zeros,
            )  # fmt: skip
            if verdict == GOOD_STEP:
                break
            counters[REJECTED] += 1
            h = new_h
            landing = False
            if verdict == TRUNCATION_REJECTED and h < min_step:
                truncation_failure(st, mid, x_previous)
                floats[H] = h
                return STEP_TOO_SMALL_LTE

        t = next_break if landing else t + h
        toggled = accept(plan, st, mid, work, t)
        finish_step(floats, counters, t, new_h, step_a0, order, landing, toggled, fixed,
                    max_order, n_history)  # fmt: skip
    return FINISHED
