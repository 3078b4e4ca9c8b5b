"""One comparison case: model -> circuit -> engine -> physical traces, against the ODE.

    System --synthesize/generate--> Circuit + ScaleMap + BOM --engine--> Waveforms
       |                                                                    |
       +--solve (kink events)--> reference traces        map_waveforms <----+
                                        \\___________ compare_traces ___________/

Used by ``circuitsim compare`` (one case) and by the reproduction of the paper's results
(many cases, several processes).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from circuitsim.compare.comparison import Comparison, Thresholds, compare_traces
from circuitsim.compare.errors import ComparisonError
from circuitsim.compare.mapping import Trace, map_waveforms
from circuitsim.mechanics.system import System
from circuitsim.solver.waveforms import Waveforms

ENGINES = ("builtin", "ngspice")

#: Reference samples per model second. The ODE's dense output is exact to its tolerance; the
#: samples only need to be dense enough for the cubic-spline resampling (10 Hz: 400 per period).
REFERENCE_RATE = 4000.0


class EngineUnavailable(ComparisonError):
    """The engine cannot run here (not installed, not built yet); the message says why."""


def engine_available(engine: str) -> str | None:
    """None when ``engine`` can run here, else the reason it cannot."""
    if engine == "ngspice":
        from circuitsim.interop.ngspice import ngspice_available

        return None if ngspice_available() else "ngspice is not installed"
    if engine == "builtin":
        try:
            from circuitsim.solver import simulate  # noqa: F401
        except ImportError as exc:
            return f"the builtin solver cannot be imported ({exc})"
        return None
    return f"unknown engine {engine!r} (choose {', '.join(ENGINES)})"


def run_engine(
    engine: str,
    circuit,
    netlist: str | os.PathLike | None = None,
    ngspice_timeout: float | None = None,
) -> Waveforms:
    """Simulate with ``engine``: ``"builtin"`` (our MNA solver) or ``"ngspice"``.

    Parameters
    ----------
    engine : str
    circuit : Circuit
        The circuit with its ``.tran``.
    netlist : path, optional
        The written netlist; ngspice runs the file itself when given (what the file says is
        what is simulated), the builtin engine the Circuit object.
    ngspice_timeout : float, optional
        Seconds before ngspice is stopped (default: ``run_ngspice``'s, 300 s).

    Raises
    ------
    EngineUnavailable
        The engine is not installed or not importable.
    """
    reason = engine_available(engine)
    if reason is not None:
        raise EngineUnavailable(reason)
    if engine == "ngspice":
        from circuitsim.interop.ngspice import DEFAULT_TIMEOUT, run_ngspice

        timeout = DEFAULT_TIMEOUT if ngspice_timeout is None else ngspice_timeout
        return run_ngspice(Path(netlist) if netlist is not None else circuit, timeout=timeout)
    from circuitsim.solver import simulate

    return simulate(circuit)


def reference_traces(
    system: System, t_stop: float, rate: float = REFERENCE_RATE, max_step: float | None = None
):
    """Solve the model directly and sample it densely.

    ``max_step`` (model seconds, default unbounded) is the direct solution's largest step.

    Returns
    -------
    result : OdeResult
        The direct solution (``circuitsim.mechanics.solve``, rtol 1e-10).
    traces : dict of str to (ndarray, ndarray)
        Per state ``(t, values)`` on a uniform grid over [0, t_stop], model seconds.
    """
    from circuitsim.mechanics import solve

    result = solve(system, t_span=(0.0, t_stop), max_step=max_step)
    t = np.linspace(0.0, t_stop, int(round(rate * t_stop)) + 1)
    x = result.sol(t)
    return result, {state: (t, x[i]) for i, state in enumerate(result.states)}


@dataclass
class CaseResult:
    """A circuit compared with the direct solution.

    Attributes
    ----------
    comparison : Comparison
    reference, circuit : dict of str to (ndarray, ndarray)
        Per state ``(t, values)`` in model seconds and physical units.
    synthesis : Synthesis
        Circuit, scale map and BOM.
    report : MappingReport or None
        The netlist's mapping check (critical speed of model and realized circuit).
    engine : str
    timings : dict of str to float
        Wall seconds of ``reference``, ``synthesis``, ``simulation``, ``comparison``; with
        the builtin engine also ``kernels`` (its compiled kernels made ready before the
        simulation: :func:`circuitsim.solver.compiled.warm_up`).
    netlist : Path or None
        The written netlist, if one was written.
    """

    comparison: Comparison
    reference: dict[str, Trace]
    circuit: dict[str, Trace]
    synthesis: object
    report: object
    engine: str
    timings: dict[str, float] = field(default_factory=dict)
    netlist: Path | None = None


def run_case(
    system: System,
    options=None,
    engine: str = "ngspice",
    thresholds: Thresholds | None = None,
    netlist: str | os.PathLike | None = None,
    n_points: int = 4096,
    label: str = "",
    ngspice_timeout: float | None = None,
    max_step: float | None = None,
) -> CaseResult:
    """Generate the circuit of ``system``, simulate it with ``engine``, compare with the ODE.

    Parameters
    ----------
    system : System
        The scenario (from ``Model.system``).
    options : SynthesisOptions, optional
        Translator options (op-amp kind, series, t_stop ...).
    engine : str
        ``"builtin"`` or ``"ngspice"``.
    thresholds : Thresholds, optional
        Default: :meth:`Thresholds.for_opamp` of the options' op-amp.
    netlist : path, optional
        Write the netlist (with its scale file and BOM) here and simulate that file.
    n_points : int
        Common-grid points of the comparison.
    label : str
    ngspice_timeout : float, optional
        Seconds before ngspice is stopped (default 300).
    max_step : float, optional
        Largest step of the direct solution, model seconds (default unbounded).

    Raises
    ------
    EngineUnavailable, ComparisonError, SynthesisError, SolverError, NgspiceError
    """
    from circuitsim.synthesis.check import check_mapping
    from circuitsim.synthesis.options import SynthesisOptions
    from circuitsim.synthesis.translator import synthesize

    options = options or SynthesisOptions()
    thresholds = thresholds or Thresholds.for_opamp(options.opamp)
    reason = engine_available(engine)
    if reason is not None:
        raise EngineUnavailable(reason)
    timings = {}
    started = time.perf_counter()
    if netlist is not None:
        from circuitsim.synthesis.generate import generate

        generated = generate(system, netlist, options)
        synthesis, report, written = generated.synthesis, generated.report, generated.netlist
    else:
        synthesis = synthesize(system, options)
        report = check_mapping(synthesis.circuit, synthesis.scale_map, system, bom=synthesis.bom)
        written = None
    timings["synthesis"] = time.perf_counter() - started

    if engine == "builtin":  # its compiled kernels loaded (or built) outside the timing
        from circuitsim.solver.compiled import warm_up

        ready = warm_up()
        if ready is not None:
            timings["kernels"] = ready
    started = time.perf_counter()
    waves = run_engine(engine, synthesis.circuit, written, ngspice_timeout)
    timings["simulation"] = time.perf_counter() - started
    circuit = map_waveforms(waves, synthesis.scale_map, list(system.states))

    started = time.perf_counter()
    _, reference = reference_traces(system, synthesis.t_stop, max_step=max_step)
    timings["reference"] = time.perf_counter() - started

    started = time.perf_counter()
    units = dict(zip(system.states, system.units, strict=False))
    comparison = compare_traces(reference, circuit, thresholds, n_points, units, label)
    timings["comparison"] = time.perf_counter() - started
    return CaseResult(comparison, reference, circuit, synthesis, report, engine, timings, written)
