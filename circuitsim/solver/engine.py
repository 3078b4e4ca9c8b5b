"""Public entry points: simulate, operating_point, transient.

Each accepts any Circuit: subcircuits are flattened (``circuitsim.netlist.flatten``) and
expressions evaluated before assembly. Results are :class:`Waveforms` with ``v(node)`` for
every node of the flattened circuit, subcircuit-internal nodes included under their flattened
names (``v(x1.n3)``), and ``i(vname)`` for every independent voltage source (SPICE sign:
current from n+ through the source to n-). Device-private nodes (a diode's series-resistance
node) are not reported.
"""

from __future__ import annotations

import dataclasses
import time as _time
from collections.abc import Callable

import numpy as np

from circuitsim.netlist.circuit import (
    AcSweep,
    Circuit,
    Expression,
    OperatingPoint,
    SubcircuitCall,
    Transient,
)
from circuitsim.netlist.names import fold
from circuitsim.netlist.run_size import RunSize
from circuitsim.solver.dc import operating_point_solution
from circuitsim.solver.errors import CircuitInputError, RunSizeError
from circuitsim.solver.options import SimulationOptions
from circuitsim.solver.system import MnaSystem
from circuitsim.solver.threads import single_threaded_blas
from circuitsim.solver.transient import check_times, run_transient
from circuitsim.solver.waveforms import Waveforms


def flat_circuit(circuit: Circuit) -> Circuit:
    """``circuit`` with subcircuits expanded and every value a float (no-op if already flat)."""
    from circuitsim.netlist.flatten import flatten

    return flatten(circuit)


def _needs_flatten(circuit: Circuit) -> bool:
    if circuit.subcircuits or circuit.params:
        return True
    for model in circuit.models.values():
        if any(isinstance(v, Expression) for v in model.params.values()):
            return True
    if any(isinstance(v, Expression) for v in circuit.initial_conditions.values()):
        return True
    for element in circuit.elements:
        if isinstance(element, SubcircuitCall):
            return True
        if any(_holds_expression(v) for v in vars(element).values()):
            return True
    return False


def _holds_expression(value) -> bool:
    """An Expression, or a source waveform with one among its arguments (``SIN({a} 1 50)``)."""
    if isinstance(value, Expression):
        return True
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return any(_holds_expression(v) for v in vars(value).values())
    if isinstance(value, tuple):
        return any(_holds_expression(v) for v in value)
    return False


def build_system(circuit: Circuit, options: SimulationOptions | None, **overrides) -> MnaSystem:
    """Flatten if needed, read ``.options`` (then ``overrides``) unless options are given,
    and assemble."""
    flat = flat_circuit(circuit) if _needs_flatten(circuit) else circuit
    if options is None:
        options = SimulationOptions.from_circuit(flat, **overrides)
    return MnaSystem(flat, options)


def probe_names(system: MnaSystem, probes: list[str] | None) -> list[str]:
    """The signal names ``probes`` ask for (case-insensitive, ``"out"`` for ``v(out)``), in
    their order; all signals for None.

    Raises
    ------
    CircuitInputError
        A probe names no signal of the circuit (before any run).
    """
    if probes is None:
        return list(system.signals)
    names, missing = [], []
    for probe in probes:
        key = fold(probe)
        key = key if key in system.signals else f"v({key})"
        if key in system.signals:
            names.append(key)
        else:
            missing.append(probe)
    if missing:
        have = list(system.signals)
        shown = ", ".join(have[:20]) + (f", ... ({len(have)} in all)" if len(have) > 20 else "")
        raise CircuitInputError(f"no signal {', '.join(missing)}; have {shown}")
    return list(dict.fromkeys(names))


def _waveforms(
    system: MnaSystem,
    times: np.ndarray,
    solutions: np.ndarray,
    stats: dict,
    names: list[str] | None = None,
    columns: dict[str, int] | None = None,
):
    """Waveforms of the signals ``names`` (default all); ``columns`` maps an unknown's index
    to its column in ``solutions`` (default: the identity)."""
    signals = {}
    for name in names if names is not None else system.signals:
        index = system.signals[name]
        if index < 0:
            signals[name] = np.zeros(len(times))
        else:
            signals[name] = solutions[:, columns[index] if columns is not None else index]
    stats["factorizations"] = system.factorizations
    stats["unknowns"] = system.size
    stats["method"] = system.options.method
    return Waveforms(time=times, signals=signals, engine="builtin", stats=stats)


def operating_point(
    circuit: Circuit, options: SimulationOptions | None = None, probes: list[str] | None = None
) -> Waveforms:
    """DC operating point (``.op``): one time point at t = 0, of the signals ``probes``
    (default all).

    Raises
    ------
    ConvergenceError, SingularMatrixError, CircuitInputError
    """
    started = _time.perf_counter()
    system = build_system(circuit, options)
    names = probe_names(system, probes)
    stats: dict = {"analysis": "op", "newton_iterations": 0}
    with single_threaded_blas():
        x, _ = operating_point_solution(system, dc_op=True, clamp_ic=False, stats=stats)
    stats["wall_time_s"] = _time.perf_counter() - started
    return _waveforms(system, np.zeros(1), x[None, :], stats, names)


def transient(
    circuit: Circuit,
    tstep: float,
    tstop: float,
    tstart: float = 0.0,
    tmax: float | None = None,
    uic: bool = False,
    options: SimulationOptions | None = None,
    progress: Callable[[str], None] | None = None,
    probes: list[str] | None = None,
    size_report: Callable[[str], None] | None = None,
) -> Waveforms:
    """Transient analysis (``.tran tstep tstop [tstart [tmax]] [uic]``), seconds.

    Returns the solution on the solver's own accepted time points (t >= tstart), of the
    signals ``probes`` (default: all; every loop then records only the unknowns those
    need). ``stats``: accepted, rejected, newton_iterations, factorizations,
    wall_time_s, kernel.

    Raises
    ------
    ConvergenceError, SingularMatrixError, CircuitInputError
        CircuitInputError also for a probe that names no signal (before the run).
    RunLimitError
        The run passed ``options.max_steps``, ``options.max_wall_time`` or
        ``options.max_memory`` (MemoryBudgetError), or was refused before its start as
        certain to pass ``max_steps`` or ``max_memory`` (RunSizeError).
    NonFiniteError
        A recorded signal became inf or NaN (the solution diverged).
    """
    started = _time.perf_counter()
    system = build_system(circuit, options)
    names = probe_names(system, probes)
    stats: dict = {"analysis": "tran", "newton_iterations": 0}
    unknowns = sorted({system.signals[n] for n in names if system.signals[n] >= 0})
    size = _checked_size(system, tstep, tstop, tstart, tmax, len(unknowns))
    stats["run_size"] = size
    if size_report is not None:
        size_report(size.describe(system.options.max_steps, system.options.max_memory))
    runner = _transient_runner(system, stats)
    columns = {index: column for column, index in enumerate(unknowns)}
    extra = {}
    if len(unknowns) < system.size:
        extra["rows"] = np.array(unknowns, dtype=np.int64)
    with single_threaded_blas():
        times, solutions = runner(
            system, tstep, tstop, tstart, tmax, uic, progress=progress, stats=stats, **extra
        )
    stats["wall_time_s"] = _time.perf_counter() - started
    if stats.get("kernel") in ("ports", "compiled"):  # after the run and its timing
        from circuitsim.solver.compiled.startup_library import build_when_missing

        build_when_missing(stats["kernel"])
    if not extra:
        columns = None
    return _waveforms(system, times, solutions, stats, names, columns)


def _checked_size(system: MnaSystem, tstep, tstop, tstart, tmax, recorded: int) -> RunSize:
    """The run's size (``recorded`` unknowns recorded), its times checked; RunSizeError when
    it cannot finish within the step limit or the memory budget."""
    options = system.options
    check_times(tstep, tstop, tstart, tmax)
    size = RunSize.of(tstep, tstop, tstart, tmax, recorded, options.fixed_step)
    refused = size.refusal(options.max_steps, options.max_memory)
    if refused is not None:
        limit, message = refused
        value = options.max_steps if limit == "max_steps" else options.max_memory
        raise RunSizeError(limit, value, tstop, message)
    return size


def _transient_runner(system: MnaSystem, stats: dict):
    """The compiled kernel or the reference loop, as ``system.options.kernel`` asks."""
    if system.options.kernel == "python":
        stats["kernel"] = "python"
        return run_transient
    from circuitsim.solver.compiled.runner import transient_runner

    return transient_runner(system, stats)


def ac_analysis(
    circuit: Circuit,
    sweep: AcSweep | None = None,
    options: SimulationOptions | None = None,
    probes: list[str] | None = None,
) -> Waveforms:
    """Small-signal AC sweep (``.ac``) at the DC operating point (solver/ac.py).

    Parameters
    ----------
    circuit : Circuit
    sweep : AcSweep, optional
        Default: the circuit's first ``.ac`` card.
    options : SimulationOptions, optional
    probes : list of str, optional
        Signals as for :func:`transient` (``v(out)``, ``i(v1)``); each gives a magnitude
        and a phase column (``vm(out)``, ``vp(out)``).

    Returns
    -------
    Waveforms
        ``time`` holds the frequencies, Hz; ``vm``/``vp`` (V, degrees) per node and
        ``im``/``ip`` (A, degrees) per voltage source; ``stats["analysis"] == "ac"``.

    Raises
    ------
    CircuitInputError
        No ``.ac`` card and no sweep given, a bad sweep, or a probe that names no signal.
    ConvergenceError, SingularMatrixError
    """
    from circuitsim.solver.ac import ac_frequencies, ac_signals, ac_solutions

    started = _time.perf_counter()
    if sweep is None:
        sweep = next((a for a in circuit.analyses if isinstance(a, AcSweep)), None)
        if sweep is None:
            raise CircuitInputError("the netlist has no .ac card")
    system = build_system(circuit, options)
    names = probe_names(system, probes)
    frequencies = ac_frequencies(sweep, system.options.reltol)
    stats: dict = {"analysis": "ac", "newton_iterations": 0, "frequencies": frequencies.size}
    with single_threaded_blas():
        x, _ = operating_point_solution(system, dc_op=True, clamp_ic=False, stats=stats)
        solutions = ac_solutions(system, x, frequencies)
    stats["factorizations"] = system.factorizations + frequencies.size
    stats["unknowns"] = system.size
    stats["wall_time_s"] = _time.perf_counter() - started
    signals = ac_signals(system, solutions, names)
    return Waveforms(
        time=frequencies, signals=signals, engine="builtin", stats=stats, axis="frequency"
    )


ANALYSES = ("tran", "op", "ac")


def simulate(
    circuit: Circuit,
    options: SimulationOptions | None = None,
    progress: Callable[[str], None] | None = None,
    probes: list[str] | None = None,
    analysis: str | None = None,
    size_report: Callable[[str], None] | None = None,
) -> Waveforms:
    """Run one of the circuit's analyses: ``analysis`` ("tran", "op" or "ac") if given,
    else its first ``.tran``, else its operating point if it has an ``.op`` card or no
    analysis at all (a circuit built in Python), else its ``.ac`` (ngspice's runner picks
    the same way).

    ``options`` default to ngspice's, overridden by the circuit's ``.options``. ``probes``:
    only these signals (see :func:`transient`; default all); ``size_report``: see
    :func:`transient`.

    Raises
    ------
    CircuitInputError
        ``analysis`` names a kind the netlist has no card for (an operating point is always
        possible), or is unknown.
    """
    kinds = {_KIND[type(a)] for a in circuit.analyses}
    if analysis is None:
        if "tran" in kinds:
            analysis = "tran"
        elif "op" in kinds or not kinds:
            analysis = "op"
        else:
            analysis = "ac"
    if analysis not in ANALYSES:
        raise CircuitInputError(f"unknown analysis {analysis!r}; choose tran, op or ac")
    if analysis != "op" and analysis not in kinds:
        raise CircuitInputError(f"the netlist has no .{analysis} card")
    if analysis == "op":
        return operating_point(circuit, options, probes)
    if analysis == "ac":
        return ac_analysis(circuit, None, options, probes)
    tran = circuit.transient
    return transient(
        circuit,
        tran.tstep,
        tran.tstop,
        tran.tstart,
        tran.tmax,
        tran.uic,
        options,
        progress,
        probes,
        size_report,
    )


_KIND = {Transient: "tran", OperatingPoint: "op", AcSweep: "ac"}
