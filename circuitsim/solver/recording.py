"""Guards on a run's recorded results: every value finite, the table within its memory budget.

Each transient loop records a table of accepted points (time, then the recorded signals). A
value that became inf or NaN is a failed run (:class:`NonFiniteError`, naming the first
signal and time), not results; a table that would pass ``SimulationOptions.max_memory`` stops
the run (:class:`MemoryBudgetError`) before the machine runs out of memory. The loops call
these between chunks of steps (the compiled ones) or per accepted point (the reference one),
never inside a Newton iteration.
"""

from __future__ import annotations

import mmap
from collections.abc import Mapping, Sequence

import numpy as np

from circuitsim.netlist.run_size import BYTES_PER_VALUE, MEMORY_REMEDIES
from circuitsim.solver.errors import MemoryBudgetError, NonFiniteError

CHECK_VALUES = 1 << 18
"""Values checked at a time (2 MB): the check's temporaries stay in the cache."""

LAZY_TABLE_BYTES = 16 << 20
"""A table from this size on (16 MiB) is mapped memory of its own (:func:`zero_table`);
below it, ``np.zeros``: a fresh mapping costs a page fault per page written, which a heap
block used before does not (runs repeated in one process: docs/robustness.md)."""


def zero_table(shape: int | tuple[int, ...]) -> np.ndarray:
    """A zero float64 array of ``shape`` whose memory costs only the pages written.

    From :data:`LAZY_TABLE_BYTES` on it is an anonymous memory map of its own (the kernel's
    zero pages until written, returned to the system when the array goes): ``np.zeros`` of
    the same size may come from the C heap, zeroed there page by page and kept by the heap
    after it is freed (glibc raises its mapping threshold after a large block is freed),
    which doubled a recording run's peak. (Above 32 MiB glibc maps every block anyway.)
    """
    count = int(np.prod(shape))
    if count * BYTES_PER_VALUE < LAZY_TABLE_BYTES:
        return np.zeros(shape)
    mapped = mmap.mmap(-1, count * BYTES_PER_VALUE)
    return np.frombuffer(mapped, dtype=np.float64).reshape(shape)


def first_non_finite(table: np.ndarray, start: int = 0, stop: int | None = None) -> int | None:
    """The first row of ``table[start:stop]`` (shape (m,) or (m, k)) holding inf or NaN, as
    an index into ``table``, or None.

    A block's sum is not finite when any of its values is not (or when finite values overflow
    the sum); only such a block is searched value by value. The sum reads the values once and
    makes no temporary array.
    """
    stop = table.shape[0] if stop is None else stop
    width = int(np.prod(table.shape[1:])) or 1
    block = max(1, CHECK_VALUES // width)
    for first in range(start, stop, block):
        part = table[first : min(first + block, stop)]
        with np.errstate(over="ignore", invalid="ignore"):
            total = np.sum(part)
        if np.isfinite(total):
            continue
        bad = ~np.isfinite(part.reshape(part.shape[0], -1)).all(axis=1)
        if bad.any():
            return first + int(np.argmax(bad))
    return None


def non_finite_error(
    names: Sequence[str], times: np.ndarray, table: np.ndarray, row: int
) -> NonFiniteError:
    """The error for ``table``'s row ``row`` (at ``times[row]``, s): its first signal (of
    ``names``, one per column) that is not finite, with that signal's last finite value."""
    values = table[row]
    column = int(np.argmax(~np.isfinite(values)))
    history = table[:row, column]
    finite = np.flatnonzero(np.isfinite(history))
    last = float(history[finite[-1]]) if finite.size else None
    return NonFiniteError(names[column], float(times[row]), float(values[column]), last)


def diverged_iterate(system, x: np.ndarray, time: float) -> NonFiniteError:
    """The error of a step whose last Newton iterate ``x`` (every unknown) is not finite
    at ``time`` (s): the solution diverged there (the step was not accepted)."""
    index = int(np.argmax(~np.isfinite(x)))
    return NonFiniteError(system.layout.unknowns[index], time, float(x[index]))


def check_finite(signals: Mapping[str, np.ndarray], times: np.ndarray) -> None:
    """Raise :class:`NonFiniteError` for the earliest point where a signal is inf or NaN
    (``signals``: name to values at ``times``, s; ngspice's results, say)."""
    earliest = None
    for name, values in signals.items():
        row = first_non_finite(np.asarray(values))
        if row is not None and (earliest is None or row < earliest[0]):
            earliest = (row, name)
    if earliest is not None:
        row, name = earliest
        values = np.asarray(signals[name])
        finite = np.flatnonzero(np.isfinite(values[:row]))
        last = float(values[finite[-1]]) if finite.size else None
        raise NonFiniteError(name, float(times[row]), float(values[row]), last)


def row_bytes(columns: int) -> int:
    """Bytes of one recorded point: the time and ``columns`` values."""
    return BYTES_PER_VALUE * (columns + 1)


def budget_rows(max_memory: float | None, columns: int, copies: int = 1) -> int | None:
    """Recorded points that fit ``max_memory`` (bytes; None: no budget) when the table of
    ``columns`` signals is held ``copies`` times."""
    if max_memory is None:
        return None
    return max(1, int(max_memory // (copies * row_bytes(columns))))


def memory_error(
    max_memory: float, time: float, tstop: float, points: int, held: float
) -> MemoryBudgetError:
    """The error of a recorder that reached its budget at ``time`` (s) with ``points``
    points in ``held`` bytes."""
    return MemoryBudgetError(max_memory, time, tstop, points, held, MEMORY_REMEDIES)
