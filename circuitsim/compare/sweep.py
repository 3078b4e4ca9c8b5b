"""Parameter sweeps of the equivalent circuit: many variants, each its own run, peak |state|.

    Systems (one per value) --synthesize once, rescale the changed parts--> Circuits
        --simulate (builtin: threads) or ngspice (processes), one run per variant-->
        peak |y| over a late window and over the whole run --> CSV + bifurcation-style plot
        (:mod:`.sweep_plot`)

The variants share one translation: the amplitude scaling is fixed from the direct solution's
peaks at the sweep's ends and middle, resistors are exact (no E-series rounding: turning the
paper's potentiometers), and a variant differs from the base circuit only in the resistors
whose model coefficient (an entry of A) changes - for the wheelset's speed, R33 and R44. When a
parameter changes anything else (forcing, constants, flange terms) every variant is translated
on its own, with the same scaling.
"""

from __future__ import annotations

import copy
import math
import os
import re
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from circuitsim.compare.errors import ComparisonError
from circuitsim.compare.sweep_measure import (
    Eta,
    Executor,
    InProcess,
    VariantMeasure,
    VariantOutcome,
    summed_stats,
)
from circuitsim.mechanics.system import System
from circuitsim.netlist.circuit import Circuit, Resistor
from circuitsim.synthesis.options import SWING_LIMIT, SynthesisOptions
from circuitsim.synthesis.scalemap import ScaleMap
from circuitsim.synthesis.scaling import direct_solution
from circuitsim.synthesis.translator import synthesize

Progress = Callable[[float, str], None]
"""Progress callback: fraction done (0..1) and a short message."""

# a node at this fraction of the op-amps' swing or above has clipped (a clipped output
# stays just below the swing: 12.87 V for the TL074 model's 13 V)
CLIPPED = 0.95
_A_ENTRY = re.compile(r"A\[(\w+), (\w+)\]")
# a forcing input's resistor (synthesis/inputs.py: "forcing 1 -> y_dot integrator ...")
_FORCING_ENTRY = re.compile(r"^forcing (\d+) -> \w+ integrator \(direction\[(\w+)\]\)")


@dataclass
class SweepCircuits:
    """The variants' circuits and what they share.

    Attributes
    ----------
    circuits : list of Circuit
        One per value, same topology.
    scale_map : ScaleMap
        Shared by every variant.
    changed : list of str
        Elements whose values differ between variants (``["R33", "R44"]`` for the speed).
    ranges : dict of str to float
        State peaks (SI units) the shared scaling was set from.
    rescaled : bool
        True when variants were made by rescaling the base circuit's resistors.
    """

    circuits: list[Circuit]
    scale_map: ScaleMap
    changed: list[str]
    ranges: dict[str, float]
    rescaled: bool


def _same_input(a, b) -> bool:
    """Whether two forcing inputs make the same circuit up to their resistors: both absent
    from it (a peak of 0 places no generator), or equal but for the size of their direction
    entries (same signs: each entry is one resistor from the generator)."""
    if a.peak == 0 and b.peak == 0:
        return True
    if type(a) is not type(b):
        return False
    da, db = np.asarray(a.direction, dtype=float), np.asarray(b.direction, dtype=float)
    return np.array_equal(np.sign(da), np.sign(db)) and a.same_as(replace(b, direction=da))


def _same_except_a(a: System, b: System) -> bool:
    """Whether ``b``'s circuit is ``a``'s with other resistors: systems that differ only in
    the size of entries of A (the same entries nonzero, with the same signs: an entry that is
    0 in one has no resistor) and of forcing directions."""
    if a.states != b.states or len(a.forcing) != len(b.forcing):
        return False
    if not np.array_equal(np.sign(np.asarray(a.A)), np.sign(np.asarray(b.A))):
        return False
    if not np.array_equal(np.asarray(a.b0), np.asarray(b.b0)):
        return False
    if (a.x0 is None) != (b.x0 is None) or (
        a.x0 is not None and not np.array_equal(np.asarray(a.x0), np.asarray(b.x0))
    ):
        return False
    if not all(_same_input(fa, fb) for fa, fb in zip(a.forcing, b.forcing, strict=True)):
        return False
    if len(a.nonlinear) != len(b.nonlinear):
        return False
    return all(repr(ta) == repr(tb) for ta, tb in zip(a.nonlinear, b.nonlinear, strict=True))


def _coefficient(role: str, system: System) -> float | None:
    """The model coefficient a resistor's role names: an entry of A, or a forcing input's
    direction entry; None for any other role."""
    states = list(system.states)
    found = _A_ENTRY.search(role)
    if found is not None:
        return float(system.A[states.index(found.group(1)), states.index(found.group(2))])
    found = _FORCING_ENTRY.search(role)
    if found is not None:
        force = system.forcing[int(found.group(1)) - 1]
        return float(np.asarray(force.direction)[states.index(found.group(2))])
    return None


def _rescaled(base, base_system: System, system: System) -> Circuit | None:
    """Base circuit with each coefficient resistor (A entry, forcing direction) scaled by
    old/new coefficient; None if not possible."""
    circuit = copy.deepcopy(base.circuit)
    for entry in base.bom:
        if entry.unit != "ohm":
            continue
        old = _coefficient(entry.role, base_system)
        if old is None:
            continue
        new = _coefficient(entry.role, system)
        if old == new:
            continue
        if new == 0 or np.sign(new) != np.sign(old):
            return None  # the resistor would move to the other node or vanish
        element = circuit.element(entry.part)
        if not isinstance(element, Resistor):
            return None
        element.resistance = float(element.resistance) * old / new
    return circuit


def sweep_circuits(
    systems: Sequence[System], options: SynthesisOptions | None = None
) -> SweepCircuits:
    """Translate every system into a circuit of one shared topology and scaling.

    Parameters
    ----------
    systems : sequence of System
        The scenario at each swept value.
    options : SynthesisOptions, optional
        Translator options; ``series`` is forced to ``"exact"`` and, for auto scaling without
        user ranges, ``ranges`` to the largest peaks of the first, middle and last systems.
    """
    options = replace(options or SynthesisOptions(), series="exact")
    middle = systems[len(systems) // 2]
    ranges = dict(options.ranges)
    t_stop = float(options.t_stop or (middle.circuit_hints or {}).get("t_stop", 5.0))
    trajectory = None  # the middle value's direct solution, for its node peaks as well
    if options.scaling == "auto" and len(ranges) < middle.n:
        probes = {0: systems[0], len(systems) // 2: middle, len(systems) - 1: systems[-1]}
        peaks = np.zeros(middle.n)
        for system in probes.values():
            solution = direct_solution(system, t_stop)
            if system is middle:
                trajectory = solution
            peaks = np.maximum(peaks, np.max(np.abs(solution[1]), axis=1))
        for name, peak in zip(middle.states, peaks, strict=True):
            ranges.setdefault(name, float(peak) if peak > 0 else 1.0)
        options = replace(options, ranges=ranges)
    base = synthesize(middle, options, trajectory=trajectory)
    circuits: list[Circuit] = []
    rescaled = all(_same_except_a(middle, s) for s in systems)
    for system in systems:
        circuit = _rescaled(base, middle, system) if rescaled else None
        if circuit is None:
            rescaled = rescaled and system is middle
            # the shared scaling is fixed: no direct solution per variant (it predicted
            # node peaks only, which the sweep measures)
            circuit = synthesize(system, options, peaks=False).circuit
        circuits.append(circuit)
    # by name: variants translated on their own may have other elements (an entry of A that
    # is 0 in some has no resistor there)
    elements = [{e.name: e for e in c.elements} for c in circuits]
    names = list(dict.fromkeys(n for c in circuits for n in (e.name for e in c.elements)))
    changed = [n for n in names if any(e.get(n) != elements[0].get(n) for e in elements[1:])]
    return SweepCircuits(circuits, base.scale_map, changed, ranges, rescaled)


@dataclass
class SweepResult:
    """Peak |state| against the swept parameter.

    Attributes
    ----------
    parameter : str
        The swept parameter's name (``"V"``).
    unit : str
        Its unit.
    values : ndarray, shape (k,)
    state : str
        The state measured (``"y"``), in ``state_unit``.
    peak_late, peak_all : ndarray, shape (k,)
        max |state| over the last ``window`` model seconds and over the whole run.
    engine : str
        ``"builtin"`` or ``"ngspice"`` (either: one run per variant).
    window : float
        Model seconds of the late window.
    critical : float or None
        The linear critical value of the parameter (marked on the plot), if known.
    changed : list of str
        Elements that differ between variants.
    timings : dict of str to float
        Wall seconds of ``synthesis`` and ``simulation``; for the builtin engine also
        ``kernels``: making its compiled kernels ready before the simulation (built on their
        first use after an install, else loaded from numba's disk cache; not in
        ``simulation``).
    stats : dict
        Engine statistics (time points, Newton iterations ...).
    traces : dict of int to (ndarray, ndarray)
        The state's (t, values) of the variants asked for with ``keep``.
    warnings : list of str
        States whose node went beyond the op-amps' swing in some variants (they clipped
        there; checked for op-amps with a finite swing, every state probed).
    resistors : dict of str to ndarray, shape (k,)
        Ohms of each changed resistor per value (the wheelset's speed: R33 and R44, the
        settings a knob turns; exact values, the sweep does not round).
    """

    parameter: str
    unit: str
    values: np.ndarray
    state: str
    state_unit: str
    peak_late: np.ndarray
    peak_all: np.ndarray
    engine: str
    window: float
    critical: float | None = None
    changed: list[str] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    traces: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    resistors: dict[str, np.ndarray] = field(default_factory=dict)

    def csv_text(self) -> str:
        """``<parameter>,peak_late,peak_all[,<R> (ohm) ...]`` header and one row per value,
        full precision; one column per changed resistor."""

        def unit(text: str) -> str:
            return f" ({text})" if text else ""

        header = (
            f"{self.parameter}{unit(self.unit)},max_abs_{self.state}_last_{self.window:g}s"
            f"{unit(self.state_unit)},max_abs_{self.state}_all{unit(self.state_unit)}"
            + "".join(f",{name} (ohm)" for name in self.resistors)
        )
        # repr: the shortest text that reads back as the same double (55.5, not 55.50000000001)
        rows = [
            f"{float(v)!r},{float(a)!r},{float(b)!r}"
            + "".join(f",{float(ohms[k])!r}" for ohms in self.resistors.values())
            for k, (v, a, b) in enumerate(
                zip(self.values, self.peak_late, self.peak_all, strict=True)
            )
        ]
        return "\n".join([header, *rows]) + "\n"


def run_sweep(
    systems: Sequence[System],
    values: np.ndarray,
    parameter: str,
    unit: str = "",
    engine: str = "builtin",
    options: SynthesisOptions | None = None,
    state: str | None = None,
    window: float = 1.0,
    workers: int | None = None,
    progress: Progress | None = None,
    keep: Sequence[int] = (),
    ngspice_timeout: float | None = None,
    executor: Executor | None = None,
    describe: Callable[..., str] | None = None,
) -> SweepResult:
    """Simulate the circuit of every system and measure the peak |state|.

    Parameters
    ----------
    systems : sequence of System
        One per entry of ``values``.
    values : ndarray, shape (k,)
        The swept parameter's values.
    parameter, unit : str
        Its name and unit (for the CSV and plot).
    engine : {"builtin", "ngspice"}
        builtin: each variant is its own run of the compiled kernel ``simulate``'s
        ``kernel="auto"`` chooses for the base circuit (the same steps and, to round-off, the
        same values as simulating that variant's circuit alone; ``stats["kernels"]`` names
        it), ``workers`` threads at a time;
        ngspice: one ngspice process per variant, ``workers`` at a time.
    options : SynthesisOptions, optional
    state : str, optional
        State to measure (default: the first, the wheelset's y).
    window : float
        Late window, model seconds.
    workers : int, optional
        Simulations at a time (default: ``os.cpu_count()``).
    progress : callable(fraction, message), optional
    keep : sequence of int
        Indices of variants whose mapped state trace to keep in ``SweepResult.traces``.
    ngspice_timeout : float, optional
        Seconds before each variant's ngspice run is stopped (default 300).
    executor : Executor, optional
        Runs the builtin engine's variants (default :class:`~circuitsim.compare.
        sweep_measure.InProcess` with ``workers`` threads; :mod:`circuitsim.studies.
        execution` has one for a Dask cluster). Every variant is run against the base
        circuit (the middle value's), whichever executor runs it.
    describe : callable(index[, last]), optional
        Names variant ``index`` (or those from ``index`` to ``last``) in warnings (default:
        by value, ``"61"`` and ``"V 50 to 61 m/s"``).

    Raises
    ------
    ComparisonError, SynthesisError, SolverError, NgspiceError
    """
    if len(systems) != len(values):
        raise ComparisonError("run_sweep: one system per value is needed")
    state = state or systems[0].states[0]
    if state not in systems[0].states:
        raise ComparisonError(f"state {state!r} is not one of {', '.join(systems[0].states)}")
    state_unit = systems[0].units[list(systems[0].states).index(state)] if systems[0].units else ""
    workers = max(1, int(workers or os.cpu_count() or 1))
    timings: dict[str, float] = {}
    started = time.perf_counter()
    variants = sweep_circuits(systems, options)
    timings["synthesis"] = time.perf_counter() - started
    if progress:
        count = f"{len(values)} variant{'' if len(values) == 1 else 's'}"
        progress(0.0, f"{count}; changed: {', '.join(variants.changed) or 'none'}")
    limit = SWING_LIMIT[(options or SynthesisOptions()).opamp]
    # with a finite swing every state node is probed, to tell where a variant clipped
    probed = list(systems[0].states) if math.isfinite(limit) else [state]
    nodes = [variants.scale_map.states[s].node for s in probed]
    measure = VariantMeasure(
        variants.scale_map, state, window, tuple(nodes), frozenset(int(k) for k in keep)
    )
    if engine == "builtin":
        from circuitsim.solver.compiled import warm_up
        from circuitsim.solver.variants import variants_kernel

        # the kernel simulate's auto chooses for the base circuit (every batch chooses so)
        kernel = variants_kernel(variants.circuits[len(variants.circuits) // 2])
        ready = warm_up((kernel,))
        if ready is not None:
            timings["kernels"] = ready
    started = time.perf_counter()
    if engine == "builtin":
        outcomes = _run_builtin(variants, measure, executor or InProcess(workers), progress)
        stats = summed_stats(outcomes)
        # an executor's own figures (a cluster's batches, workers, retries), or the threads
        stats.update(getattr(executor, "stats", None) or {"threads": workers})
    elif engine == "ngspice":
        outcomes, stats = _run_ngspice(variants, measure, workers, progress, ngspice_timeout)
    else:
        raise ComparisonError(f"unknown engine {engine!r} (choose builtin or ngspice)")
    timings["simulation"] = time.perf_counter() - started
    node_peaks = np.array([o.node_peaks for o in outcomes], dtype=float).reshape(len(outcomes), -1)
    warnings = _clipped(node_peaks, nodes, probed, limit, options, describe or _values_text(
        values, parameter, unit
    ))
    traces = {k: outcomes[k].trace for k in keep}
    return SweepResult(
        parameter=parameter,
        unit=unit,
        values=np.asarray(values, dtype=float),
        state=state,
        state_unit=state_unit,
        peak_late=np.array([o.peak_late for o in outcomes]),
        peak_all=np.array([o.peak_all for o in outcomes]),
        engine=engine,
        window=window,
        changed=variants.changed,
        timings=timings,
        stats=stats,
        traces=traces,
        warnings=warnings,
        resistors=_changed_resistors(variants),
    )


def _changed_resistors(variants: SweepCircuits) -> dict[str, np.ndarray]:
    """Ohms of every changed resistor that every variant has, per variant (netlist order)."""
    found = {}
    by_name = [{e.name: e for e in c.elements} for c in variants.circuits]
    for name in variants.changed:
        elements = [c.get(name) for c in by_name]
        if all(isinstance(e, Resistor) for e in elements):
            found[name] = np.array([float(e.resistance) for e in elements])
    return found


def _values_text(values, parameter: str, unit: str) -> Callable[..., str]:
    """Names variants by their value: ``(k)`` gives ``"61"``, ``(j, k)`` ``"V 50 to 61 m/s"``."""

    def describe(first: int, last: int | None = None) -> str:
        if last is None:
            return f"{float(values[first]):g}"
        return f"{parameter} {float(values[first]):g} to {float(values[last]):g} {unit}".rstrip()

    return describe


def _clipped(node_peaks, nodes, states, limit, options, describe) -> list[str]:
    """A warning per state whose node reached the op-amps' output swing ``limit`` (V; within
    CLIPPED) in some variants: an output that clips stays just under it. ``node_peaks``:
    shape (variants, nodes), volts; ``describe(k)`` names variant k, ``describe(j, k)`` the
    variants from j to k."""
    if not math.isfinite(limit):
        return []
    found = []
    for column, (state, node) in enumerate(zip(states, nodes, strict=True)):
        volts = node_peaks[:, column]
        reached = np.flatnonzero(volts >= CLIPPED * limit)
        if reached.size:
            worst = int(np.argmax(volts))
            found.append(
                f"state {state} ({node}) reached the {options.opamp} op-amp's output swing "
                f"(about {limit:g} V) in {reached.size} of {len(volts)} variants "
                f"({describe(int(reached[0]), int(reached[-1]))}; "
                f"{volts[worst]:.3g} V at {describe(worst)}): it clipped there. The scaling "
                "was set from the first, middle and last values: sweep a narrower range"
            )
    return found


def _run_builtin(
    variants: SweepCircuits, measure: VariantMeasure, executor: Executor, progress
) -> list[VariantOutcome]:
    """Every variant as its own compiled run (:func:`~circuitsim.solver.variants.
    simulate_variants`: the steps of its single run), resistor changes taken from the base
    circuit (the middle one), run by ``executor``."""
    eta = Eta(getattr(executor, "label", "builtin"))

    def advance(done: int, total: int) -> None:
        if progress:
            progress(done / total, eta.message(done, total))

    base = variants.circuits[len(variants.circuits) // 2]
    return executor(variants.circuits, base, measure, advance)


def _run_ngspice(
    variants: SweepCircuits,
    measure: VariantMeasure,
    workers: int,
    progress: Progress | None,
    timeout: float | None = None,
):
    from circuitsim.interop.ngspice import DEFAULT_TIMEOUT, run_ngspice
    from circuitsim.interop.sandbox import private_folder

    probes = measure.probes
    total = len(variants.circuits)
    waves: list = [None] * total
    # a private folder: removed however the sweep ends, and by the next run after a SIGKILL
    with private_folder("circuitsim-sweep-") as folder:
        from circuitsim.netlist.writer import save_netlist

        paths = []
        for k, circuit in enumerate(variants.circuits):
            path = Path(folder) / f"variant_{k:04d}.cir"
            save_netlist(circuit, path, "ngspice")
            paths.append(path)
        with ThreadPoolExecutor(max_workers=workers) as pool:
            limit = DEFAULT_TIMEOUT if timeout is None else timeout
            futures = {pool.submit(run_ngspice, p, probes, limit): k for k, p in enumerate(paths)}
            try:
                for done, future in enumerate(as_completed(futures), start=1):
                    k = futures[future]
                    waves[k] = measure(k, future.result())
                    if progress:
                        progress(done / total, f"ngspice: {done} of {total} variants")
            except BaseException:  # an error, Ctrl-C, SIGTERM: start no further variant
                pool.shutdown(wait=True, cancel_futures=True)
                raise
    points = [o.stats["time_points"] for o in waves]
    return waves, {"processes": total, "workers": workers, "time_points": int(np.sum(points))}
