"""Circuits and results made elsewhere, compared with the ODE through a scale file.

Two inputs that :func:`~circuitsim.compare.case.run_case` (which generates its own circuit)
cannot take:

- an existing netlist (hand-edited, or with a vendor op-amp model) with its scale file,
  simulated here with either engine: :func:`run_netlist_case`;
- waveforms produced by another tool, an ngspice raw file say, with the scale file of the
  netlist that produced them: :func:`compare_waveforms`.

Both map node voltages to physical states exactly as ``run_case`` does
(:func:`~circuitsim.compare.mapping.map_waveforms`) and solve the model over the model time
the circuit covered.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

from circuitsim.compare.case import CaseResult, reference_traces, run_engine
from circuitsim.compare.comparison import Thresholds, compare_traces
from circuitsim.compare.errors import ComparisonError
from circuitsim.compare.mapping import map_waveforms
from circuitsim.mechanics.system import System
from circuitsim.solver.waveforms import Waveforms
from circuitsim.synthesis.scalemap import ScaleMap


def compare_waveforms(
    system: System,
    waves: Waveforms,
    scale_map: ScaleMap,
    thresholds: Thresholds | None = None,
    engine: str = "",
    n_points: int = 4096,
    label: str = "",
    timings: dict[str, float] | None = None,
    max_step: float | None = None,
) -> CaseResult:
    """Compare any engine's transient ``waves`` with the direct solution of ``system``.

    Parameters
    ----------
    system : System
        The scenario the circuit realizes (its states must be in the scale map).
    waves : Waveforms
        A transient result holding ``v(node)`` of every state node; time in circuit seconds.
    scale_map : ScaleMap
        The netlist's scale file.
    thresholds : Thresholds, optional
        Default: those of ideal op-amps.
    engine : str
        Who made ``waves`` (for the result).
    max_step : float, optional
        Largest step of the direct solution, model seconds (default unbounded).

    Raises
    ------
    ComparisonError
        A state is not in the scale map, a state node is not in the waveforms, or the
        waveforms cover no time.
    """
    thresholds = thresholds or Thresholds.for_opamp("ideal")
    timings = dict(timings or {})
    if len(waves.time) < 2 or not waves.time[-1] > waves.time[0]:
        raise ComparisonError(
            f"the {engine or 'given'} waveforms cover no time ({len(waves.time)} point(s)); "
            "a transient result is needed"
        )
    circuit = map_waveforms(waves, scale_map, list(system.states))
    t_stop = float(scale_map.model_time(float(waves.time[-1])))
    started = time.perf_counter()
    _, reference = reference_traces(system, t_stop, max_step=max_step)
    timings["reference"] = time.perf_counter() - started
    started = time.perf_counter()
    units = dict(zip(system.states, system.units, strict=False))
    comparison = compare_traces(reference, circuit, thresholds, n_points, units, label)
    timings["comparison"] = time.perf_counter() - started
    return CaseResult(comparison, reference, circuit, None, None, engine, timings)


def run_netlist_case(
    system: System,
    netlist: str | os.PathLike,
    scale_map: ScaleMap,
    engine: str = "builtin",
    thresholds: Thresholds | None = None,
    n_points: int = 4096,
    label: str = "",
    ngspice_timeout: float | None = None,
    max_step: float | None = None,
) -> CaseResult:
    """Simulate the netlist file with ``engine`` and compare it with ``system``'s solution.

    ngspice runs the file itself (stopped after ``ngspice_timeout`` seconds, default 300);
    the builtin engine the circuit our reader makes of it. ``max_step``: the direct
    solution's largest step (model seconds; default unbounded).

    Raises
    ------
    EngineUnavailable, ComparisonError, NetlistError, SolverError, NgspiceError
    """
    netlist = Path(netlist)
    timings: dict[str, float] = {}
    circuit = None
    if engine == "builtin":
        from circuitsim.netlist.reader import read_netlist
        from circuitsim.solver.compiled import warm_up

        circuit = read_netlist(netlist)
        ready = warm_up()
        if ready is not None:
            timings["kernels"] = ready
    started = time.perf_counter()
    waves = run_engine(engine, circuit, netlist, ngspice_timeout)
    timings["simulation"] = time.perf_counter() - started
    result = compare_waveforms(
        system, waves, scale_map, thresholds, engine, n_points, label, timings, max_step
    )
    result.netlist = netlist
    return result
