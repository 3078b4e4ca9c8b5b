"""Compiled Newton iteration of one time point on the whole MNA matrix (sparse_lu.py).

The reference engine's general Newton (solver/newton.py), as ngspice runs it: at every
iteration the devices are linearized at the iterate, the matrix is assembled into its fixed
sparse pattern, refactored numerically (the pivot order is kept; only the columns that the
changed conductances reach, sparse_lu.refactor_marked) and solved. A junction whose
conductance moved by less than ``plan.real[CHORD]`` of the one factored keeps the factored
one, its current exact (a chord step: same solution, the refactor skipped or smaller). Switch states
are re-decided against the accepted state at the first iteration, junctions limited with
pnjlim against the accepted junction voltage at the first iteration and the last
linearization afterwards; convergence when nothing was limited or toggled, every unknown is
within reltol/vntol/abstol of the previous iterate and every junction passes SPICE's current
check. The solve is exact for the matrix stamped (no low-rank update), so there is no
refinement step.
"""

from __future__ import annotations

import numpy as np

from circuitsim.solver.compiled.mna_terminals import (
    load_terminals,
    stamp_terminals,
    terminal_rhs,
    terminals_converged,
)
from circuitsim.solver.compiled.newton import FACTORIZATIONS, RESUME_NONCON, copy_into
from circuitsim.solver.compiled.slots import ABSTOL, CHORD, ITL4, PIVOT_ORDERS, RELTOL
from circuitsim.solver.compiled.sparse_lu import (
    ALL_COLUMNS,
    assemble,
    lu_solve,
    mark_changed,
    refactor,
    refactor_marked,
)
from circuitsim.solver.devices.diode_kernel import linearize_junction
from circuitsim.solver.devices.switch_kernel import (
    CONTROL_NEGATIVE,
    CONTROL_POSITIVE,
    G_OFF,
    G_ON,
    OFF_BELOW,
    ON_ABOVE,
    next_state,
)
from circuitsim.solver.jit import njit

# mna_newton's outcomes besides converged (True) / not converged (False): the pivot order no
# longer suits the matrix (the loop returns to Python, which analyses it again); a pivot
# became too small (the loop returns to Python for a new order at this matrix, then goes on)
CONVERGED, FAILED, REPIVOT, REORDER = 1, 0, 2, 3


# compiled once, inlined by LLVM: inlined by numba three calls deep (time_loop's stub,
# mna_attempt, this), it was typed at each level and the MNA kernel's compile took twice the
# CPU (docs/solver.md, "One time loop")
@njit(cache=True, _nrt=False, forceinline=True)
def mna_newton(plan, st, x0, a0, hist, rhs0, q, qdot, g_sw, x_new, b, resume, x, x_ext):
    """Newton at one time point. Returns (outcome, iterations, x_previous); the last iterate
    is in ``x_new``.

    rhs0 : the x-independent right-hand side (sources, charge history), shape (n,);
    g_sw, b : scratch, shapes (ms,), (n,);
    x, x_ext : scratch, shapes (n,), (n + 1,): the iterate (the last solution), and it
        extended by ground (the returned x_previous is ``x``);
    resume : 0, or the iteration that returned REORDER (re-entered on the new pivot order,
        with its linearization, x_new, q and qdot as it left them).
    """
    reltol, abstol, chord = plan.real[RELTOL], plan.real[ABSTOL], plan.real[CHORD]
    itl4 = plan.ints[ITL4]
    jp, cp, jslot, has_charge, charged = plan.jp, plan.cp, plan.jslot, plan.has_charge, plan.charged
    port_p, port_n, abs_tol = plan.port_p, plan.port_n, plan.abs_tol
    sw, approach, g_switch = plan.sw, plan.approach, plan.g_switch
    vd_accepted, vd, cd, gd, ieq = st.vd_accepted, st.vd, st.cd, st.gd, st.ieq
    state, accepted = st.state, st.accepted
    lu = st.lu
    a_ptr, a_row, a_val, g_val, m_val, port_pos = (
        lu.a_ptr,
        lu.a_row,
        lu.a_val,
        lu.g_val,
        lu.m_val,
        lu.port_pos,
    )
    l_ptr, l_row, l_val, u_ptr, u_row, u_val = (
        lu.l_ptr,
        lu.l_row,
        lu.l_val,
        lu.u_ptr,
        lu.u_row,
        lu.u_val,
    )
    row_to, col_of, work = lu.row_to, lu.col_of, lu.work
    port_reach, port_from, m_reach, extra_reach, factored, redo = (
        lu.port_reach,
        lu.port_from,
        lu.m_reach,
        lu.extra_reach,
        lu.factored,
        lu.redo,
    )
    tp, ts, extra_pos = plan.terms, st.terms, lu.extra_pos  # JFETs, BJTs, POLY: mna_terminals
    ms = sw.shape[0]
    md = jp.shape[0]
    # no junctions, switches or transistors: the first solve is exact (one iteration, as
    # MnaSystem's)
    terminals = tp.kind.size > 0  # (each call with the tuples costs reference counts)
    linear = md == 0 and ms == 0 and not terminals
    n = x0.size
    if resume > 1:  # the iterate (the last solution)
        copy_into(x, x_new)
    else:
        copy_into(x, x0)
    for i in range(n):
        x_ext[i] = x[i]
    x_ext[n] = 0.0
    for iteration in range(max(resume, 1), itl4 + 1):
        first = iteration == 1
        noncon = st.ints[RESUME_NONCON] if iteration == resume else 0
        for k in range(ms if iteration != resume else 0):  # SwitchFamily.update_state
            control = x_ext[sw[k, CONTROL_POSITIVE]] - x_ext[sw[k, CONTROL_NEGATIVE]]
            keep = accepted[k] if first else state[k]
            new = next_state(control, keep, approach[k, ON_ABOVE], approach[k, OFF_BELOW])
            if new != state[k]:
                state[k] = new
                noncon += 1
            g_sw[k] = g_switch[k, G_ON] if state[k] else g_switch[k, G_OFF]
        for k in range(ms if iteration == resume else 0):
            g_sw[k] = g_switch[k, G_ON] if state[k] else g_switch[k, G_OFF]
        for k in range(md if iteration != resume else 0):  # the junctions, linearized at x
            charged_k = has_charge and charged[k]
            slot = jslot[k]
            v, limited, current, conductance, charge, charge_current = linearize_junction(
                jp, cp, k, x_ext[port_p[k]] - x_ext[port_n[k]],
                vd_accepted[k] if first else vd[k], charged_k, a0,
                hist[slot] if charged_k else 0.0,
            )  # fmt: skip
            noncon += limited
            if charged_k:
                q[slot] = charge
                qdot[slot] = charge_current
            if abs(conductance - factored[k]) <= chord * abs(factored[k]):
                conductance = factored[k]  # the chord: the factors' slope, the exact current
            vd[k], cd[k], gd[k] = v, current, conductance
            ieq[k] = current - conductance * v
        if terminals and iteration != resume:
            noncon += load_terminals(tp, ts, x_ext, a0, hist, q, qdot)
        assemble(a_val, g_val, m_val, a0, port_pos, gd, g_sw)
        if terminals:
            stamp_terminals(tp, ts, extra_pos, a_val)
        # the columns whose entries changed since the factors were made, and those their
        # change reaches, are factored again (none, first == n: a repeated step, junctions
        # unchanged)
        first = mark_changed(port_reach, port_from, m_reach, extra_reach, factored, redo, gd,
                             g_sw, a0, n)  # fmt: skip
        small = -1
        if first < n:
            st.ints[FACTORIZATIONS] += 1
        if first == ALL_COLUMNS:
            small = refactor(a_ptr, a_row, a_val, l_ptr, l_row, l_val, u_ptr, u_row, u_val, work,
                             redo, True)  # fmt: skip
        elif first < n:
            small = refactor_marked(a_ptr, a_row, a_val, l_ptr, l_row, l_val, u_ptr, u_row,
                                    u_val, work, redo, first)  # fmt: skip
        if small >= 0:
            factored[-1] = np.nan  # the factors stopped at that column: all of them next
            if iteration == resume:  # on the order made at this very matrix
                return REPIVOT, iteration, x
            # a pivot became too small: a new order at this matrix, and on (ngspice's
            # spOrderAndFactor); in Python (SuperLU), rare
            st.ints[PIVOT_ORDERS] += 1
            st.ints[RESUME_NONCON] = noncon
            return REORDER, iteration, x
        for i in range(n):  # rhs0 - W ieq
            b[i] = rhs0[i]
        for k in range(md):
            if port_p[k] >= 0:
                b[port_p[k]] -= ieq[k]
            if port_n[k] >= 0:
                b[port_n[k]] += ieq[k]
        if terminals:
            terminal_rhs(tp, ts, b)
        lu_solve(l_ptr, l_row, l_val, u_ptr, u_row, u_val, row_to, col_of, b, work, x_new)
        for i in range(n):
            if not np.isfinite(x_new[i]):
                return FAILED, iteration, x
        done = noncon == 0 and (iteration > 1 or linear)
        for i in range(n if done and not linear else 0):  # MnaSystem.close
            if abs(x_new[i] - x[i]) > reltol * max(abs(x_new[i]), abs(x[i])) + abs_tol[i]:
                done = False
                break
        for i in range(n):
            x_ext[i] = x_new[i]
        for k in range(md if done else 0):  # DiodeFamily.port_converged
            delta = gd[k] * (x_ext[port_p[k]] - x_ext[port_n[k]] - vd[k])
            if abs(delta) > reltol * max(abs(cd[k] + delta), abs(cd[k])) + abstol:
                done = False
                break
        if done and terminals and not terminals_converged(tp, ts, x_ext, reltol):
            done = False
        if done:
            return CONVERGED, iteration, x
        if iteration < itl4:  # else x stays the iterate before the last (failure reports)
            for i in range(n):
                x[i] = x_new[i]
    return FAILED, itl4, x
