"""Direct solution of a System: scipy's solve_ivp, restarted at every kink.

A piecewise-linear term is smooth except where one of its ``|row . x + offset|`` arguments
crosses zero. A Runge-Kutta step that straddles such a kink loses its order there (and its
error estimate lies), so each argument is a terminal event: integration stops exactly at the
crossing and restarts from it. Between two crossings the field is affine (each ``|g|`` is
``side * g``), and that affine piece is what is integrated, so every step, including the
trial steps that reach past the next kink before the event cuts them back, sees one smooth
vector field. Times at which a term switches on (``t_on``) end a segment the same way, and so
do the corners of the inputs (each point of a time series or step, both ends of a bump): the
forcing of a segment is its smooth piece, extended past the corner for the trial steps.

Like any event location, a crossing and re-crossing of the same kink within one step is not
seen; ``max_step`` bounds how short such an excursion can be.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

from circuitsim.mechanics.errors import IntegrationError
from circuitsim.mechanics.limits import (
    MAX_STEPS,
    MAX_WALL_TIME,
    Budget,
    BudgetExhausted,
    guarded_method,
    limit_error,
    refuse_unresolvable_forcing,
)
from circuitsim.mechanics.system import Sinusoid, System

# A restart that has not moved time forward more than this many times in a row means events
# keep firing at the restart point: give up rather than loop forever.
_MAX_STALLS = 3


@dataclass
class OdeResult:
    """The direct solution of a System.

    Attributes
    ----------
    t : ndarray, shape (m,)
        Solver time points, s (each restart point once).
    x : ndarray, shape (n, m)
        States at ``t`` in the model's SI units, row order ``states``.
    states, units : tuple of str
        State names and units.
    kinks : ndarray, shape (k,)
        Times (s) at which an ``|.|`` argument crossed zero.
    kink_terms : list of (str, int)
        For each kink: the piecewise-linear term's name and the index of its abs term.
    switches : ndarray
        Times (s) at which a term switched on (``t_on``) inside the span.
    nfev : int
        Right-hand-side evaluations, all segments.
    system : System
        What was solved.
    """

    t: np.ndarray
    x: np.ndarray
    states: tuple[str, ...]
    units: tuple[str, ...]
    kinks: np.ndarray
    kink_terms: list[tuple[str, int]]
    switches: np.ndarray
    nfev: int
    system: System
    _starts: np.ndarray = field(repr=False, default=None)
    _pieces: list = field(repr=False, default_factory=list)

    def sol(self, t: float | np.ndarray) -> np.ndarray:
        """Dense evaluation anywhere in the span, piecewise across restarts.

        Parameters
        ----------
        t : float or array_like, shape (p,)
            Times, s.

        Returns
        -------
        ndarray, shape (n,) for scalar t, else (n, p)
        """
        times = np.asarray(t, dtype=float)
        flat = np.atleast_1d(times).ravel()
        index = np.clip(np.searchsorted(self._starts, flat, side="right") - 1, 0, None)
        out = np.empty((len(self.states), flat.size))
        for piece in np.unique(index):
            mask = index == piece
            out[:, mask] = self._pieces[piece](flat[mask])
        return out[:, 0] if times.ndim == 0 else out

    def state(self, name: str) -> np.ndarray:
        """One state's values at ``t``, shape (m,); ``name`` as in ``states``."""
        if name not in self.states:
            raise KeyError(f"unknown state {name!r} (states: {', '.join(self.states)})")
        return self.x[self.states.index(name)]

    def max_abs(self, name: str, t_from: float | None = None, t_to: float | None = None) -> float:
        """Largest ``|state|`` over [t_from, t_to] from the dense output.

        The solver points are refined by 16 dense samples per step, which puts the sampled
        peak within ~1e-4 relative of the true one even for steps spanning a fair part of a
        period.
        """
        lo = self.t[0] if t_from is None else t_from
        hi = self.t[-1] if t_to is None else t_to
        inside = self.t[(self.t >= lo) & (self.t <= hi)]
        grid = np.concatenate(([lo, hi], inside))
        grid = np.unique(grid)
        fine = np.linspace(0.0, 1.0, 17)[:-1]
        dense = (grid[:-1, None] + np.diff(grid)[:, None] * fine).ravel()
        dense = np.concatenate((dense, [hi]))
        return float(np.max(np.abs(self.sol(dense)[self.states.index(name)])))

    def csv_text(self, t: np.ndarray | None = None) -> str:
        """CSV text: header ``time,<states...>``, one row per time (SI units, 10 digits).

        Parameters
        ----------
        t : ndarray, shape (p,), optional
            Sample times, s (default: the solver points ``self.t``).
        """
        times = self.t if t is None else np.asarray(t, dtype=float)
        values = self.x if t is None else self.sol(times)
        table = np.vstack((times, values)).T
        lines = [",".join(("time",) + self.states)]
        lines.extend(",".join(f"{v:.10g}" for v in row) for row in table)
        return "\n".join(lines) + "\n"


class _Phase:
    """One smooth piece of the vector field: fixed active terms and fixed kink sides.

    Between two kink crossings every ``|g_j|`` equals ``side_j * g_j``, so the field is affine:
    ``A_seg x + b_seg + forcing(t)``. Integrating that affine field (its smooth extension past
    the kink) instead of the abs() form means a trial step that reaches beyond the next kink
    is still smooth, so it is not rejected over and over; the event then stops the segment at
    the crossing and the part beyond is discarded. The trajectory is the same, with about half
    the evaluations.
    """

    def __init__(
        self, system: System, t: float, x: np.ndarray, atol: np.ndarray, nudge: bool = False
    ):
        n = system.n
        active = [term for term in system.nonlinear if term.t_on is None or term.t_on <= t]
        A = np.array(system.A, dtype=float, copy=True)
        b = np.array(system.b0, dtype=float, copy=True)
        rows, offsets, columns, labels = [], [], [], []
        for term in active:
            A += np.outer(term.direction, term.linear)
            b += term.direction * term.constant
            for index, kink in enumerate(term.abs_terms):
                rows.append(kink.row)
                offsets.append(kink.offset)
                columns.append(term.direction * kink.gain)
                labels.append((term.name, index))
        R = np.array(rows, dtype=float).reshape(len(rows), n)
        offsets = np.array(offsets, dtype=float)
        G = np.array(columns, dtype=float).reshape(len(columns), n).T
        self.labels = labels
        sines = [f for f in system.forcing if isinstance(f, Sinusoid)]
        self.F = np.array([f.direction for f in sines], dtype=float).reshape(-1, n).T
        self.amplitude = np.array([f.amplitude for f in sines], dtype=float)
        self.omega = np.array([2.0 * np.pi * f.frequency for f in sines], dtype=float)
        self.phase = np.array([f.phase for f in sines], dtype=float)
        # the other inputs: their smooth piece from t to their next corner (a segment of a
        # time series, the inside of a bump), extended past it like the kinks' affine pieces
        self.inputs = [
            (np.asarray(f.direction, dtype=float), f.piece(t))
            for f in system.forcing
            if not isinstance(f, Sinusoid)
        ]
        self.forcing = self._forcing()
        sides, biases = self._sides(A, b, R, offsets, G, t, x, atol, nudge)
        self.A = A + G @ (sides[:, None] * R)
        self.b = b + G @ (sides * offsets)
        self.events = [_event(R[j], offsets[j] + biases[j], -sides[j]) for j in range(len(labels))]

    def _forcing(self):
        """The forcing as a closure; a single sinusoid uses math.sin (numpy's per-call
        overhead dominates at these sizes)."""
        sines = None
        if self.amplitude.size == 1:
            column = self.F[:, 0] * self.amplitude[0]
            omega, phase = float(self.omega[0]), float(self.phase[0])

            def sines(t):
                return column * math.sin(omega * t + phase)

        elif self.amplitude.size:
            F, amplitude, omegas, phases = self.F, self.amplitude, self.omega, self.phase

            def sines(t):
                return F @ (amplitude * np.sin(omegas * t + phases))

        if not self.inputs:
            return sines
        inputs = self.inputs

        def total(t):
            out = sines(t) if sines is not None else 0.0
            for direction, piece in inputs:
                out = out + direction * piece(t)
            return out

        return total

    def _sides(self, A, b, R, offsets, G, t, x, atol, nudge):
        """The side each kink argument is on (or, sitting on zero, about to move into).

        An argument on zero at the restart point gets its side from its rate (or its curvature
        when the rate vanishes); its event looks only for a crossing away from that side, so
        the crossing just handled cannot fire again at the restart point. When that was not
        enough (the state rests on the kink, the argument stays exactly zero and scipy counts
        0 -> 0 as a crossing), ``nudge`` also shifts such arguments onto their side by a margin
        below the absolute tolerance.
        """
        count = len(self.labels)
        sides, biases = np.ones(count), np.zeros(count)
        if not count:
            return sides, biases
        g = R @ x + offsets
        slope = A @ x + b + G @ np.abs(g)
        if self.forcing is not None:
            slope = slope + self.forcing(t)
        rate = R @ slope
        curvature = R @ (A @ slope)
        scale = np.abs(R) @ np.abs(x) + np.abs(offsets)
        margin = 1e-12 * scale + np.abs(R) @ atol
        for j in range(count):
            if abs(g[j]) > margin[j]:
                sides[j] = np.sign(g[j])
            else:
                sides[j] = np.sign(rate[j]) or np.sign(curvature[j]) or 1.0
                biases[j] = 2.0 * sides[j] * margin[j] if nudge else 0.0
        return sides, biases

    def rhs(self, t: float, x: np.ndarray) -> np.ndarray:
        """dx/dt on this piece, shape (n,).

        Raises
        ------
        IntegrationError
            The derivative is not finite: the states or the forcing overflowed. scipy's
            step-size control would go on with a NaN step for ever.
        """
        dx = self.A @ x + self.b
        if self.forcing is not None:
            dx += self.forcing(t)
        if not math.isfinite(dx.sum()):
            raise IntegrationError(
                f"the derivative is not finite at t = {t:.6g} s (largest |state| "
                f"{float(np.max(np.abs(x))):.3g}): the model overflows"
            )
        return dx


def _event(row: np.ndarray, offset: float, direction: float):
    def crossing(t: float, x: np.ndarray) -> float:
        return float(row @ x) + offset

    crossing.terminal = True
    crossing.direction = direction
    return crossing


def solve(
    system: System,
    t_span: tuple[float, float] = (0.0, 5.0),
    rtol: float = 1e-10,
    atol: float = 1e-12,
    method: str = "DOP853",
    max_step: float | None = None,
    x0: np.ndarray | None = None,
    max_steps: int | None = MAX_STEPS,
    max_wall_time: float | None = MAX_WALL_TIME,
) -> OdeResult:
    """Integrate ``system`` over ``t_span`` with a restart at every kink crossing.

    Parameters
    ----------
    system : System
        From :meth:`Model.system`.
    t_span : (float, float)
        Start and end time, s.
    rtol, atol : float
        solve_ivp tolerances (atol in the states' units).
    method : str
        Any explicit solve_ivp method (``"DOP853"``, ``"RK45"``, ``"Radau"`` ...).
    max_step : float, optional
        Largest step, s (default unbounded).
    x0 : array_like, shape (n,), optional
        Initial state (default ``system.x0``, or zeros).
    max_steps : int or None
        Most integrator steps, all restarts together (default 500,000; None: no limit).
    max_wall_time : float or None
        Most seconds of wall time (default 300; None: no limit).

    Returns
    -------
    OdeResult

    Raises
    ------
    IntegrationLimitError
        A limit was reached: the message says at what model time and what to try. Also
        raised before the start when a forcing alone needs more than ``max_steps`` steps.
    IntegrationError
        The integrator failed, or events kept firing without time advancing.
    """
    t0, t1 = (float(v) for v in t_span)
    if not t1 > t0:
        raise IntegrationError(f"t_span must increase, got ({t0}, {t1})")
    n = system.n
    start = system.x0 if x0 is None else x0
    x = np.zeros(n) if start is None else np.array(start, dtype=float).reshape(-1)
    if x.shape != (n,):
        raise IntegrationError(f"initial state needs {n} values, got {x.size}")
    switches = sorted({term.t_on for term in system.nonlinear if term.t_on is not None})
    switches = [s for s in switches if t0 < s < t1]
    # segments end where a term switches on and at every corner of an input (a time series'
    # points, a bump's ends): the input is smooth only between them
    corners = {float(c) for force in system.forcing for c in force.corners()}
    stops = sorted({s for s in corners if t0 < s < t1} | set(switches))
    atol_vector = np.broadcast_to(np.asarray(atol, dtype=float), (n,))
    refuse_unresolvable_forcing(system, (t0, t1), float(np.min(atol_vector)), max_steps)
    budget = Budget(max_steps, max_wall_time)
    options = {"rtol": rtol, "atol": atol, "dense_output": True}
    options["method"] = guarded_method(method, budget)
    if max_step is not None:
        options["max_step"] = max_step

    times, values, starts, pieces, kinks, labels = [], [], [], [], [], []
    nfev, stalls, t = 0, 0, t0
    first_step = None
    while t < t1:
        phase = _Phase(system, t, x, atol_vector, nudge=stalls > 0)
        t_end = next((s for s in stops if s > t), t1)
        events = phase.events
        if first_step is not None:
            options["first_step"] = min(first_step, t_end - t)
        try:
            sol = solve_ivp(phase.rhs, (t, t_end), x, events=events or None, **options)
        except BudgetExhausted as exhausted:
            raise limit_error(exhausted, budget, t1) from None
        nfev += sol.nfev
        if sol.status == -1:
            raise IntegrationError(f"integration failed at t = {sol.t[-1]:.6g} s: {sol.message}")
        t_next, x_next = sol.t[-1], sol.y[:, -1]
        if sol.status == 1:
            hit = [(ev[0], k) for k, ev in enumerate(sol.t_events) if len(ev)]
            t_next, k = min(hit)
            x_next = sol.y_events[k][0]
        if t_next <= t:
            # an event at the restart point itself: retry with the arguments nudged
            stalls += 1
            if stalls > _MAX_STALLS:
                raise IntegrationError(f"kink events keep firing without progress at t = {t:.6g} s")
            continue
        stalls = 0
        keep = slice(1, None) if times else slice(None)
        times.append(sol.t[keep])
        values.append(sol.y[:, keep])
        starts.append(t)
        pieces.append(sol.sol)
        if len(sol.t) > 2:
            # the last full step: a far better first step after the restart than scipy's
            # generic guess, which is often rejected several times in a row
            first_step = float(sol.t[-2] - sol.t[-3])
        if sol.status == 1:
            kinks.append(t_next)
            labels.append(phase.labels[k])
            t, x = float(t_next), np.array(x_next, dtype=float)
        else:
            t, x = t_end, np.array(x_next, dtype=float)
    return OdeResult(
        t=np.concatenate(times),
        x=np.concatenate(values, axis=1),
        states=tuple(system.states),
        units=tuple(system.units),
        kinks=np.array(kinks),
        kink_terms=labels,
        switches=np.array(switches, dtype=float),
        nfev=nfev,
        system=system,
        _starts=np.array(starts),
        _pieces=pieces,
    )
