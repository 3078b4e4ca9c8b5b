"""Direct solution of a System: scipy's integrators, stepped here and restarted at every kink.

A piecewise-linear term is smooth except where one of its ``|row . x + offset|`` arguments
crosses zero. A step that straddles such a kink loses its order there (and its error
estimate lies), so integration stops exactly at each crossing and restarts from it. Between
two crossings the field is affine (each ``|g|`` is ``side * g``), and that affine piece is
what is integrated, so every step, including the trial steps that reach past the next kink
before the crossing cuts them back, sees one smooth vector field. Times at which a term
switches on (``t_on``) end a segment the same way, and so do the corners of the inputs (each
point of a time series or step, both ends of a bump): the forcing of a segment is its smooth
piece, extended past the corner for the trial steps.

What is guaranteed about kinks (for the integrator's own trajectory, its dense output):

- **No step spans a sign change undetected, a graze included.** After every accepted step,
  each argument's interpolant over the step (a polynomial in t of the method's dense-output
  degree: 7 for DOP853, 4 for RK45, 3 for RK23 and Radau, at most 5 for BDF and 12 for
  LSODA) is checked against its side (:mod:`circuitsim.mechanics.crossings`): bounds clear
  most steps, and for the others the argument's lowest value over the step is found exactly.
  A contact that enters and leaves within one step is found however short it is, and each
  crossing is located by Brent's method on the interpolant. No step is shortened for this.
- **The side of a term at a restart is never the sign of a rounding-level value.** The kink
  just crossed takes the side it crossed into; any other argument within the rounding level
  of zero takes the side it moves into (its rate, or its curvature when the rate vanishes:
  the field is continuous across a kink, so both are the same on either side). A crossing
  counts only when an argument goes beyond the rounding level on the other side, so the
  crossing just handled cannot fire again at the restart point, and a state resting exactly
  on a kink raises no events. A kink that changes side at a restart without being the one
  just crossed is a crossing there too, and is recorded.

Not guaranteed: an excursion the integrator's trajectory does not make. Whether a trajectory
grazes at all is decided to its integration error (about ``rtol`` times the states per
step): a graze shallower than that may be found or missed, as by any solver at that
tolerance. One shallower than the rounding level (16 machine epsilons of the argument's
scale, plus its rate times the time's resolution) is ignored by design: the two sides'
fields differ there by that much. LSODA's interpolant can be of a degree above 12, where the
sampled polynomial is an approximation. ``max_step`` caps the step: kinks do not need it,
but it bounds the interpolation error between solver points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import BDF, LSODA, OdeSolution

from circuitsim.mechanics.crossings import KinkArguments, dense_form
from circuitsim.mechanics.errors import IntegrationError, IntegrationLimitError
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

# A restart that has not moved time forward more than this many times in a row means a
# kink keeps changing side at the restart point: give up rather than loop forever.
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
    is still smooth, so it is not rejected over and over; ``kinks.first_exit`` then finds where
    the step left the piece, and the part beyond is discarded.

    Parameters
    ----------
    system : System
    t : float
        Start of the phase, s.
    x : ndarray, shape (n,)
        State there.
    previous : dict of (str, int) to float
        Each kink's side in the phase before (empty at the start).
    crossed : dict of (str, int) to float
        Kinks known to have just crossed, with the side they crossed into.
    form : (int, str)
        The integrator's dense output: its degree in t and the form of its coefficients
        (:func:`~circuitsim.mechanics.crossings.dense_form`).
    """

    def __init__(
        self,
        system: System,
        t: float,
        x: np.ndarray,
        previous: dict[tuple[str, int], float],
        crossed: dict[tuple[str, int], float],
        form: tuple[int, str],
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
        self.kinks = KinkArguments(R, np.array(offsets, dtype=float), form)
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
        sides = self.sides = self.kinks.sides = self._sides(A, b, G, t, x, previous, crossed)
        self.A = A + G @ (sides[:, None] * R)
        self.b = b + G @ (sides * self.kinks.offsets)

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

    def _sides(self, A, b, G, t, x, previous, crossed) -> np.ndarray:
        """The side each kink argument is on or, within the rounding level of zero, moves into.

        A kink in ``crossed`` takes the side given there (the side it crossed into). Any
        other argument within the rounding level of zero takes its side from its rate (the
        direction of motion; the field is continuous across a kink, so the rate is the same
        on both sides), or its curvature when the rate vanishes, or its side in ``previous``.
        """
        count = len(self.labels)
        if not count:
            return np.ones(0)
        R, offsets = self.kinks.R, self.kinks.offsets
        g = R @ x + offsets
        signs = np.sign(g)
        slope = A @ x + b + G @ np.abs(g)
        if self.forcing is not None:
            slope = slope + self.forcing(t)
        rate = R @ slope
        curvature = R @ ((A + G @ (signs[:, None] * R)) @ slope)
        level = self.kinks.rounding(x, np.abs(rate) * abs(t))
        sides = np.ones(count)
        for j, label in enumerate(self.labels):
            if label in crossed:
                sides[j] = crossed[label]
            elif abs(g[j]) > level[j]:
                sides[j] = signs[j]
            else:
                sides[j] = np.sign(rate[j]) or np.sign(curvature[j]) or previous.get(label, 1.0)
        return sides

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


@dataclass
class _Segment:
    """What one phase integrated: solver points, interpolants, and how it ended."""

    t: list[float]
    x: list[np.ndarray]
    interpolants: list
    nfev: int
    crossing: tuple[float, int] | None
    full_step: float | None


def _integrate(phase: _Phase, method: type, t: float, t_end: float, x: np.ndarray, options):
    """Step ``phase`` from ``t`` to ``t_end`` or to the first crossing, whichever is first."""
    if "first_step" in options:
        options = {**options, "first_step": min(options["first_step"], t_end - t)}
    solver = method(phase.rhs, t, x, t_end, **options)
    segment = _Segment([t], [x], [], 0, None, None)
    while solver.status == "running":
        solver.step()
        if solver.status == "failed":
            raise IntegrationError(f"integration failed at t = {solver.t:.6g} s")
        dense = solver.dense_output()
        crossing = phase.kinks.first_exit(solver.t_old, solver.t, dense)
        if crossing is not None:
            segment.crossing = crossing
            if crossing[0] > segment.t[-1]:
                segment.t.append(crossing[0])
                segment.x.append(dense(crossing[0]))
                segment.interpolants.append(dense)
            break
        segment.t.append(solver.t)
        segment.x.append(np.array(solver.y, dtype=float))
        segment.interpolants.append(dense)
        segment.full_step = solver.t - solver.t_old
    segment.nfev = solver.nfev
    return segment


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
        Integrator tolerances (atol in the states' units).
    method : str
        Any solve_ivp method (``"DOP853"``, ``"RK45"``, ``"Radau"`` ...).
    max_step : float, optional
        Largest step, s (positive and finite; default unbounded).
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
        raised before the start when a forcing alone, or ``max_step`` over the span, needs
        more than ``max_steps`` steps.
    IntegrationError
        The integrator failed, ``max_step`` is not positive and finite, or a kink kept
        changing side without time advancing.
    """
    t0, t1 = (float(v) for v in t_span)
    if not t1 > t0:
        raise IntegrationError(f"t_span must increase, got ({t0}, {t1})")
    if max_step is not None and not (math.isfinite(max_step) and max_step > 0):
        raise IntegrationError(f"max_step must be positive and finite, got {max_step}")
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
    if max_step is not None and max_steps is not None and (t1 - t0) / max_step > max_steps:
        needed = f"{(t1 - t0) / max_step:.3g}" if (t1 - t0) / max_step < 1e300 else "1e300"
        raise IntegrationLimitError(
            f"not started: max_step {max_step:g} s needs at least {needed} steps over "
            f"{t1 - t0:g} s, more than the limit of {max_steps:,} steps; try a "
            "larger max_step (--max-step) or raise the step limit (max_steps; --max-steps)",
            time=t0,
            steps=0,
            limit="steps",
        )
    budget = Budget(max_steps, max_wall_time)
    integrator = guarded_method(method, budget)
    form = dense_form(integrator)
    options = {"rtol": rtol, "atol": atol}
    if max_step is not None:
        options["max_step"] = max_step

    times, values, starts, pieces, kinks, labels = [], [], [], [], [], []
    nfev, stalls, t = 0, 0, t0
    sides: dict[tuple[str, int], float] = {}
    crossed: dict[tuple[str, int], float] = {}
    while t < t1:
        phase = _Phase(system, t, x, sides, crossed, form)
        # a kink that changed side at the restart without being the one just crossed
        # crossed too, within the rounding level of this point
        for label, side in zip(phase.labels, phase.sides, strict=True):
            if label in sides and label not in crossed and sides[label] != side:
                kinks.append(t)
                labels.append(label)
        sides = dict(zip(phase.labels, phase.sides, strict=True))
        t_end = next((s for s in stops if s > t), t1)
        try:
            segment = _integrate(phase, integrator, t, t_end, x, options)
        except BudgetExhausted as exhausted:
            raise limit_error(exhausted, budget, t1) from None
        nfev += segment.nfev
        crossed = {}
        if segment.crossing is not None:
            j = segment.crossing[1]
            kinks.append(segment.t[-1])
            labels.append(phase.labels[j])
            crossed = {phase.labels[j]: -phase.sides[j]}
            if segment.t[-1] <= t:
                # the argument left its side at the restart point: change it and restart
                stalls += 1
                if stalls > _MAX_STALLS:
                    raise IntegrationError(
                        f"a kink keeps changing side without progress at t = {t:.6g} s"
                    )
                continue
        stalls = 0
        keep = slice(1, None) if times else slice(None)
        times.append(np.array(segment.t)[keep])
        values.append(np.array(segment.x).T[:, keep])
        starts.append(t)
        pieces.append(
            OdeSolution(segment.t, segment.interpolants, alt_segment=_alternate(integrator))
        )
        if segment.full_step is not None:
            # the last full step: a far better first step after the restart than scipy's
            # generic guess, which is often rejected several times in a row
            options["first_step"] = segment.full_step
        t, x = segment.t[-1], np.array(segment.x[-1], dtype=float)
        if segment.crossing is None:
            t = t_end
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


def _alternate(method: type) -> bool:
    """OdeSolution's ``alt_segment`` for a method (as solve_ivp sets it: BDF and LSODA)."""
    return issubclass(method, (BDF, LSODA))
