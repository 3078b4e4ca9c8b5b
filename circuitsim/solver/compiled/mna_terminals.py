"""The multi-terminal devices in the compiled MNA Newton (mna_newton.py): load, stamp,
right-hand side and current check of every JFET, BJT and nonlinear POLY source.

Each element is linearized at the iterate by its family's kernel twin (devices/jfet_kernel.py,
bjt_kernel.py, poly_kernel.py), which writes its terminal currents I_t and slopes g_tc at the
controls v_c (terminal_plan.TerminalState); from those this module adds, as
devices/terminals.py's TerminalStamp does, g_tc at (row t, column c+) and -g_tc at (row t,
column c-) into the assembled matrix (the sparse LU's extra entries) and sum_c g_tc v_c - I_t
to the right-hand side of row t, and checks SPICE's device current test at the new iterate
(terminals.current_converged). Each function takes the plan's and the state's terminal tuples
and loops over the elements itself: one call per Newton iteration, not one per element. They
are compiled once, not inlined into the Newton loop (inlining the device equations there
doubled the kernel's first compile); the twins' ``load`` are inlined here.
"""

from __future__ import annotations

from circuitsim.solver.compiled.terminal_plan import BJT, JFET
from circuitsim.solver.devices import bjt_kernel, jfet_kernel, poly_kernel
from circuitsim.solver.jit import njit


@njit(cache=True)
def load_terminals(tp, ts, x_ext, a0, hist, q, qdot) -> int:
    """Linearize every element at ``x_ext`` (charges integrated with a0 and the history
    ``hist`` into the slots' q, qdot); returns how many limited a voltage (noncon)."""
    noncon = 0
    for k in range(tp.kind.size):
        kind = tp.kind[k]
        if kind == JFET:
            noncon += jfet_kernel.load(tp, ts, k, x_ext, a0, hist, q, qdot)
        elif kind == BJT:
            noncon += bjt_kernel.load(tp, ts, k, x_ext, a0, hist, q, qdot)
        else:
            noncon += poly_kernel.load(tp, ts, k, x_ext)
    return noncon


@njit(cache=True)
def stamp_terminals(tp, ts, extra_pos, a_val) -> None:
    """Add the elements' entries to the assembled values ``a_val`` (positions ``extra_pos``
    of the sparse LU, in terminal_plan.entry_pattern's order)."""
    slope = ts.slope
    for k in range(tp.kind.size):
        e = tp.entry[k]
        for t in range(tp.nterm[k]):
            for c in range(tp.nctrl[k]):
                g = slope[k, t, c]
                if extra_pos[e] >= 0:
                    a_val[extra_pos[e]] += g
                if extra_pos[e + 1] >= 0:
                    a_val[extra_pos[e + 1]] -= g
                e += 2
        if tp.rb[k]:  # the modulated base resistance: a conductance outer base - base'
            g = ts.rb_g[k]
            for j in range(4):
                if extra_pos[e + j] >= 0:
                    a_val[extra_pos[e + j]] += g if j < 2 else -g


@njit(cache=True)
def terminal_rhs(tp, ts, b) -> None:
    """Add the companion currents sum_c g_tc v_c - I_t to each terminal's row of ``b``."""
    for k in range(tp.kind.size):
        for t in range(tp.nterm[k]):
            row = tp.rows[k, t]
            if row < 0:
                continue
            linear = 0.0
            for c in range(tp.nctrl[k]):
                linear += ts.slope[k, t, c] * ts.vlin[k, c]
            b[row] += linear - ts.cur[k, t]


@njit(cache=True)
def terminals_converged(tp, ts, x_ext, reltol) -> bool:
    """SPICE's device current check (terminals.current_converged) of every element at the
    new iterate ``x_ext``."""
    ctrl = tp.ctrl
    for k in range(tp.kind.size):
        for t in range(tp.nterm[k]):
            delta = 0.0
            for c in range(tp.nctrl[k]):
                v_new = x_ext[ctrl[k, c, 0]] - x_ext[ctrl[k, c, 1]]
                delta += ts.slope[k, t, c] * (v_new - ts.vlin[k, c])
            current = ts.cur[k, t]
            if abs(delta) > reltol * max(abs(current + delta), abs(current)) + tp.tol[k]:
                return False
    return True
