"""The compiled loops' shared state indices and the ports kernel's factorization.

The state slots (``fs`` floats, ``ints`` counters) both loops use (named in slots.py, imported
here for both loops); ``factor_now``, the ports
kernel's refactor at the present port values (dense, lowrank.rebuild; above SPARSE_FROM
unknowns the loop returns FACTOR and the runner factors sparse, then the loop goes on
where it stopped); the rule that asks for a refactor when many junctions stay active. The MNA
kernel's Newton is mna_newton.py, the ports kernel's is port_newton.py's steps (run by
port_steps.py).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from circuitsim.solver.compiled.lowrank import rebuild
from circuitsim.solver.compiled.slots import (  # noqa: F401 (importable from here too)
    ACCEPTED,
    AFTER_REFACTOR,
    AT_BREAK,
    ATTEMPTS,
    BI,
    COUNT,
    FACTORIZATIONS,
    FIRST,
    JUNCTION_VERSION,
    LAST_A0,
    MEASURED_VERSION,
    NEWTON,
    NHIST,
    ORDER,
    PAUSE_ATTEMPTS,
    REJECTED,
    SAME_A0,
    SAVED_H,
    VERSION,
    H,
    T,
)
from circuitsim.solver.devices.diode_kernel import linearize_junction
from circuitsim.solver.jit import njit

# a junction current change that moves no unknown by more than this fraction of its absolute
# tolerance (vntol, abstol) is not applied until it grows (port_steps.py, ports.all_unknowns)
JUNCTION_NEGLIGIBLE = 1e-9

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
REBASE_STEPS = 8  # also: refactor when this many accepted steps in a row used one new a0
# A Newton failure at an a0 this far from the factorization's is retried once on a
# factorization at this a0 before the step is cut: with the charge columns' update
# d = a0 - a0_ref dominating B (steps far shorter than the factored one, right after a
# breakpoint or a switch transition), the Woodbury solve can lose the digits that Newton's
# branch-current tolerance (abstol 1e-12 A) needs, where an exact solve converges
# (measured: the wheelset at reltol 1e-6 with uic failed at t = 6e-16 s without it).
RETRY_RATIO = 16.0


@njit(cache=True, inline="always")
def rebase_wanted(active, after_refactor):
    """Whether ``active`` junction columns in the last Newton iteration of an accepted step
    are many more than the ``after_refactor`` a refactor at a solution left (0: none yet)."""
    return active > REBASE_ACTIVE and active > REBASE_GROWTH * after_refactor


@njit(cache=True, inline="always")
def copy_into(target, source) -> None:
    """target[:] = source, written out: numba's slice assignment of an array needs its
    reference counting (it may copy an overlapping source first), which the time loop is
    compiled without (time_loop.march)."""
    for i in range(source.size):
        target[i] = source[i]


@njit(cache=True, inline="always")
def extend(x, x_ext):
    """x_ext[:n] = x, x_ext[n] = 0 (ground, reached by node index -1)."""
    copy_into(x_ext, x)
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


# The loops' return to Python in the middle of a step, for a factorization made there (the
# ports kernel above SPARSE_FROM unknowns: sparse_factors.py; the MNA kernel: a new pivot
# order, when a pivot became too small). numba
# compiles a block of Python inside a compiled function (objmode) again in every process, at
# its first call; a return costs microseconds against the factorization's milliseconds. The
# loop keeps what it needs to go on in the slots below and goes on bit for bit where it
# stopped: the step's scalars, and which of the step's points to re-enter (RESUME_AT).
# return code: factor (ports kernel) or order the pivots anew (MNA kernel) at st.fs[FACTOR_A0]
# and the devices' present state, then re-enter
FACTOR = 5
# where to re-enter (ints[RESUME_AT]): not at all, after the step's refactor test, at the
# start of the step's second Newton attempt, inside Newton iteration ints[RESUME_ITERATION]
# after its linearization (attempt ints[RESUME_ATTEMPT], ints[RESUME_NONCON] limited or
# toggled so far); FIRST_FACTOR (set by the runner): the ports kernel's first factorization,
# at fs[FACTOR_A0], made by the loop (a second compiled function loaded from the cache would
# cost a process 0.07 s, docs/performance.md)
NOT_RESUMING, AT_REFACTOR_TEST, AT_SECOND_ATTEMPT, IN_ITERATION, FIRST_FACTOR = 0, 1, 2, 3, 4
# slots the runner appends to fs and ints (negative: after whatever the state's owner has)
RESUME_H, FACTOR_A0 = -2, -1  # fs: the step's h; the a0 to factor at (1/s)
RESUME_AT, RESUME_ORDER, RESUME_LANDING, RESUME_ATTEMPT, RESUME_ITERATION, RESUME_NONCON = (
    -6, -5, -4, -3, -2, -1
)  # fmt: skip
FACTOR_IN_PYTHON = -7  # ints: 1 when the ports kernel's factorizations are made in Python
RESUME_RETRY = -8  # ints: the MNA loop's step retries from a failed attempt's iterate
RESUME_FLOATS, RESUME_INTS = 2, 8


class MidStep(NamedTuple):
    """The MNA loop's arrays that outlive a return in the middle of a step, and the unknowns
    it records (the runner's; shapes: n unknowns, nq charge slots, nrows recorded)."""

    x_new: np.ndarray  # (n,) Newton's last solution
    q: np.ndarray  # (nq,) the time point's charges and their currents so far
    qdot: np.ndarray
    fs_start: np.ndarray  # fs and ints at the step's start (a step undone: REPIVOT)
    ints_start: np.ndarray
    rows: np.ndarray  # (nrows,) int: the unknowns recorded at each accepted point (out_x)


@njit(cache=True, _nrt=True)
def factor_now(plan, st, a0):
    """Refactor at the present values and bump the factorization version (dense, in compiled
    code: lowrank.rebuild); False when the factorization is to be made in Python
    (ints[FACTOR_IN_PYTHON]: sparse, for a state without dense matrices, sparse_factors.py):
    then ``fs[FACTOR_A0] = a0`` and the loop returns FACTOR (:func:`wait_for_factor`)."""
    if st.ints[FACTOR_IN_PYTHON]:
        st.fs[FACTOR_A0] = a0
        return False
    dense_factor(plan, st, a0)
    return True


@njit(cache=True)
def dense_factor(plan, st, a0):
    """lowrank.rebuild at the present port values and a0 (1/s); the version bumped."""
    values = port_values(st.gd, plan.g_switch, st.state, plan.VT.shape[0], a0)
    rebuild(st.fac, plan, a0, values)
    st.ints[FACTORIZATIONS] += 1
    st.ints[VERSION] += 1


@njit(cache=True, inline="always")
def wait_for_factor(fs, si, at, h, order, landing, attempt, iteration, noncon):
    """Keep the step's place (RESUME_*) and return FACTOR."""
    si[RESUME_AT] = at
    fs[RESUME_H] = h
    si[RESUME_ORDER] = order
    si[RESUME_LANDING] = 1 if landing else 0
    si[RESUME_ATTEMPT] = attempt
    si[RESUME_ITERATION] = iteration
    si[RESUME_NONCON] = noncon
    return FACTOR


@njit(cache=True, inline="always")
def resumed_step(fs, si, breaks):
    """The step's (t, next breakpoint, h, order, landing) as kept by :func:`wait_for_factor`
    (step_start already ran for it)."""
    return fs[T], breaks[si[BI]], fs[RESUME_H], si[RESUME_ORDER], si[RESUME_LANDING] != 0


@njit(cache=True, inline="always")
def junction_charges(vd, a0, hist, jp, cp, jslot, has_charge, charged, q, qdot):
    """The charged junctions' charge and its current at their linearization voltages ``vd``
    (as the Newton iteration computed them), into q and qdot: what an iteration re-entered
    after its linearization needs."""
    for k in range(vd.size):
        if has_charge and charged[k]:
            slot = jslot[k]
            # at v_old = v nothing is limited: the iteration's own charge, recomputed
            _, _, _, _, q[slot], qdot[slot] = linearize_junction(
                jp, cp, k, vd[k], vd[k], True, a0, hist[slot]
            )
