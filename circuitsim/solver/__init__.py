"""MNA engine: flattens a Circuit, assembles it, and runs ``.op``, ``.tran`` and ``.ac``.

Public API::

    simulate(circuit, options=None, progress=None, probes=None, analysis=None) -> Waveforms
    ac_analysis(circuit, sweep=None, options=None, probes=None) -> Waveforms
    operating_point(circuit, options=None) -> Waveforms
    transient(circuit, tstep, tstop, tstart=0, tmax=None, uic=False, options=None,
              progress=None) -> Waveforms
    SimulationOptions (ngspice defaults; SimulationOptions.from_circuit reads .options)

See docs/solver.md for the method and its measured accuracy against ngspice.
"""

from circuitsim.solver.engine import ac_analysis, operating_point, simulate, transient
from circuitsim.solver.options import SimulationOptions

__all__ = ["SimulationOptions", "ac_analysis", "operating_point", "simulate", "transient"]
