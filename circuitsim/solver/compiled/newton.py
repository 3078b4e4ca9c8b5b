"""The compiled loops' shared state indices and the ports kernel's factorization.

The state slots (``fs`` floats, ``ints`` counters) both loops use; ``factor_now``, the ports
kernel's refactor at the present port values (dense, lowrank.rebuild, or SuperLU above
SPARSE_FROM unknowns); the rule that asks for it when many junctions stay active. The MNA
kernel's Newton is mna_newton.py, the ports kernel's is written out in port_loop.py.
"""

from __future__ import annotations

import warnings

import numpy as np
from numba import njit, objmode
from numba.core.errors import NumbaWarning

from circuitsim.solver.compiled.lowrank import rebuild
from circuitsim.solver.compiled.sparse_factors import sparse_port_factors

# factor_now leaves compiled code for SuperLU holding the GIL (nogil loops run in threads:
# only the factorizations, a few per run, are serialized); numba warns about it when compiling
warnings.filterwarnings("ignore", "Code running in object mode", NumbaWarning)

# a junction current change that moves no unknown by more than this fraction of its absolute
# tolerance (vntol, abstol) is not applied until it grows (port_loop.py, ports.all_unknowns)
JUNCTION_NEGLIGIBLE = 1e-9

# indices into KernelState.fs (floats) and .ints
T, H, SAVED_H, LAST_A0 = 0, 1, 2, 3
ORDER, AT_BREAK, FIRST, BI, ATTEMPTS, ACCEPTED, REJECTED, NEWTON, FACTORIZATIONS = range(9)
NHIST, COUNT, SAME_A0, VERSION, JUNCTION_VERSION = 9, 10, 11, 12, 13
# slot 14: mna_newton.PIVOT_ORDERS (the MNA loop's)
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
