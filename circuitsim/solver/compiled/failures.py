"""The compiled loops' failures as the engine's typed errors (what solver/transient.py raises)."""

from __future__ import annotations

import numpy as np

from circuitsim.solver.errors import ConvergenceError, RunLimitError, SolverError
from circuitsim.solver.linalg import SingularPivot, factor
from circuitsim.solver.recording import diverged_iterate
from circuitsim.solver.system import MnaSystem


def worst_junction(system: MnaSystem, fail_v: np.ndarray) -> str:
    """The junction whose voltage moved most (relative to its tolerance) in the last Newton
    iteration, as ``"a-k"`` node names (``fail_v``: that iterate and the one before, (2, md))."""
    options = system.options
    new, old = fail_v
    tol = options.reltol * np.maximum(np.abs(new), np.abs(old)) + options.vntol
    k = int(np.argmax(np.abs(new - old) / tol))
    p = np.concatenate([f.port_nodes[0] for f in system.nonlinear if f.port_nodes is not None])
    n = np.concatenate([f.port_nodes[1] for f in system.nonlinear if f.port_nodes is not None])
    names = system.layout.unknowns

    def name(i: int) -> str:
        return "0" if i < 0 else names[i][2:-1] if names[i].startswith("v(") else names[i]

    return f"{name(int(p[k]))}-{name(int(n[k]))}"


def singular_row(matrix: np.ndarray) -> int | None:
    """The unknown whose pivot vanishes in the matrix the kernel failed to invert."""
    try:
        factor(matrix.copy())
    except SingularPivot as exc:
        return exc.index
    return None


def failure(system: MnaSystem, st, status: int, tstop: float) -> SolverError:
    """The error of a loop that returned ``status`` (step_control.py's codes)."""
    from circuitsim.solver.compiled import newton as nw
    from circuitsim.solver.compiled import step_control as tr

    t, h = float(st.fs[nw.T]), float(st.fs[nw.H])
    if status == tr.TOO_MANY_STEPS:
        options = system.options
        return RunLimitError("max_steps", options.max_steps, t, tstop, options.max_steps)
    messages = {
        tr.NEWTON_FAILED_FIXED: "Newton failed at the fixed step",
        tr.STEP_TOO_SMALL: "time step too small",
        tr.STEP_TOO_SMALL_LTE: "time step too small (truncation error)",
    }
    node = None
    fail_x = getattr(st, "fail_x", None)  # the ports kernel keeps junction voltages only
    if fail_x is not None and not np.all(np.isfinite(fail_x)):
        return diverged_iterate(system, fail_x, t + h)
    if fail_x is not None:
        node = system.worst_unknown(st.fail_x, st.fail_prev)
    elif fail_x is None and st.fail_v.size and np.all(np.isfinite(st.fail_v)):
        node = worst_junction(system, st.fail_v)
    return ConvergenceError(messages[status], time=t + h, step=h, node=node)
