"""MNA engine: flattens a Circuit, assembles it, and runs ``.op`` and ``.tran``.

Public API::

    simulate(circuit, options=None, progress=None) -> Waveforms
    operating_point(circuit, options=None) -> Waveforms
    transient(circuit, tstep, tstop, tstart=0, tmax=None, uic=False, options=None,
              progress=None) -> Waveforms
    SimulationOptions (ngspice defaults; SimulationOptions.from_circuit reads .options)

See docs/solver.md for the method and its measured accuracy against ngspice.
"""

from circuitsim.solver.engine import operating_point, simulate, transient
from circuitsim.solver.options import SimulationOptions

__all__ = ["SimulationOptions", "operating_point", "simulate", "transient"]
