"""The builtin engine's run guards on the ngspice path: size refused up front, memory and
progress watched while it runs, non-finite results refused after.

ngspice has no step limit and keeps every vector at every accepted point in memory until it
writes them, so a ``.tran`` with a needlessly fine step runs to the time limit or out of
memory in silence. Before it starts, the deck's ``.tran`` card is sized as the builtin
engine sizes its own runs (:class:`circuitsim.netlist.run_size.RunSize`) and refused on the
same grounds (the same errors: a step below the resolution of time, a run past the step
limit or the memory budget). While it runs, :class:`RunWatch` reads its resident memory about
once a second, stops it past the budget (a named error, not the kernel's out-of-memory
kill) and reports the elapsed time. Its results must be finite.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field

from circuitsim.netlist.run_size import (
    NGSPICE_MEMORY_REMEDIES,
    RunSize,
    default_memory_budget,
    size_text,
)
from circuitsim.netlist.values import parse_value
from circuitsim.solver.errors import CircuitInputError, MemoryBudgetError, RunSizeError
from circuitsim.solver.transient import check_times

try:
    import resource
except ImportError:  # pragma: no cover - Windows: the address space is not capped
    resource = None  # type: ignore[assignment]


def tran_times(lines: list[str]) -> tuple[float, float, float, float | None] | None:
    """(tstep, tstop, tstart, tmax) of the deck's first ``.tran`` card, seconds; None when
    there is none or its times are not plain numbers (parameters: ngspice evaluates them)."""
    for text in lines:
        words = re.split(r"[\s,]+", text.strip())
        if not words or words[0].lower() != ".tran":
            continue
        numbers = []
        for word in words[1:5]:
            if word.lower() == "uic":
                break
            try:
                numbers.append(parse_value(word))
            except ValueError:
                return None
        if len(numbers) < 2:
            return None
        tstart = numbers[2] if len(numbers) > 2 else 0.0
        tmax = numbers[3] if len(numbers) > 3 else None
        return numbers[0], numbers[1], tstart, tmax
    return None


def refuse_endless_sweep(lines: list[str]) -> None:
    """Refuse an ``.ac dec`` card whose range holds less than one step: ngspice 39 takes
    ``floor(decades * points)`` equal ratios from fstart to fstop, and with none its ratio is
    infinite and its sweep never ends (acan.c: ``freq *= inf`` stays within ``fstop + inf``).

    Raises
    ------
    CircuitInputError
        Naming the card, before ngspice starts.
    """
    for text in lines:
        words = re.split(r"[\s,]+", text.strip())
        if len(words) < 5 or words[0].lower() != ".ac" or words[1].lower() != "dec":
            continue
        try:
            points, fstart, fstop = (parse_value(w) for w in words[2:5])
        except ValueError:
            return  # parameters: ngspice evaluates them
        if fstart > 0 and fstop > 0 and math.floor(abs(math.log10(fstop / fstart)) * points) < 1:
            raise CircuitInputError(
                f"{text.strip()}: less than one step between fstart and fstop at {points:g} "
                "points per decade; ngspice 39 never ends such a sweep (widen the range or "
                "raise the points)"
            )
        return


def checked_size(
    lines: list[str], signals: int, max_steps: int | None, max_memory: float | None
) -> RunSize | None:
    """The size of the deck's ``.tran`` run recording ``signals`` signals (None: no plain
    ``.tran``), refused as the builtin engine refuses its runs.

    Raises
    ------
    CircuitInputError
        A time out of order, or a largest step below the resolution of time near tstop.
    RunSizeError
        More steps than ``max_steps`` or more recorded bytes than ``max_memory`` at least.
    """
    times = tran_times(lines)
    if times is None:
        return None
    tstep, tstop, tstart, tmax = times
    check_times(tstep, tstop, tstart, tmax)
    size = RunSize.of(tstep, tstop, tstart, tmax, signals)
    refused = size.refusal(max_steps, max_memory, NGSPICE_MEMORY_REMEDIES)
    if refused is not None:
        limit, message = refused
        raise RunSizeError(limit, max_steps if limit == "max_steps" else max_memory, tstop, message)
    return size


def process_memory(pid: int, field: str = "VmRSS") -> int | None:
    """A memory figure of process ``pid`` (Linux: /proc/<pid>/status; ``VmRSS`` resident,
    ``VmSize`` address space), bytes; None where it cannot be read."""
    try:
        with open(f"/proc/{pid}/status", encoding="ascii", errors="replace") as status:
            for line in status:
                if line.startswith(f"{field}:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


ALLOCATION_FAILED = re.compile(r"can't allocate|out of memory|cannot allocate", re.IGNORECASE)
"""What ngspice prints when an allocation fails (its tmalloc: "can't allocate N bytes")."""


class RunWatch:
    """Called by the sandbox about once a second with ngspice's process id and the seconds
    since its start: stops the run past ``max_memory`` (bytes of resident memory) and
    reports the elapsed time and memory to ``progress`` every ``report_every`` seconds.

    ngspice grows its vectors by reallocation, a large step at once (its resident memory
    went from 620 MB to 1.37 GB within a second of a run: the watch alone cannot hold it).
    So at its first look (a tenth of a second after the start) the watch also caps
    ngspice's address space (Linux ``prlimit(RLIMIT_AS)``) at its size then plus the
    budget: an allocation past that fails in ngspice, which stops with "can't allocate"
    (:meth:`allocation_failure` makes that the same MemoryBudgetError). The budget then
    bounds the growth of ngspice's address space; its resident memory can reach its
    address space at the start (about 200 MB for ngspice-39, mostly libraries and
    reserved heap) plus the budget.

    Attributes
    ----------
    peak : int
        The largest resident memory read, bytes.
    cap : int or None
        The address-space limit set on ngspice, bytes (None: none set).
    """

    def __init__(
        self,
        max_memory: float | None,
        tstop: float | None,
        progress: Callable[[str], None] | None,
        report_every: float = 10.0,
    ):
        self.max_memory, self.tstop, self.progress = max_memory, tstop, progress
        self.peak = 0
        self.cap: int | None = None
        self.report_every = report_every
        self._next_report = report_every

    def __call__(self, pid: int, elapsed: float) -> None:
        """Look at process ``pid``, ``elapsed`` seconds after its start (see the class)."""
        if self.cap is None and self.max_memory is not None:
            self._cap(pid)
        held = process_memory(pid)
        if held is not None:
            self.peak = max(self.peak, held)
            if self.max_memory is not None and held > self.max_memory:
                raise MemoryBudgetError(
                    self.max_memory, None, self.tstop or 0.0, None, held,
                    f"ngspice was stopped; {NGSPICE_MEMORY_REMEDIES}", "ngspice's resident memory",
                )  # fmt: skip
        if self.progress is not None and elapsed >= self._next_report:
            memory = f", {size_text(held)} resident" if held is not None else ""
            self.progress(f"ngspice: running for {elapsed:.0f} s{memory}")
            self._next_report += self.report_every

    def _cap(self, pid: int) -> None:
        """Limit ``pid``'s address space to its present size plus the budget (soft limit
        only, which any process may lower for its own children)."""
        size = process_memory(pid, "VmSize")
        if size is None or resource is None or not hasattr(resource, "prlimit"):
            return
        cap = int(size + self.max_memory)
        try:
            _, hard = resource.prlimit(pid, resource.RLIMIT_AS)
            if hard != resource.RLIM_INFINITY:
                cap = min(cap, hard)
            resource.prlimit(pid, resource.RLIMIT_AS, (cap, hard))
        except (OSError, ValueError):
            return
        self.cap = cap

    def allocation_failure(self, log: str) -> MemoryBudgetError | None:
        """The MemoryBudgetError of a run that ngspice's log says failed to allocate under
        the cap, or None."""
        if self.cap is None or not ALLOCATION_FAILED.search(log):
            return None
        return MemoryBudgetError(
            self.max_memory, None, self.tstop or 0.0, None, max(self.peak, self.max_memory),
            f"ngspice could not allocate more; {NGSPICE_MEMORY_REMEDIES}",
            "ngspice's memory",
        )  # fmt: skip


def _default_max_steps() -> int:
    from circuitsim.solver.options import SimulationOptions

    return SimulationOptions.__dataclass_fields__["max_steps"].default


@dataclass
class RunLimits:
    """The guards of one ngspice run (``run_ngspice(..., limits=...)``).

    Attributes
    ----------
    max_steps : int or None
        A ``.tran`` needing more steps than this at least is refused (default: the builtin
        engine's ``SimulationOptions.max_steps``; None: no limit).
    max_memory : float or None
        Bytes: a ``.tran`` recording more at least is refused, and ngspice is stopped when
        its resident memory passes it (default: ``default_memory_budget()``; None: none).
    signals : int or None
        The signals ngspice records (every node and branch; the builtin engine's count of
        the same circuit is a close lower bound); None: not known, 1 is assumed (the memory
        is then watched while ngspice runs rather than refused before).
    progress : callable or None
        Receives the size before the run and a line about every ``report_every`` seconds
        while ngspice runs.
    report_every : float
        Seconds between progress lines (default 10).
    """

    max_steps: int | None = field(default_factory=_default_max_steps)
    max_memory: float | None = field(default_factory=default_memory_budget)
    signals: int | None = None
    progress: Callable[[str], None] | None = None
    report_every: float = 10.0

    def before_run(self, lines: list[str]) -> RunWatch:
        """Check the deck's ``.tran`` (``lines``; none: nothing to check), report its size,
        and return the watch of the run (raises as :func:`checked_size`)."""
        size = checked_size(lines, self.signals or 1, self.max_steps, self.max_memory)
        if size is not None and self.progress is not None:
            self.progress(f"ngspice {size.describe(self.max_steps, self.max_memory)}")
        tstop = None if size is None else size.tstop
        return RunWatch(self.max_memory, tstop, self.progress, self.report_every)
