"""Many variants of one circuit: each its own ports-kernel run, a few at a time in threads.

A parameter sweep simulates circuits that differ only in element values. Each variant runs
exactly what ``simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="ports"))``
runs (same options, same time steps, same Newton iterates), but records only the probed
signals (formed row by row, so their values equal the single run's to round-off). A run of more
than 20,000 attempted steps returns to Python every 20,000 attempts (``fixed_pauses``: its
values do not depend on the machine's speed or load), where a single run does so by the
clock; each return restarts the loop's local caches, so such runs agree to round-off. And
``workers`` variants run at once in threads: the compiled loop releases the GIL, so the
threads use separate cores without the start-up and pickling of worker processes.
"""

from __future__ import annotations

import os
import time as _time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from circuitsim.netlist.circuit import Circuit, Resistor
from circuitsim.netlist.names import fold
from circuitsim.solver.engine import build_system
from circuitsim.solver.errors import CircuitInputError
from circuitsim.solver.jit import use_numba
from circuitsim.solver.threads import single_threaded_blas
from circuitsim.solver.waveforms import Waveforms

Progress = Callable[[int, int], None]
"""Called with (variants done, variants in all) after each variant."""

Reduce = Callable[[int, Waveforms], object]
"""Called in the worker thread with (variant index, its waveforms); its value is kept instead."""


def simulate_variants(
    circuits: Sequence[Circuit],
    probes: Sequence[str],
    workers: int | None = None,
    progress: Progress | None = None,
    base: Circuit | None = None,
    reduce: Reduce | None = None,
) -> list:
    """The ``.tran`` of every circuit on the ports kernel, only ``probes`` recorded.

    Variants that differ from the base circuit (``base``, else the first) only in the values
    of top-level resistors, with a ``uic`` transient (a sweep's), share its assembly, start
    and plan: each is run with its own constant matrix G (``MnaSystem.conductances_with``,
    equal bit for bit to assembling it), which saves the set-up that would otherwise hold
    the GIL for about as long as a fifth of a short run. Any other variant (one whose
    capacitors, sources or analysis differ) is assembled on its own. With ``base`` given,
    which of the two ways a variant runs depends on it and the base only, so that a study
    split into batches (each with the same base) gives the values of one call for all.

    Parameters
    ----------
    circuits : sequence of Circuit
        Each with a ``.tran``; usually one topology with different values.
    probes : sequence of str
        Signal names as in :attr:`Waveforms.signals` (``"v(y)"``, ``"i(v1)"``).
    workers : int, optional
        Variants simulated at once (threads; default ``os.cpu_count()``).
    progress : callable(done, total), optional
    base : Circuit, optional
        The circuit the variants' resistor changes are taken from (default: the first).
    reduce : callable(index, Waveforms), optional
        Applied to each variant's waveforms in its worker thread as soon as it ends (the
        index counts ``circuits`` from 0); its results are returned instead, so that a long
        study need not hold every trace at once.

    Returns
    -------
    list of Waveforms (or of ``reduce``'s results)
        In the order of ``circuits``; ``stats["wall_time_s"]`` is each variant's own time
        (its share of a shared start not included).

    Raises
    ------
    CircuitInputError
        A circuit without ``.tran``, one the ports kernel cannot run, or an unknown probe
        (the message names the variant, counted from 0).
    ConvergenceError, SingularMatrixError
        With a note naming the variant.
    """
    from circuitsim.solver.compiled import check_cache

    probes = [fold(p) for p in probes]
    total = len(circuits)
    workers = max(1, min(int(workers or os.cpu_count() or 1), max(total, 1)))
    if workers > 1:  # the start-up library's functions hold the GIL; numba's release it
        use_numba()
    check_cache()  # once, here, before threads would race for it
    reference = base if base is not None else (circuits[0] if total else None)
    changes = [resistor_changes(reference, c) for c in circuits] if total else []
    shared = None
    enough = 1 if base is not None else 2  # the first circuit alone needs no shared start
    if sum(c is not None for c in changes) >= enough and reference.transient is not None:
        if reference.transient.uic:
            try:
                shared = _shared_start(reference, probes)
            except Exception as error:
                where = "the base circuit" if base is not None else "variant 0 (0-based)"
                error.add_note(f"in {where}")
                raise
    results: list = [None] * total
    with single_threaded_blas(), ThreadPoolExecutor(max_workers=workers) as pool:
        futures = {}
        for k, circuit in enumerate(circuits):
            if shared is not None and changes[k] is not None and shared.names >= changes[k].keys():
                futures[pool.submit(_one_shared, shared, changes[k], probes, k, reduce)] = k
            else:
                futures[pool.submit(_one, circuit, probes, k, reduce)] = k
        for done, future in enumerate(as_completed(futures), start=1):
            k = futures[future]
            try:
                results[k] = future.result()
            except Exception as error:
                for pending in futures:
                    pending.cancel()
                error.add_note(f"in variant {k} (0-based)")
                raise
            if progress is not None:
                progress(done, total)
    return results


def resistor_changes(base: Circuit, other: Circuit) -> dict[str, float] | None:
    """The top-level resistors whose values differ, name to ohm, if ``other`` is ``base``
    with only such changes (numbers, not expressions); else None."""
    if other is base:
        return {}
    same = (
        other.models == base.models
        and other.subcircuits == base.subcircuits
        and other.params == base.params
        and other.analyses == base.analyses
        and other.initial_conditions == base.initial_conditions
        and other.options == base.options
        and len(other.elements) == len(base.elements)
    )
    if not same:
        return None
    changes: dict[str, float] = {}
    for a, b in zip(base.elements, other.elements, strict=True):
        if a == b:
            continue
        if type(a) is not Resistor or type(b) is not Resistor:
            return None
        if isinstance(b.resistance, bool) or not isinstance(b.resistance, int | float):
            return None
        if replace(a, resistance=b.resistance) != b:
            return None
        changes[b.name] = float(b.resistance)
    return changes


class _Shared(NamedTuple):
    start: object  # compiled.PortsStart
    index: list[int]  # each probe's unknown (-1: ground)
    rows: np.ndarray  # the unknowns recorded
    names: frozenset  # the assembled elements' names (a variant's changes must be among them)


def _checked_system(circuit: Circuit, probes: list[str], k: int):
    """The variant's assembled system, its probes' unknowns and the recorded rows."""
    from circuitsim.solver.compiled import kernel_unavailable

    if circuit.transient is None:
        raise CircuitInputError(f"variant {k}: the circuit has no .tran")
    system = build_system(circuit, None, kernel="ports")
    reason = kernel_unavailable(system, "ports")
    if reason is not None:
        raise CircuitInputError(f"variant {k}: the ports kernel cannot run it: {reason}")
    unknown = [p for p in probes if p not in system.signals]
    if unknown:
        raise CircuitInputError(
            f"variant {k}: no signal {', '.join(unknown)} (known: {', '.join(system.signals)})"
        )
    index = [system.signals[p] for p in probes]
    rows = np.array([i for i in index if i >= 0], dtype=np.int64)
    return system, index, rows


def _shared_start(circuit: Circuit, probes: list[str]) -> _Shared:
    from circuitsim.solver.compiled import ports_start

    system, index, rows = _checked_system(circuit, probes, 0)
    tran = circuit.transient
    start = ports_start(system, tran.tstep, tran.tstop, tran.tstart, tran.tmax, tran.uic)
    names = frozenset(name for family in system.families for name in family.names)
    return _Shared(start, index, rows, names)


def _one_shared(
    shared: _Shared, changes: dict[str, float], probes: list[str], k: int, reduce: Reduce | None
):
    """One variant of the first circuit's resistor values (in a worker thread)."""
    from circuitsim.solver.compiled import run_ports_from

    started = _time.perf_counter()
    system = shared.start.system
    G = system.conductances_with(changes) if changes else None
    stats: dict = {"analysis": "tran", "newton_iterations": 0}
    times, values = run_ports_from(shared.start, G, shared.rows, stats, fixed_pauses=True)
    stats["shared_start"] = True
    waves = _waveforms(system, times, values, probes, shared.index, stats, started)
    return waves if reduce is None else reduce(k, waves)


def _one(circuit: Circuit, probes: list[str], k: int, reduce: Reduce | None):
    """One variant's run (in a worker thread)."""
    from circuitsim.solver.compiled import run_ports

    started = _time.perf_counter()
    system, index, rows = _checked_system(circuit, probes, k)
    tran = circuit.transient
    stats: dict = {"analysis": "tran", "newton_iterations": 0}
    times, values = run_ports(
        system,
        tran.tstep,
        tran.tstop,
        tran.tstart,
        tran.tmax,
        tran.uic,
        None,
        stats,
        rows=rows,
        fixed_pauses=True,
    )
    stats["factorizations"] = system.factorizations
    stats["shared_start"] = False
    waves = _waveforms(system, times, values, probes, index, stats, started)
    return waves if reduce is None else reduce(k, waves)


def _waveforms(system, times, values, probes, index, stats, started) -> Waveforms:
    signals = {}
    column = 0
    for name, i in zip(probes, index, strict=True):
        if i >= 0:
            signals[name] = values[:, column]
            column += 1
        else:
            signals[name] = np.zeros(times.size)
    stats["unknowns"] = system.size
    stats["method"] = system.options.method
    stats["wall_time_s"] = _time.perf_counter() - started
    return Waveforms(time=times, signals=signals, engine="builtin", stats=stats)
