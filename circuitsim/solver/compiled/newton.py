"""Compiled Newton iteration of one time point, at the junction ports (see lowrank.py).

The same iterates and convergence test as the reference engine's ``_newton_at_ports``
(solver/newton.py): switch states re-decided against the accepted state at the first
iteration, junctions limited with pnjlim against the accepted junction voltage at the first
iteration and the last linearization afterwards, convergence when nothing was limited or
toggled, every unknown is within reltol/vntol/abstol of the previous iterate and every
junction passes SPICE's current check; a solution that may be accepted (and every solution
from the third iteration on) is checked by one refinement step against the full matrix.
"""

from __future__ import annotations

import warnings

import numpy as np
from numba import njit, objmode
from numba.core.errors import NumbaWarning

from circuitsim.solver.compiled.devices import junction_charge, junction_current, pnjlim
from circuitsim.solver.compiled.lowrank import (
    active_columns,
    add_u_columns,
    rebuild,
    refine,
    source_solution,
    update,
)
from circuitsim.solver.compiled.sparse_factors import sparse_port_factors
from circuitsim.solver.port_solver import REFINE_FRACTION

# factor_now leaves compiled code for SuperLU holding the GIL (nogil loops run in threads:
# only the factorizations, a few per run, are serialized); numba warns about it when compiling
warnings.filterwarnings("ignore", "Code running in object mode", NumbaWarning)

# a junction current change that moves no unknown by more than this fraction of its absolute
# tolerance (vntol, abstol) is not applied until it grows (junction_response)
JUNCTION_NEGLIGIBLE = 1e-9

# indices into KernelState.fs (floats) and .ints
T, H, SAVED_H, LAST_A0 = 0, 1, 2, 3
ORDER, AT_BREAK, FIRST, BI, ATTEMPTS, ACCEPTED, REJECTED, NEWTON, FACTORIZATIONS = range(9)
NHIST, COUNT, SAME_A0, VERSION, JUNCTION_VERSION = 9, 10, 11, 12, 13
ACTIVE_JUNCTIONS = 14  # the compiled kernel's: junction columns active in the last update
# the loop returns PAUSED once this many steps were attempted, so that the caller can check
# its wall-time limit and Ctrl-C (both loops; slots 15-17 are port_state.py's)
PAUSE_ATTEMPTS = 18
# (both loops) active junctions the last refactor made during the run left, and that
# refactor's VERSION (see rebase_wanted)
AFTER_REFACTOR, MEASURED_VERSION = 19, 20

# When to refactor at the present conductances because many junctions stay active (both
# compiled loops). A factorization made at a solution leaves active only the junctions whose
# conductance keeps changing (those conducting forward: about half of a precision rectifier's);
# a refactor cannot make fewer than that, so the rule is relative to what the last one left:
# more than REBASE_ACTIVE and more than REBASE_GROWTH times that count, at the end of
# REBASE_STEPS accepted steps in a row. A uic start's factorization (every junction at 0 V)
# left nothing measured, so the first refactor comes once more than REBASE_ACTIVE stay active
# (the TL074 wheelset: 0.89 s on that one factorization, 0.09 s after one refactor); the
# absolute count alone refactored every 8 steps from 16 junctions on (docs/solver.md).
REBASE_ACTIVE = 8
REBASE_GROWTH = 2


@njit(cache=True, inline="always")
def rebase_wanted(active, after_refactor):
    """Whether ``active`` junction columns in the last Newton iteration of an accepted step
    are many more than the ``after_refactor`` a refactor at a solution left (0: none yet)."""
    return active > REBASE_ACTIVE and active > REBASE_GROWTH * after_refactor


@njit(cache=True, inline="always")
def extend(x, x_ext):
    """x_ext[:n] = x, x_ext[n] = 0 (ground, reached by node index -1)."""
    x_ext[: x.size] = x
    x_ext[x.size] = 0.0


@njit(cache=True)
def all_finite(x) -> bool:
    """Whether every entry of x is finite (no temporary arrays)."""
    for v in x:
        if not np.isfinite(v):
            return False
    return True


@njit(cache=True)
def port_values(gd, g_switch, state, r, a0):
    """The present port values (junction g, switch g, a0 per charge), shape (r,)."""
    md, ms = gd.size, state.size
    values = np.empty(r)
    values[:md] = gd
    for k in range(ms):
        values[md + k] = g_switch[k, 0] if state[k] else g_switch[k, 1]
    values[md + ms :] = a0
    return values


@njit(cache=True)
def factor_now(plan, st, a0):
    """Refactor at the present values and bump the factorization version: densely in
    compiled code (lowrank.rebuild), or with SuperLU when the state has no room for the dense
    matrices (sparse_factors.py; the ports kernel above SPARSE_FROM unknowns)."""
    values = port_values(st.gd, plan.g_switch, st.state, plan.VT.shape[0], a0)
    fac = st.fac
    if fac.Binv.shape[0] == fac.yc.size:
        rebuild(fac, plan, a0, values)
    else:
        with objmode(singular="int64"):
            singular = sparse_port_factors(
                plan.G, plan.M, plan.U, plan.VT, plan.port_p, plan.port_n, values, a0,
                plan.rhs_const, plan.src_unit, plan.abs_tol, fac.Z, fac.ZT, fac.K, fac.ZdT,
                fac.KdT, fac.zrel, fac.Zq, fac.Kq, fac.yc, fac.cc, fac.Yb, fac.Cb, fac.ref,
            )  # fmt: skip
        if singular:
            raise np.linalg.LinAlgError("singular matrix")
    st.ints[FACTORIZATIONS] += 1
    st.ints[VERSION] += 1


@njit(cache=True)
def junction_response(ieq, ZdT, KdT, zrel, yd, cd_response, applied, full):
    """Keep yd = B^-1 W ieq and V^T yd up to date with the junction currents ieq.

    After a factorization (``full``) they are recomputed; otherwise only the junctions whose
    current changed enough to move some unknown by more than JUNCTION_NEGLIGIBLE of its
    absolute tolerance are applied (most clamp diodes of an op-amp macromodel sit far in
    reverse, their companion current constant from one iteration to the next).
    """
    if full:
        yd[:] = 0.0
        cd_response[:] = 0.0
        for j in range(ieq.size):
            applied[j] = 0.0
    for j in range(ieq.size):
        delta = ieq[j] - applied[j]
        if delta != 0.0 and (full or abs(delta) * zrel[j] > JUNCTION_NEGLIGIBLE):
            z, k = ZdT[j], KdT[j]
            for i in range(yd.size):
                yd[i] += delta * z[i]
            for i in range(cd_response.size):
                cd_response[i] += delta * k[i]
            applied[j] = ieq[j]


@njit(cache=True)
def solve_ports(y0, c0, yd, cd_response, d, K, ZT):
    """The solution at the present linearization: Woodbury on the present factorization.

    y0 - yd = B^-1 (rhs0 - W ieq); d : the port values' change since the factorization,
    shape (r,).
    """
    return update(y0 - yd, c0 - cd_response, d, K, ZT, active_columns(d, K))


@njit(cache=True, inline="always")
def newton(plan, st, x0, a0, hist, rhs0, src_values, q, qdot):
    """Newton at one time point. Returns (converged, iterations, x, x_previous).

    rhs0 : the x-independent right-hand side (sources, charge history), shape (n,);
    src_values : the time-dependent sources' values at this time, shape (ns,).
    """
    reltol, abstol = plan.real[0], plan.real[1]
    itl4 = plan.ints[2]
    jp, cp, jslot, has_charge, charged = plan.jp, plan.cp, plan.jslot, plan.has_charge, plan.charged
    port_p, port_n, abs_tol = plan.port_p, plan.port_n, plan.abs_tol
    sw, approach, g_switch = plan.sw, plan.approach, plan.g_switch
    vt = (plan.VT_ptr, plan.VT_idx, plan.VT_val)
    ut = (plan.UT_ptr, plan.UT_idx, plan.UT_val)
    r = plan.VT.shape[0]
    vd_accepted, vd, cd, gd, ieq = st.vd_accepted, st.vd, st.cd, st.gd, st.ieq
    state, accepted = st.state, st.accepted
    ms = sw.shape[0]
    md = jp.shape[0]
    # no junctions or switches: the first solve is exact (one iteration, as MnaSystem's)
    linear = jp.shape[0] == 0 and ms == 0
    n = x0.size
    x = x0.copy()
    x_prev = x0.copy()
    x_ext = np.empty(n + 1)
    extend(x, x_ext)
    y0, c0 = st.y0, st.c0
    yd, cd_response, applied = st.yd, st.cd_response, st.ieq_applied
    hist_lin = hist[plan.lin_slots]
    version = -1  # of the factorization y0 and c0 belong to
    fac = st.fac  # rebuilt in place by factor_now
    ref, K, ZT, ZdT, KdT, zrel = fac.ref, fac.K, fac.ZT, fac.ZdT, fac.KdT, fac.zrel
    d = np.empty(r)
    for iteration in range(1, itl4 + 1):
        first = iteration == 1
        noncon = 0
        for k in range(ms):  # switch states (SwitchFamily.update_state), written out
            vc = x_ext[sw[k, 2]] - x_ext[sw[k, 3]]
            keep = accepted[k] if first else state[k]
            new = (keep or vc > approach[k, 0]) and vc >= approach[k, 1]
            if new != state[k]:
                state[k] = new
                noncon += 1
        # the junctions, linearized at x (DiodeFamily.port_load; written out here rather than
        # called: a call costs a reference-count update per array argument, ~20 ns each)
        for k in range(md):
            v = x_ext[port_p[k]] - x_ext[port_n[k]]
            vold = vd_accepted[k] if first else vd[k]
            vk = v
            if abs(v - vold) > jp[k, 9]:
                vk, was = pnjlim(v, vold, jp[k, 1], jp[k, 8])
                if was:
                    noncon += 1
            ck, gk = junction_current(
                vk, jp[k, 0], jp[k, 2], jp[k, 3], jp[k, 4], jp[k, 5], jp[k, 6], jp[k, 7]
            )
            if has_charge and charged[k]:  # else q = C = 0
                qk, capk = junction_charge(
                    vk,
                    ck,
                    gk,
                    cp[k, 0],
                    cp[k, 1],
                    cp[k, 2],
                    cp[k, 3],
                    cp[k, 4],
                    cp[k, 5],
                    cp[k, 6],
                    cp[k, 7],
                    cp[k, 8],
                )
                slot = jslot[k]
                icap = a0 * qk + hist[slot]
                q[slot] = qk
                qdot[slot] = icap
                ck += icap
                gk += a0 * capk
            vd[k], cd[k], gd[k] = vk, ck, gk
            ieq[k] = ck - gk * vk
        checked = False
        for attempt in range(2):  # the second after a refactorization at this iterate
            if version != st.ints[VERSION]:
                source_solution(
                    fac.yc, fac.cc, fac.Yb, fac.Cb, fac.Zq, fac.Kq, src_values, hist_lin, y0, c0
                )
                version = st.ints[VERSION]
            # d: the port values' change since the factorization (port_values - ref)
            for k in range(md):
                d[k] = gd[k] - ref[k]
            for k in range(ms):
                d[md + k] = (g_switch[k, 0] if state[k] else g_switch[k, 1]) - ref[md + k]
            for k in range(md + ms, r):
                d[k] = a0 - ref[k]
            if st.ints[JUNCTION_VERSION] != st.ints[VERSION]:
                junction_response(ieq, ZdT, KdT, zrel, yd, cd_response, applied, True)
                st.ints[JUNCTION_VERSION] = st.ints[VERSION]
            else:  # junction_response's incremental case, written out
                for j in range(md):
                    delta = ieq[j] - applied[j]
                    if delta != 0.0 and abs(delta) * zrel[j] > JUNCTION_NEGLIGIBLE:
                        for i in range(n):
                            yd[i] += delta * ZdT[j, i]
                        for i in range(r):
                            cd_response[i] += delta * KdT[j, i]
                        applied[j] = ieq[j]
            active = active_columns(d, K)
            x_new, ok = update(y0 - yd, c0 - cd_response, d, K, ZT, active)
            count = 0  # junction columns (the first md), counted without an array per iteration
            for a in range(active.size):
                if active[a] < md:
                    count += 1
            st.ints[ACTIVE_JUNCTIONS] = count
            if ok and all_finite(x_new):
                break
            if attempt == 0:
                factor_now(plan, st, a0)  # fills st.fac's arrays in place
                checked = True
        if not ok or not all_finite(x_new):
            return False, iteration, x_new, x
        x_new_ext = np.empty(n + 1)
        extend(x_new, x_new_ext)
        done = noncon == 0 and (iteration > 1 or linear)
        # MnaSystem.close and DiodeFamily.port_converged, written out (twice: here and after
        # the refinement below)
        for i in range(n if done and not linear else 0):
            if abs(x_new[i] - x[i]) > reltol * max(abs(x_new[i]), abs(x[i])) + abs_tol[i]:
                done = False
                break
        for k in range(md if done else 0):
            delta = gd[k] * (x_new_ext[port_p[k]] - x_new_ext[port_n[k]] - vd[k])
            if abs(delta) > reltol * max(abs(cd[k] + delta), abs(cd[k])) + abstol:
                done = False
                break
        if (done or iteration > 2) and not checked:
            tol = reltol * np.abs(x_new) + abs_tol
            rhs = add_u_columns(ut, -ieq, 0, rhs0.copy())  # rhs0 - W ieq
            refined, good = refine(
                fac.b_ptr,
                fac.b_idx,
                fac.b_val,
                fac.Binv,
                K,
                ZT,
                vt,
                ut,
                x_new,
                d,
                rhs,
                tol,
                REFINE_FRACTION,
            )
            if not good:  # refactor here: then the update is exact (d = 0)
                factor_now(plan, st, a0)
                source_solution(
                    fac.yc, fac.cc, fac.Yb, fac.Cb, fac.Zq, fac.Kq, src_values, hist_lin, y0, c0
                )
                version = st.ints[VERSION]
                d[:] = 0.0  # at the new factorization's own values
                junction_response(ieq, ZdT, KdT, zrel, yd, cd_response, applied, True)
                st.ints[JUNCTION_VERSION] = st.ints[VERSION]
                refined, ok = solve_ports(y0, c0, yd, cd_response, d, K, ZT)
            x_new = refined
            extend(x_new, x_new_ext)
            for i in range(n if done and not linear else 0):
                if abs(x_new[i] - x[i]) > reltol * max(abs(x_new[i]), abs(x[i])) + abs_tol[i]:
                    done = False
                    break
            for k in range(md if done else 0):
                delta = gd[k] * (x_new_ext[port_p[k]] - x_new_ext[port_n[k]] - vd[k])
                if abs(delta) > reltol * max(abs(cd[k] + delta), abs(cd[k])) + abstol:
                    done = False
                    break
        x_prev = x
        x = x_new
        x_ext = x_new_ext
        if done:
            return True, iteration, x, x_prev
    return False, itl4, x, x_prev
