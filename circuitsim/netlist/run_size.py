"""The size of a transient run before it starts: time steps and recorded bytes, for any engine.

Every transient loop (ours and ngspice's) takes steps of at most TMAX (``.tran``'s fourth
number, else ngspice's ``min(tstep, (tstop - tstart) / 50)``) from 0 to TSTOP and records
every accepted point, each with every signal it keeps. So a run needs at least TSTOP / TMAX
steps and records at least (TSTOP - TSTART) / TMAX points; how many more depends on the
circuit (a switching edge or a stiff stretch takes shorter steps). That lower bound is what a
run is refused on before it starts (:meth:`RunSize.refusal`): past the step limit or the
memory budget it cannot finish. The estimate is shared by both engines (the builtin in
``circuitsim.solver.engine``, ngspice in ``circuitsim.interop.ngspice``), so both refuse
the same runs.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

BYTES_PER_VALUE = 8
"""A recorded value is a double (both engines)."""

SMALLEST_STEP = 1e-100
"""Seconds: far below any time constant; its 1e-11 squared is still a normal float."""

MEMORY_FRACTION = 0.5
"""The default memory budget is this fraction of the machine's physical memory."""


def largest_step(tstep: float, tstop: float, tstart: float = 0.0, tmax: float | None = None):
    """TMAX: ``tmax`` if given, else ngspice's ``min(tstep, (tstop - tstart) / 50)``, s."""
    return tmax if tmax else min(tstep, (tstop - tstart) / 50)


def time_resolution(tstop: float) -> float:
    """The shortest step that still advances time near ``tstop`` (a few ulps of it, and
    never below :data:`SMALLEST_STEP`), s: below it ``t + h == t``."""
    return max(4.0 * np.finfo(float).eps * tstop, SMALLEST_STEP)


def physical_memory() -> int | None:
    """The machine's physical memory, bytes (None where the system does not say)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, OSError, ValueError):
        return None


def default_memory_budget() -> int | None:
    """:data:`MEMORY_FRACTION` of the physical memory, bytes (None: unknown, no budget)."""
    total = physical_memory()
    return None if total is None else int(MEMORY_FRACTION * total)


def size_text(count: float) -> str:
    """Bytes as a short text with a decimal unit (``"3.7 GB"``)."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if count >= scale:
            return f"{count / scale:.3g} {unit}"
    return f"{count:.0f} B"


@dataclass(frozen=True)
class RunSize:
    """The least a ``.tran`` run takes: its steps and its recorded table.

    Attributes
    ----------
    tstop, tstart : float
        The run's end and the start of its recorded part, s.
    step : float
        Its largest step (TMAX, or the fixed step of a fixed-step run), s.
    signals : int
        Signals recorded at each point (the time column comes on top).
    """

    tstop: float
    tstart: float
    step: float
    signals: int

    @classmethod
    def of(cls, tstep, tstop, tstart=0.0, tmax=None, signals=1, fixed_step=None) -> RunSize:
        """The size of ``.tran tstep tstop tstart tmax`` recording ``signals`` signals (with
        ``fixed_step``, s, every step is that one)."""
        step = fixed_step or largest_step(tstep, tstop, tstart, tmax)
        return cls(float(tstop), float(tstart), float(step), int(signals))

    @property
    def steps(self) -> float:
        """Time steps at least (TSTOP / step, rounded up)."""
        return _ceiling(self.tstop / self.step)

    @property
    def points(self) -> float:
        """Recorded time points at least ((TSTOP - TSTART) / step, and the first)."""
        return _ceiling((self.tstop - self.tstart) / self.step) + 1.0

    @property
    def row_bytes(self) -> int:
        """Bytes of one recorded point: the time and each signal."""
        return BYTES_PER_VALUE * (self.signals + 1)

    @property
    def recorded_bytes(self) -> float:
        """Bytes of the recorded table at least."""
        return self.points * self.row_bytes

    def describe(self, max_steps: int | None = None, max_memory: float | None = None) -> str:
        """One line: steps and recorded memory at least, against the limits given."""
        steps = f"at least {self.steps:.3g} time steps (TSTOP {self.tstop:g} s"
        steps += f" / step {self.step:g} s"
        steps += f"; limit {max_steps:,})" if max_steps else ")"
        memory = (
            f"{self.signals} signal{'s' if self.signals != 1 else ''} recorded: at least "
            f"{size_text(self.recorded_bytes)} "
            f"({self.points:.3g} points x {self.row_bytes} bytes"
        )
        memory += f"; budget {size_text(max_memory)})" if max_memory else ")"
        return f"run size: {steps}, {memory}"

    def refusal(
        self, max_steps: int | None, max_memory: float | None, remedies: str = ""
    ) -> tuple[str, str] | None:
        """Why the run cannot finish within ``max_steps`` or ``max_memory`` (bytes), as
        (the limit's name, the message), or None. The message gives the figures and the
        remedies (``remedies`` for the memory: default :data:`MEMORY_REMEDIES`)."""
        if max_steps is not None and self.steps > max_steps:
            return "max_steps", (
                f"the run needs at least {self.steps:.3g} time steps (TSTOP {self.tstop:g} s "
                f"in steps of at most {self.step:g} s), more than the limit of {max_steps:,}: "
                "give a larger .tran tstep or tmax, a shorter tstop, or a higher limit "
                "(option max_steps, CLI --max-steps)"
            )
        if max_memory is not None and self.recorded_bytes > max_memory:
            return "max_memory", (
                f"the recorded results need at least {size_text(self.recorded_bytes)} "
                f"({self.points:.3g} time points x {self.signals} "
                f"signal{'s' if self.signals != 1 else ''} and the time, "
                f"{BYTES_PER_VALUE} bytes each), above the memory budget of "
                f"{size_text(max_memory)}: {remedies or MEMORY_REMEDIES}"
            )
        return None


def _ceiling(ratio: float) -> float:
    """``ratio`` rounded up, as a float (an infinite ratio stays infinite)."""
    return float(math.ceil(ratio)) if math.isfinite(ratio) else ratio


MEMORY_REMEDIES = (
    "record fewer signals (--probe), give a coarser output step (a larger .tran tstep or "
    "tmax) or a shorter tstop, or a larger budget (option max_memory, CLI --max-memory)"
)
"""What to try when a run's recorded results do not fit the budget."""

NGSPICE_MEMORY_REMEDIES = (
    "give a coarser output step (a larger .tran tstep or tmax) or a shorter tstop, or a "
    "larger budget (--max-memory); ngspice keeps every signal (--probe selects after its run)"
)
"""The same for ngspice, which records every signal whatever is probed."""
