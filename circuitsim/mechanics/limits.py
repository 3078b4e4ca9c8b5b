"""Step-count and wall-time limits of the direct solution, so that no run goes on for ever.

A forcing of 1e9 Hz over one second (or a stiff eigenvalue an explicit method must follow)
asks for billions of steps: without a limit the integration runs for days, holding a dense
interpolant per step. :func:`guarded_method` wraps any scipy ``OdeSolver`` class so that every
step is charged to a :class:`Budget`; past either limit the step raises
:class:`BudgetExhausted`, which :func:`~circuitsim.mechanics.solve.solve` turns into an
:class:`~circuitsim.mechanics.errors.IntegrationLimitError` saying where (model time) it
stopped. scipy documents ``_step_impl`` as the method an ``OdeSolver`` subclass implements;
the wrapper only counts before delegating to it.
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, OdeSolver, Radau

from circuitsim.mechanics.errors import IntegrationError, IntegrationLimitError
from circuitsim.mechanics.system import System

METHODS: dict[str, type[OdeSolver]] = {
    "RK23": RK23,
    "RK45": RK45,
    "DOP853": DOP853,
    "Radau": Radau,
    "BDF": BDF,
    "LSODA": LSODA,
}

MAX_STEPS = 500_000
"""Default step limit of one solution (all restarts together). The wheelset's default 5 s run
takes about 1,500 steps; a dense interpolant per step makes 500,000 a few hundred megabytes."""

MAX_WALL_TIME = 300.0
"""Default wall-time limit of one solution, seconds."""


class BudgetExhausted(Exception):
    """A limit of the :class:`Budget` was reached at model time ``t`` (internal signal)."""

    def __init__(self, limit: str, t: float, step: float):
        super().__init__(limit)
        self.limit = limit
        self.t = t
        self.step = step


class Budget:
    """Steps taken and time used by one solution, against its limits.

    Parameters
    ----------
    max_steps : int or None
        Most steps (each with the rejected attempts scipy makes inside it), all segments
        together; None: no limit.
    max_wall_time : float or None
        Most seconds of wall time from the budget's creation; None: no limit.
    """

    def __init__(self, max_steps: int | None, max_wall_time: float | None):
        if max_steps is not None and not max_steps >= 1:
            raise IntegrationError(f"max_steps must be at least 1, got {max_steps}")
        if max_wall_time is not None and not max_wall_time > 0:
            raise IntegrationError(f"max_wall_time must be positive, got {max_wall_time}")
        self.max_steps = max_steps
        self.max_wall_time = max_wall_time
        self.steps = 0
        self.started = time.monotonic()

    @property
    def elapsed(self) -> float:
        """Seconds of wall time since the budget was created."""
        return time.monotonic() - self.started

    def charge(self, t: float, step: float) -> None:
        """Count one step from model time ``t`` (s) of size ``step`` (s).

        Raises
        ------
        BudgetExhausted
            Past the step or the wall-time limit.
        """
        self.steps += 1
        if self.max_steps is not None and self.steps > self.max_steps:
            raise BudgetExhausted("steps", t, step)
        if self.max_wall_time is not None and self.elapsed > self.max_wall_time:
            raise BudgetExhausted("time", t, step)


def guarded_method(method: str | type[OdeSolver], budget: Budget) -> type[OdeSolver]:
    """The ``OdeSolver`` class of ``method`` with every step charged to ``budget``.

    Raises
    ------
    IntegrationError
        An unknown method name.
    """
    base = METHODS.get(method) if isinstance(method, str) else method
    if base is None:
        raise IntegrationError(f"unknown method {method!r} (known: {', '.join(METHODS)})")

    class Guarded(base):
        def _step_impl(self):
            budget.charge(self.t, self.h_abs if hasattr(self, "h_abs") else math.nan)
            return super()._step_impl()

    Guarded.__name__ = Guarded.__qualname__ = f"Guarded{base.__name__}"
    return Guarded


def refuse_unresolvable_forcing(
    system: System, t_span: tuple[float, float], atol: float, max_steps: int | None
) -> None:
    """Refuse at once a run whose forcing alone needs more than ``max_steps`` steps.

    An integrator must take at least one step per period of a forcing that moves the states
    by more than ``atol`` (its rate ``amplitude * direction`` over ``2 pi f``); a lower
    bound past the limit would end in :class:`IntegrationLimitError` anyway, after minutes.

    Raises
    ------
    IntegrationLimitError
        Naming the forcing, its frequency, the steps it needs and what to change.
    """
    if max_steps is None:
        return
    t0, t1 = t_span
    for force in system.forcing:
        frequency = getattr(force, "frequency", None)  # a sinusoid; other inputs have none
        amplitude = getattr(force, "amplitude", None)
        if frequency is None or amplitude is None or frequency == 0:
            continue
        rate = abs(amplitude) * float(np.max(np.abs(force.direction), initial=0.0))
        if rate / (2 * math.pi * abs(frequency)) <= atol:
            continue
        needed = abs(frequency) * (t1 - t0)
        if needed > max_steps:
            name = getattr(force, "name", "") or "the forcing"
            raise IntegrationLimitError(
                f"not started: the forcing {name} at {abs(frequency):.3g} Hz needs at least "
                f"{needed:.3g} steps over {t1 - t0:g} s (one per period), more than the limit "
                f"of {max_steps:,} steps; try a shorter run, a lower frequency, or raise the "
                "step limit (max_steps; --max-steps)",
                time=t0,
                steps=0,
                limit="steps",
            )


def limit_error(exhausted: BudgetExhausted, budget: Budget, t_end: float) -> IntegrationLimitError:
    """The :class:`IntegrationLimitError` for a run stopped by ``budget`` before ``t_end``."""
    where = f"stopped at t = {exhausted.t:.6g} s of {t_end:g} s"
    step = "" if math.isnan(exhausted.step) else f", the last step {exhausted.step:.3g} s"
    if exhausted.limit == "steps":
        what = f"after {budget.steps - 1:,} steps (the step limit{step})"
        knob = "raise the step limit (max_steps; --max-steps)"
    else:
        what = (
            f"after {budget.elapsed:.3g} s of wall time (the limit: {budget.max_wall_time:g} s; "
            f"{budget.steps:,} steps{step})"
        )
        knob = "raise the time limit (max_wall_time; --max-wall-time)"
    return IntegrationLimitError(
        f"{where} {what}: the model moves faster than the run can follow (a fast forcing or "
        f"a stiff mode); try a shorter run, a looser tolerance (rtol; --rtol), or "
        f"{knob}",
        time=exhausted.t,
        steps=budget.steps,
        limit=exhausted.limit,
    )
