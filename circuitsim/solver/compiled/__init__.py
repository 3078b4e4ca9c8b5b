"""The compiled transient kernels: the reference engine's algorithm, run by numba.

This package only re-exports. Where things are:

- runner.py: kernel choice (``SimulationOptions.kernel``: ``auto``, ``compiled``, ``ports``,
  ``python``; auto_kernel, from measurements in docs/solver.md), the start of a run and its
  loop in chunks (progress, wall-time limit, a new pivot order when the loop asks);
- time_loop.py + step_control.py: the one time loop (breakpoints, orders, truncation error,
  Newton failures, switch transitions), compiled once per kernel around its steps;
- mna_steps.py + mna_newton.py + sparse_lu.py: the MNA kernel (``kernel="compiled"``: Newton
  on the whole matrix, refactored sparse at every iteration on a fixed pivot order);
- port_steps.py + port_newton.py + ports.py + port_state.py + lowrank.py: the ports kernel
  (Newton on the junction voltages in port_newton.py's named steps, one factorization updated
  at low rank);
- newton.py (the ports kernel's factorization and refactor rule), slots.py (the named slots of
  the run's constants and the loop's state), plan.py (the arrays it runs on); the device
  equations both kernels inline are the families' kernel twins, solver/devices/*_kernel.py;
- cache.py: where numba keeps the machine code (a user cache directory), stale-code removal,
  whether a run must compile first (announced by a KernelCompileWarning);
- failures.py: the loop's return codes as the engine's typed errors;
- warmup.py: making the kernels ready before timed work.

The reference engine stays the specification: tests run both on the same circuits
(tests/solver/test_compiled_kernel.py). Which circuits the kernels take: plan.unsupported.
"""

from __future__ import annotations

from circuitsim.solver.compiled.cache import check_cache, clear_stale_cache
from circuitsim.solver.compiled.runner import (
    PortsStart,
    auto_kernel,
    kernel_unavailable,
    ports_start,
    run_compiled,
    run_ports,
    run_ports_from,
    transient_runner,
)
from circuitsim.solver.compiled.warmup import WARM_UP_NETLIST, warm_up

__all__ = [
    "WARM_UP_NETLIST",
    "PortsStart",
    "auto_kernel",
    "check_cache",
    "clear_stale_cache",
    "kernel_unavailable",
    "ports_start",
    "run_compiled",
    "run_ports",
    "run_ports_from",
    "transient_runner",
    "warm_up",
]
