"""Many variants of one circuit: each its own ports-kernel run, a few at a time in threads.

A parameter sweep simulates circuits that differ only in element values. Each variant runs
exactly what ``simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="ports"))``
runs (same options, same time steps, same Newton iterates), but records only the probed
signals (formed row by row, so their values equal the single run's to round-off), and
``workers`` variants run at once in threads: the compiled loop releases the GIL, so the
threads use separate cores without the start-up and pickling of worker processes.
"""

from __future__ import annotations

import os
import time as _time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed

import numpy as np

from circuitsim.netlist.circuit import Circuit
from circuitsim.solver.engine import build_system
from circuitsim.solver.errors import CircuitInputError
from circuitsim.solver.threads import single_threaded_blas
from circuitsim.solver.waveforms import Waveforms

Progress = Callable[[int, int], None]
"""Called with (variants done, variants in all) after each variant."""


def simulate_variants(
    circuits: Sequence[Circuit],
    probes: Sequence[str],
    workers: int | None = None,
    progress: Progress | None = None,
) -> list[Waveforms]:
    """The ``.tran`` of every circuit on the ports kernel, only ``probes`` recorded.

    Parameters
    ----------
    circuits : sequence of Circuit
        Each with a ``.tran``; usually one topology with different values.
    probes : sequence of str
        Signal names as in :attr:`Waveforms.signals` (``"v(y)"``, ``"i(v1)"``).
    workers : int, optional
        Variants simulated at once (threads; default ``os.cpu_count()``).
    progress : callable(done, total), optional

    Returns
    -------
    list of Waveforms
        In the order of ``circuits``; ``stats["wall_time_s"]`` is each variant's own time.

    Raises
    ------
    CircuitInputError
        A circuit without ``.tran``, one the ports kernel cannot run, or an unknown probe
        (the message names the variant, counted from 0).
    ConvergenceError, SingularMatrixError
        With a note naming the variant.
    """
    from circuitsim.solver.compiled import check_cache

    probes = [p.lower() for p in probes]
    total = len(circuits)
    workers = max(1, min(int(workers or os.cpu_count() or 1), max(total, 1)))
    check_cache()  # once, here, before threads would race for it
    results: list = [None] * total
    with single_threaded_blas(), ThreadPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(_one, circuit, probes, k): k for k, circuit in enumerate(circuits)}
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


def _one(circuit: Circuit, probes: list[str], k: int) -> Waveforms:
    """One variant's run (in a worker thread)."""
    from circuitsim.solver.compiled import kernel_unavailable, run_ports

    started = _time.perf_counter()
    tran = circuit.transient
    if tran is None:
        raise CircuitInputError(f"variant {k}: the circuit has no .tran")
    system = build_system(circuit, None, kernel="ports")
    reason = kernel_unavailable(system)
    if reason is not None:
        raise CircuitInputError(f"variant {k}: the ports kernel cannot run it: {reason}")
    unknown = [p for p in probes if p not in system.signals]
    if unknown:
        raise CircuitInputError(
            f"variant {k}: no signal {', '.join(unknown)} (known: {', '.join(system.signals)})"
        )
    index = [system.signals[p] for p in probes]
    rows = np.array([i for i in index if i >= 0], dtype=np.int64)
    stats: dict = {"analysis": "tran", "newton_iterations": 0}
    times, values = run_ports(
        system, tran.tstep, tran.tstop, tran.tstart, tran.tmax, tran.uic, None, stats, rows=rows
    )
    signals = {}
    column = 0
    for name, i in zip(probes, index, strict=True):
        if i >= 0:
            signals[name] = values[:, column]
            column += 1
        else:
            signals[name] = np.zeros(times.size)
    stats["factorizations"] = system.factorizations
    stats["unknowns"] = system.size
    stats["method"] = system.options.method
    stats["wall_time_s"] = _time.perf_counter() - started
    return Waveforms(time=times, signals=signals, engine="builtin", stats=stats)
