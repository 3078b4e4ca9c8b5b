"""Kernel twin of poly.py: one nonlinear POLY(n) source linearized at the iterate, for the
compiled MNA kernel.

The equations of ``_Polynomials.evaluate`` and ``_PolyFamily.load`` for one element: the
polynomial P (SPICE 2G6's term order, the term table of the terminal plan) and its slopes at
the controlling voltages or branch currents; a current output (G, F) drives P from n+ to n-
(terminal currents P, -P), a voltage output (E, H) enters its branch row as -P. No limiting.
"""

from __future__ import annotations

from circuitsim.solver.jit import njit

# terminal plan kinds of the two outputs (compiled/terminal_plan.py)
CURRENT_OUTPUT, VOLTAGE_OUTPUT = 0, 1


@njit(cache=True, inline="always")
def load(tp, ts, k, x_ext) -> int:
    """Linearize POLY source ``k`` (a row of the terminal plan ``tp``) at ``x_ext``, writing
    ts.cur/slope/vlin; returns 0 (nothing is limited)."""
    ctrl, power, coefficient = tp.ctrl, tp.term_pow, tp.term_coef
    cur, slope, vlin = ts.cur, ts.slope, ts.vlin
    nc = tp.nctrl[k]
    for c in range(nc):
        vlin[k, c] = x_ext[ctrl[k, c, 0]] - x_ext[ctrl[k, c, 1]]
        slope[k, 0, c] = 0.0
    value = 0.0
    for t in range(tp.term_ptr[k], tp.term_ptr[k + 1]):
        product = 1.0
        for c in range(nc):
            product *= vlin[k, c] ** power[t, c]
        value += coefficient[t] * product
        for c in range(nc):  # d/dx_c of the term: e x_c^(e-1) times the other factors
            e = power[t, c]
            if e == 0:
                continue
            others = 1.0
            for d in range(nc):
                if d != c:
                    others *= vlin[k, d] ** power[t, d]
            slope[k, 0, c] += coefficient[t] * e * vlin[k, c] ** (e - 1) * others
    if tp.kind[k] == VOLTAGE_OUTPUT:  # the branch row: x[p] - x[n] + I = 0 with I = -P
        cur[k, 0] = -value
        for c in range(nc):
            slope[k, 0, c] = -slope[k, 0, c]
    else:  # into n+, out of n-
        cur[k, 0], cur[k, 1] = value, -value
        for c in range(nc):
            slope[k, 1, c] = -slope[k, 0, c]
    return 0
