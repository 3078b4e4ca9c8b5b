"""Making the compiled kernels ready before timed work (compiled, or loaded from the cache)."""

from __future__ import annotations

import time

import numpy as np

# A circuit with every device kind the kernels compile for: a junction with charge, a
# switch, a capacitor and a sine source (numba compiles one machine code for all circuits).
WARM_UP_NETLIST = """* kernel warm-up
V1 in 0 SIN(0 1 1k)
R1 in a 1k
D1 a b DW
C1 b 0 1u
S1 b 0 in 0 SW1
.model DW D(is=1e-14 cjo=1p tt=1n)
.model SW1 SW(vt=0.5 ron=1 roff=1g)
.tran 10u 200u
.end
"""


def warm_up(kernels: tuple[str, ...] = ("ports",)) -> float | None:
    """Make the compiled ``kernels`` ready in this process: built on their first use after
    an install (minutes, announced by a KernelCompileWarning, then kept in the user cache
    directory: compiled/cache.py, with the start-up library's module of each kernel:
    compiled/startup_library.py), loaded from the cache after that (about half a second).
    Call it before timing runs, so that their times do not include it. Returns the seconds
    it took; None without numba (nothing to make ready: ``kernel="auto"`` then
    runs the numpy loop).

    Raises
    ------
    CircuitInputError
        An unknown kernel.
    """
    from circuitsim.solver.jit import numba_installed

    if not numba_installed():
        return None

    from circuitsim.netlist.reader import parse_netlist
    from circuitsim.solver.compiled.runner import run_compiled, run_ports
    from circuitsim.solver.compiled.startup_library import build_when_missing
    from circuitsim.solver.errors import CircuitInputError
    from circuitsim.solver.float_text import table_text
    from circuitsim.solver.options import SimulationOptions
    from circuitsim.solver.system import MnaSystem

    started = time.perf_counter()
    circuit = parse_netlist(WARM_UP_NETLIST)
    tran = circuit.transient
    runners = {"ports": run_ports, "compiled": run_compiled}
    for kernel in kernels:
        if kernel not in runners:
            raise CircuitInputError(
                f"warm_up: no compiled kernel {kernel!r}; expected one of {', '.join(runners)}"
            )
        system = MnaSystem(circuit, SimulationOptions.from_circuit(circuit, kernel=kernel))
        runners[kernel](system, tran.tstep, tran.tstop, tran.tstart, tran.tmax, tran.uic)
        build_when_missing(kernel)  # the start-up library's module too (once; announced)
    if kernels:  # the CSV writer (with its start-up library module), as a simulate process uses it
        table_text(np.zeros((1, 1)))
    return time.perf_counter() - started
