"""What a sweep keeps of each variant's run, and the in-process way of running them.

A variant's traces are reduced where it ran (in its worker thread, or on a cluster's worker) to
a few numbers: the peak |state| over the late window and over the whole run, and the peak
|voltage| of every probed state node (to tell where an op-amp clipped). Only those travel back,
so that a study of thousands of variants holds no traces, and a cluster sends kilobytes.

An *executor* runs a list of variant circuits and returns one :class:`VariantOutcome` each, in
order: :func:`run_in_process` (threads, the default), or the Dask executor of
:mod:`circuitsim.studies.execution` (batches on a cluster), which runs each batch with
:func:`measure_batch` too, so that both give the same numbers bit for bit.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple, Protocol

import numpy as np

from circuitsim.compare.mapping import map_waveforms
from circuitsim.netlist.circuit import Circuit
from circuitsim.synthesis.scalemap import ScaleMap

Advance = Callable[[int, int], None]
"""Called with (variants done, variants in all)."""

# per-variant engine statistics summed over a sweep (the rest stay per variant)
SUMMED_STATS = ("accepted", "rejected", "newton_iterations")


class VariantOutcome(NamedTuple):
    """One variant's measurements.

    Attributes
    ----------
    peak_late, peak_all : float
        max |state| (the state's SI unit) over the late window and over the whole run.
    node_peaks : tuple of float
        max |v(node)|, volts, of each probed node (:attr:`VariantMeasure.nodes`).
    stats : dict
        The engine's counts for this variant (accepted and rejected steps, Newton
        iterations, time points, wall seconds, whether it ran from the shared start).
    trace : (ndarray, ndarray) or None
        The state's (t, values) when the variant's index is in :attr:`VariantMeasure.keep`.
    """

    peak_late: float
    peak_all: float
    node_peaks: tuple[float, ...]
    stats: dict
    trace: tuple[np.ndarray, np.ndarray] | None = None


@dataclass(frozen=True)
class VariantMeasure:
    """How a variant's waveforms become a :class:`VariantOutcome` (picklable: it travels to
    a cluster's workers with the circuits).

    Attributes
    ----------
    scale_map : ScaleMap
        Maps node voltages back to states (shared by every variant).
    state : str
        The state measured.
    window : float
        Late window, model seconds.
    nodes : tuple of str
        The probed state nodes (the measured state's among them).
    keep : frozenset of int
        Variant indices whose state trace is kept.
    """

    scale_map: ScaleMap
    state: str
    window: float
    nodes: tuple[str, ...]
    keep: frozenset[int] = field(default_factory=frozenset)

    @property
    def probes(self) -> list[str]:
        """The signals recorded: ``v(node)`` of each probed node."""
        return [f"v({node})" for node in self.nodes]

    def __call__(self, index: int, waves) -> VariantOutcome:
        """Measure variant ``index``'s waveforms (its index in the whole sweep)."""
        t, values = map_waveforms(waves, self.scale_map, [self.state])[self.state]
        late = t >= t[-1] - self.window
        node_peaks = tuple(float(np.max(np.abs(waves[p]))) for p in self.probes)
        stats = {k: v for k, v in waves.stats.items() if k in (*SUMMED_STATS, "kernel")}
        stats["time_points"] = len(waves.time)
        stats["wall_time_s"] = float(waves.stats.get("wall_time_s", 0.0))
        stats["shared_start"] = bool(waves.stats.get("shared_start", False))
        return VariantOutcome(
            float(np.max(np.abs(values[late]))),
            float(np.max(np.abs(values))),
            node_peaks,
            stats,
            (t, values) if index in self.keep else None,
        )


class Executor(Protocol):
    """Runs variant circuits of one base and measures each (the builtin engine)."""

    def __call__(
        self,
        circuits: Sequence[Circuit],
        base: Circuit,
        measure: VariantMeasure,
        advance: Advance | None,
    ) -> list[VariantOutcome]: ...  # pragma: no cover - a protocol


def measure_batch(
    circuits: Sequence[Circuit],
    base: Circuit,
    measure: VariantMeasure,
    first: int = 0,
    threads: int = 1,
    advance: Advance | None = None,
) -> list[VariantOutcome]:
    """Simulate a batch of variants (:func:`~circuitsim.solver.variants.simulate_variants`,
    the resistor changes taken from ``base``) and measure each as it ends.

    Parameters
    ----------
    circuits : sequence of Circuit
        The batch.
    base : Circuit
        The study's base circuit (the same for every batch: a variant's values then do not
        depend on how the study was split).
    measure : VariantMeasure
    first : int
        The batch's first variant's index in the study (for ``measure.keep``).
    threads : int
        Variants run at once.
    advance : callable(done, total), optional
        Counts within the batch.
    """
    from circuitsim.solver.variants import simulate_variants

    return simulate_variants(
        circuits,
        measure.probes,
        workers=threads,
        progress=advance,
        base=base,
        reduce=lambda k, waves: measure(first + k, waves),
    )


@dataclass
class InProcess:
    """The default executor: every variant in this process, ``threads`` at a time (the
    compiled loop releases the GIL)."""

    threads: int = 1

    def __call__(self, circuits, base, measure, advance=None) -> list[VariantOutcome]:
        return measure_batch(circuits, base, measure, 0, self.threads, advance)


class Eta:
    """Progress messages with the time left, from the rate so far.

    Parameters
    ----------
    label : str
        What runs (``"builtin"``, ``"dask (2 workers)"``).
    """

    def __init__(self, label: str) -> None:
        self.label = label
        self.started = time.perf_counter()

    def message(self, done: int, total: int) -> str:
        """``"<label>: 30 of 100 variants, 12 s left"`` (no estimate before the first)."""
        text = f"{self.label}: {done} of {total} variants"
        if 0 < done < total:
            left = (time.perf_counter() - self.started) / done * (total - done)
            text += f", {_duration(left)} left"
        return text


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def summed_stats(outcomes: Sequence[VariantOutcome]) -> dict:
    """The sweep's engine statistics: counts summed over the variants."""
    stats: dict = {"variants": len(outcomes)}
    for key in (*SUMMED_STATS, "time_points"):
        stats[key] = int(sum(o.stats.get(key, 0) for o in outcomes))
    stats["variant_wall_s"] = float(sum(o.stats.get("wall_time_s", 0.0) for o in outcomes))
    stats["shared_start"] = int(sum(bool(o.stats.get("shared_start")) for o in outcomes))
    kernels = {str(o.stats["kernel"]) for o in outcomes if "kernel" in o.stats}
    if kernels:
        stats["kernels"] = sorted(kernels)
    return stats
