"""Transient analysis: variable-step trapezoidal / Gear-2 with ngspice's step control.

The loop follows ngspice's dctran: start from the operating point (or the ``uic`` initial
conditions) with a step of min(tstop/100, tstep)/10; at each breakpoint (t = 0, source corners,
switch transitions) drop to order 1 and shrink the step to a tenth of the distance to the next
breakpoint; land exactly on breakpoints; after each converged step estimate the truncation
error of every charge and flux (CKTterr), reject the step if the allowed step is below 0.9 h,
otherwise accept and let the step at most double; try order 2 when order 1 is comfortable.
A Newton failure divides the step by 8 and drops to order 1. The step never exceeds TMAX
(default min(tstep, (tstop - tstart)/50), as ngspice) and a step below 1e-11 TMAX is an error.
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from circuitsim.netlist.run_size import largest_step, time_resolution
from circuitsim.solver.compressed import unique
from circuitsim.solver.context import StepContext
from circuitsim.solver.dc import initial_condition_solution, operating_point_solution
from circuitsim.solver.devices.base import DeviceFamily
from circuitsim.solver.devices.switch import transition_retry
from circuitsim.solver.errors import (
    CircuitInputError,
    ConvergenceError,
    RunLimitError,
    SolverError,
)
from circuitsim.solver.integration import METHODS, truncation_step
from circuitsim.solver.layout import with_ground
from circuitsim.solver.newton import newton
from circuitsim.solver.recording import (
    budget_rows,
    diverged_iterate,
    memory_error,
    non_finite_error,
    row_bytes,
)
from circuitsim.solver.system import MnaSystem

HISTORY = 4  # accepted points kept: order 2 truncation needs t_n+1 and three before


def start_transient(
    system: MnaSystem,
    tstep: float,
    tstop: float,
    tstart: float,
    tmax: float | None,
    uic: bool,
    stats: dict,
) -> tuple[float, float, np.ndarray, np.ndarray, StepContext]:
    """What every transient loop does before its first step (this one and the compiled one).

    Checks the ``.tran`` times, resets the step counters in ``stats``, sets the sources'
    analysis-dependent defaults, and solves the start: the operating point, or the ``uic``
    initial conditions.

    Returns
    -------
    max_step, min_step : float
        TMAX (given, or ngspice's min(tstep, (tstop - tstart) / 50)) and 1e-11 of it, s.
    breaks : ndarray
        Sorted breakpoints after 0, ending with tstop, s.
    x : ndarray, shape (n,)
        The start solution.
    ctx0 : StepContext
        With its charges in ``ctx0.q``.
    """
    max_step = check_times(tstep, tstop, tstart, tmax)
    stats.update(accepted=0, rejected=0, newton_iterations=stats.get("newton_iterations", 0))
    min_step = 1e-11 * max_step
    for family in system.families:
        family.set_timing(tstep, tstop)
    corners = [family.breakpoints(tstop) for family in system.families]
    breaks = unique(np.concatenate([*corners, [tstop]]))
    breaks = breaks[breaks > min_step]
    if uic:
        x, ctx0 = initial_condition_solution(system)
    else:
        x, ctx0 = operating_point_solution(system, dc_op=False, clamp_ic=True, stats=stats)
    return max_step, min_step, breaks, x, ctx0


def check_times(tstep: float, tstop: float, tstart: float, tmax: float | None) -> float:
    """The ``.tran`` times checked; returns TMAX (given, or ngspice's default), s.

    Raises
    ------
    CircuitInputError
        A time out of order, or TMAX below the resolution of time near tstop (no step could
        advance time: ``.tran 1e-30 1e-6``).
    """
    if not (tstep > 0 and tstop > 0 and 0 <= tstart < tstop):
        raise CircuitInputError(
            f".tran {tstep:g} {tstop:g} {tstart:g}: need tstep > 0 and 0 <= tstart < tstop"
        )
    if tmax is not None and not tmax > 0:
        raise CircuitInputError(f".tran tmax {tmax:g} must be > 0")
    max_step = largest_step(tstep, tstop, tstart, tmax)
    # below a few ulps of tstop, t + h == t: no step could advance time; below SMALLEST_STEP the
    # smallest step (1e-11 of it) and its powers in the error estimate leave the normal floats
    # (a 1e-320 s tstep once reached 1/h = inf in the integration coefficients)
    resolution = time_resolution(tstop)
    if not max_step > resolution:
        raise CircuitInputError(
            f".tran {tstep:g} {tstop:g}: the largest step, {max_step:g} s, is below the "
            f"resolution of time near tstop ({resolution:.3g} s); give a larger tstep or tmax"
        )
    return max_step


@dataclass
class _Steps:
    """The step control's state between time points.

    ``t`` the last accepted time, ``h`` the step to try next, ``saved_h`` the step before the
    last landing on a breakpoint (s); ``order`` of the integration; ``at_break`` the last
    point was a breakpoint (or a switch toggled there); ``first`` no step accepted yet;
    ``bi`` index of the next breakpoint; ``attempts`` steps attempted; ``retry_from`` the last
    iterate of a failed first step (see :func:`_newton_at`).
    """

    t: float
    h: float
    saved_h: float
    order: int = 1
    at_break: bool = True
    first: bool = True
    bi: int = 0
    attempts: int = 0
    retry_from: np.ndarray | None = None


@dataclass
class _History:
    """The accepted points the integration and its error estimate use, newest first (at most
    HISTORY): times (s), unknowns, charges and their derivatives."""

    times: list[float]
    xs: list[np.ndarray]
    charges: list[np.ndarray]
    currents: list[np.ndarray]

    def h_prev(self, h: float) -> float:
        """The last accepted step (s), or ``h`` at the first."""
        return self.times[0] - self.times[1] if len(self.times) > 1 else h

    def push(self, t: float, x: np.ndarray, ctx: StepContext, toggled: bool) -> None:
        """Add the accepted point at ``t``. After a switch toggled, the history ends at the
        toggle: points before it would make the next steps' truncation error span the jump in
        dq/dt that the toggle made (the step that toggles is short, so that jump over it
        cascaded to "time step too small")."""
        self.times.insert(0, t)
        self.xs.insert(0, x)
        self.charges.insert(0, ctx.q)  # a fresh context per attempt: no copies needed
        self.currents.insert(0, ctx.qdot)
        keep = 1 if toggled else HISTORY
        del self.times[keep:], self.xs[keep:], self.charges[keep:], self.currents[keep:]


def run_transient(
    system: MnaSystem,
    tstep: float,
    tstop: float,
    tstart: float = 0.0,
    tmax: float | None = None,
    uic: bool = False,
    progress: Callable[[str], None] | None = None,
    stats: dict | None = None,
    rows: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate from 0 to ``tstop``, recording only the unknowns ``rows`` (default: all).

    Returns
    -------
    times : ndarray, shape (m,)
        Accepted time points >= tstart (with uic, after 0: see ``recorded``), seconds.
    solutions : ndarray, shape (m, len(rows))
        The unknowns ``rows`` at those points.
    """
    stats = stats if stats is not None else {}
    max_step, min_step, breaks, x, ctx0 = start_transient(
        system, tstep, tstop, tstart, tmax, uic, stats
    )
    options = system.options
    fixed = options.fixed_step
    x_prev_ext = with_ground(x)
    # families whose accept hook does something (the default does nothing)
    accepting = [f for f in system.families if type(f).accept is not DeviceFamily.accept]
    history = _History([0.0], [x], [ctx0.q.copy()], [np.zeros(system.n_charges)])
    out_t, out_x = [0.0], [x if rows is None else x[rows]]
    steps = _Steps(t=0.0, h=fixed if fixed else min(tstop / 100, tstep) / 10, saved_h=tstop / 50)
    report_every, next_report = tstop / 10, tstop / 10
    deadline = wall_deadline(options)
    # the list of points and the array made of it at the end: the table twice
    columns = system.size if rows is None else len(rows)
    most_points = budget_rows(options.max_memory, columns, copies=2)

    while tstop - steps.t > min_step:
        next_break, landing = _step_start(steps, breaks, fixed, max_step, min_step)
        landing, ctx, x_new, x_ext, new_h = _time_point(
            system, steps, history, x_prev_ext, landing, min_step, uic, deadline, tstop, stats
        )
        t = next_break if landing else steps.t + steps.h
        x_prev_ext = x_ext
        steps.retry_from = None  # only for attempts at this time point (not after a toggle)
        toggled = any([family.accept(x_ext, ctx) for family in accepting])
        history.push(t, x_new, ctx, toggled)
        kept = x_new if rows is None else x_new[rows]
        if not np.isfinite(kept).all():
            _raise_non_finite(system, rows, out_t, out_x, t, kept)
        if most_points is not None and len(out_t) >= most_points:
            held = 2 * len(out_t) * row_bytes(columns)
            raise memory_error(options.max_memory, steps.t, tstop, len(out_t), held)
        out_t.append(t)
        out_x.append(kept)
        stats["accepted"] += 1
        if fixed and steps.order < options.maxord:
            steps.order += 1
        if landing or toggled:
            steps.at_break = True
        steps.first = False
        steps.t, steps.h = t, new_h
        if progress is not None and t >= next_report:
            progress(f"transient: t = {t:.4g} s of {tstop:.4g} s, {stats['accepted']} steps")
            next_report += report_every

    out_t = np.array(out_t)
    out_x = np.array(out_x)
    keep = recorded(out_t, tstart, min_step, uic)
    return out_t[keep], out_x[keep]


def _step_start(
    steps: _Steps, breaks: np.ndarray, fixed: float, max_step: float, min_step: float
) -> tuple[float, bool]:
    """The next step's start: advance past the breakpoints reached; after a breakpoint drop
    to order 1 and shorten the step; cap it at TMAX and land exactly on the next breakpoint.
    Sets ``steps.h`` and ``steps.order``; returns (next breakpoint (s), landing on it)."""
    t = steps.t
    while steps.bi < len(breaks) - 1 and breaks[steps.bi] <= t + min_step:
        steps.bi += 1
    next_break = breaks[steps.bi]
    if fixed:
        steps.h = fixed
        if steps.at_break:
            steps.order = 1
    elif steps.at_break:
        steps.order = 1
        steps.h = min(steps.h, 0.1 * min(steps.saved_h, next_break - t))
        if steps.first:
            steps.h /= 10
    steps.at_break = False
    steps.h = min(steps.h, max_step) if not fixed else steps.h
    landing = False
    if t + steps.h >= next_break - min_step:
        steps.saved_h = steps.h
        steps.h = next_break - t
        landing = True
    return next_break, landing


def _time_point(
    system: MnaSystem,
    steps: _Steps,
    history: _History,
    x_prev_ext: np.ndarray,
    landing: bool,
    min_step: float,
    uic: bool,
    deadline: float | None,
    tstop: float,
    stats: dict,
) -> tuple[bool, StepContext, np.ndarray, np.ndarray, float]:
    """Attempts at the time point after ``steps.t`` until one is accepted: Newton, the cut
    of a step across a switch transition, the truncation-error test. Leaves the accepted
    step in ``steps.h`` and its order in ``steps.order``; returns (landing on the next
    breakpoint, the point's context, unknowns, unknowns with ground, the next step (s)).
    Raises ConvergenceError when the step falls below ``min_step`` and RunLimitError past
    max_steps or max_wall_time."""
    options = system.options
    fixed = options.fixed_step
    t = steps.t
    while True:
        steps.attempts += 1
        if steps.attempts > options.max_steps:
            raise RunLimitError("max_steps", options.max_steps, t, tstop, steps.attempts - 1)
        if deadline is not None and _time.perf_counter() > deadline:
            raise RunLimitError(
                "max_wall_time", options.max_wall_time, t, tstop, steps.attempts - 1
            )
        h = steps.h
        h_prev = history.h_prev(h)
        ok, iterations, ctx, x_new = _newton_at(system, steps, history, h, h_prev)
        stats["newton_iterations"] += iterations
        if not ok:
            stats["rejected"] += 1
            steps.retry_from = x_new if np.all(np.isfinite(x_new)) else None
            if fixed:
                raise _failure(system, "Newton failed at the fixed step", t + h, h, ctx, x_new)
            steps.h = h / 8
            steps.order = 1
            landing = False
            if steps.h < min_step:
                raise _failure(system, "time step too small", t + steps.h, steps.h, ctx, x_new)
            continue
        system.linear_charges(x_new, ctx)
        x_ext = with_ground(x_new)
        transition = False
        if not fixed and system.discrete and not (steps.first and uic):
            # A switch toggled inside the step: cut the step to end short of the crossing,
            # then take it in a short step (devices/switch.py, transition_retry). Not on
            # the first step from uic: its start is no solution (a control node driven by a
            # source reads 0 V there), so there is no crossing to locate; cutting towards
            # one took every such run down to steps of 1e-14 s (ngspice cuts none).
            fraction = min(f.transition_fraction(x_ext, x_prev_ext) for f in system.discrete)
            retry = transition_retry(fraction, h, h_prev, min_step)
            if retry:
                stats["rejected"] += 1
                steps.h = retry
                landing = False
                continue
            # A step that ends just past a transition is a breakpoint: its truncation
            # error estimate spans the jump in dq/dt and would reject every step that
            # crosses (a cascade to "time step too small" when the switched branch moves
            # a charge far above the one before, e.g. ROFF = 1e12 then RON onto an RC).
            transition = fraction < 1.0
        new_h = h if fixed else 2 * h
        if not fixed and not steps.first:
            new_h, order, good = _truncation_control(
                system, steps.order, t + h, h, ctx, history, x_ext, x_prev_ext, transition
            )
            steps.order = order
            if not good:
                stats["rejected"] += 1
                steps.h = new_h
                landing = False
                if new_h < min_step:
                    raise _failure(
                        system, "time step too small (truncation error)", t + new_h, new_h, ctx,
                        x_new,
                    )  # fmt: skip
                continue
        return landing, ctx, x_new, x_ext, new_h


def _newton_at(
    system: MnaSystem, steps: _Steps, history: _History, h: float, h_prev: float
) -> tuple[bool, int, StepContext, np.ndarray]:
    """Newton at t + h from the predictor: (converged, iterations, the point's context,
    the last iterate)."""
    method = METHODS[system.options.method]
    a0, a1, a2, b1 = method.coefficients(steps.order, h, h_prev)
    hist = a1 * history.charges[0] + b1 * history.currents[0]
    if a2:
        hist += a2 * history.charges[1]
    ctx = StepContext(system.n_charges, time=steps.t + h, dc=False, a0=a0, hist=hist)
    rhs = system.source_vector(ctx, dc_op=False, clamp_ic=False)
    xs = history.xs
    if len(xs) > 1:
        x_guess = xs[0] + (h / h_prev) * (xs[0] - xs[1])
    elif steps.retry_from is not None:
        # The first step again, shorter: go on from the failed attempt's last iterate,
        # as ngspice does (its solution vector is not reset). Its start is only the
        # operating point or, with uic, the initial conditions with every other node
        # at 0 V (supplies too): each attempt from there climbed the same pnjlim ladder
        # to the rails and ran out of itl4 iterations, down to "time step too small"
        # (a BJT op-amp macromodel's wheelset, tests/synthesis/test_opamp_library.py).
        x_guess = steps.retry_from
    else:
        x_guess = xs[0]
    ok, iterations, x_new = newton(system, x_guess, ctx, rhs, system.options.transient_iterations)
    return ok, iterations, ctx, x_new


def _truncation_control(
    system: MnaSystem,
    order: int,
    t_new: float,
    h: float,
    ctx: StepContext,
    history: _History,
    x_ext: np.ndarray,
    x_prev_ext: np.ndarray,
    transition: bool,
) -> tuple[float, int, bool]:
    """ngspice's truncation-error rule for the converged step of ``h`` s ending at
    ``t_new``: (next step (s), order, accepted). The charges' and the switches' limits;
    reject below 0.9 h, unless the step ends just past a switch transition (a
    breakpoint); at order 1, try order 2 when it allows more than 1.05 h."""
    options = system.options
    method = METHODS[options.method]
    step_times = [t_new, *history.times]
    step_q = [ctx.q, *history.charges]
    step_i = [ctx.qdot, history.currents[0]]
    new_h = 2 * h
    if len(step_times) >= order + 2:
        new_h = min(new_h, truncation_step(method, order, step_times, step_q, step_i, options))
    for family in system.discrete:
        new_h = min(new_h, family.truncate(x_ext, x_prev_ext, h))
    if not (new_h > 0.9 * h or transition):
        return new_h, order, False
    if order == 1 and options.maxord > 1 and len(step_times) >= 4:
        trial = min(2 * h, truncation_step(method, 2, step_times, step_q, step_i, options))
        for family in system.discrete:
            trial = min(trial, family.truncate(x_ext, x_prev_ext, h))
        new_h = trial
        if trial > 1.05 * h:
            order = 2
    return new_h, order, True


def wall_deadline(options, clock: Callable[[], float] = _time.perf_counter) -> float | None:
    """The reading of ``clock`` (s) past which a run started now stops (max_wall_time); a
    loop compares the deadline with readings of the same clock."""
    limit = options.max_wall_time
    return None if limit is None else clock() + limit


def recorded(times: np.ndarray, tstart: float, min_step: float, uic: bool) -> np.ndarray:
    """Which accepted points (``times``, s) a transient returns: those at or after ``tstart``,
    and with ``uic`` not t = 0, whose unknowns are only the initial conditions set in x, not
    a solution of the circuit (every node without an .ic at 0 V, whatever the capacitors hold;
    ngspice writes no t = 0 point in a uic run either). Returns a boolean mask."""
    keep = times >= tstart - min_step
    if uic:
        keep &= times > 0.0
    return keep


def _raise_non_finite(system, rows, out_t, out_x, t, kept) -> None:
    """Raise the NonFiniteError of the point ``kept`` (the unknowns ``rows``) at ``t``, s."""
    names = system.layout.unknowns
    names = names if rows is None else [names[i] for i in rows]
    table = np.vstack([*out_x, kept])
    raise non_finite_error(names, np.array([*out_t, t]), table, len(out_t))


def _failure(system, message, time, step, ctx: StepContext, x_new) -> SolverError:
    """The ConvergenceError of a failed step, or the NonFiniteError when its last Newton
    iterate is not finite (the solution diverged)."""
    if not np.all(np.isfinite(x_new)):
        return diverged_iterate(system, x_new, time)
    previous = ctx.x_previous
    node = None
    if previous is not None and np.all(np.isfinite(x_new)):
        node = system.worst_unknown(x_new, previous)
    return ConvergenceError(message, time=time, step=step, node=node)
