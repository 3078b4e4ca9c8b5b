"""The time loop's kernel-specific steps, chosen when numba compiles the loop for a kernel.

time_loop.march is written once for both kernels; where they differ it calls the functions
below. Each is a stub that numba replaces, by the type of ``mid``, with the ports kernel's step
(``mid`` None: port_steps.py) or the MNA kernel's (``mid`` a newton.MidStep: mna_steps.py),
inlined into the loop (numba's ``overload(..., inline="always")``), so the loop compiled for
a kernel holds that kernel's steps only and calls none of them. Called from Python, a stub
does nothing: it only names the step.
"""

from __future__ import annotations

from circuitsim.solver.compiled.mna_steps import (
    mna_accept,
    mna_attempt,
    mna_step_begins,
)
from circuitsim.solver.compiled.newton import FACTOR, FIRST_FACTOR, NOT_RESUMING, copy_into
from circuitsim.solver.compiled.port_steps import (
    port_accept,
    port_attempt,
    port_first_factor,
    port_fixed_point,
)
from circuitsim.solver.compiled.step_control import CONTINUE
from circuitsim.solver.jit import library_in_use


def _ports(mid) -> bool:
    """Whether the loop is compiled for the ports kernel (``mid`` typed None)."""
    from numba import types

    return isinstance(mid, types.NoneType)


def loop_views(st, work, mid):
    """(t_history, q_history, qdot_history, x_ext): the accepted times (s), charges (C) and
    their currents (A), newest first, and the iterate (V, A; ground last) the step control
    reads."""


def loop_start(plan, st, mid, resume):
    """Before the loop: the ports kernel's first factorization (``resume`` newton.FIRST_FACTOR);
    returns (status, resume): step_control.CONTINUE, or newton.FACTOR (made in Python)."""


def at_pause(counters, mid):
    """At a pause a tenth of the run on: the ports kernel's fixed point."""


def step_begins(st, mid, work, resume):
    """At a step's start: the MNA kernel keeps the state of an undone step."""


def attempt(plan, st, mid, work, t, h, order, landing, coefficients, ratio, n_history, resume):
    """Newton at t + h (s): (status, converged, x_before); x_before the MNA kernel's iterate
    before the last (for a failure report)."""


def truncation_failure(st, mid, x_before):
    """A step cut below the minimum by the truncation error: the MNA kernel keeps its
    iterates for the report."""


def accept(plan, st, mid, work, t):
    """The converged point at t (s) accepted; returns whether a switch toggled."""


# the kernels' steps as numba inlines them (named functions: numba keeps inlined functions by
# name, so two lambdas of one overload would be taken for one another)


def _ports_views(st, work, mid):
    return st.t_history, st.q_history, st.qdot_history, st.x_ext


def _mna_views(st, work, mid):
    return st.ht, st.hq, st.hi, work.x_ext


def _ports_start(plan, st, mid, resume):
    if resume == FIRST_FACTOR:
        if not port_first_factor(plan, st):
            return FACTOR, NOT_RESUMING  # then re-entered at the first step
        return CONTINUE, NOT_RESUMING
    return CONTINUE, resume


def _mna_start(plan, st, mid, resume):
    return CONTINUE, resume


def _ports_pause(counters, mid):
    port_fixed_point(counters)


def _mna_pause(counters, mid):
    return None


def _ports_step_begins(st, mid, work, resume):
    return None


def _mna_step_begins(st, mid, work, resume):
    mna_step_begins(st, mid, work, resume)


def _ports_attempt(plan, st, mid, work, t, h, order, landing, coefficients, ratio, n_history,
                   resume):  # fmt: skip
    status, ok = port_attempt(plan, st, work, t, h, order, landing, coefficients, ratio, resume)
    return status, ok, work.hist[:0]


def _mna_attempt(plan, st, mid, work, t, h, order, landing, coefficients, ratio, n_history,
                 resume):  # fmt: skip
    return mna_attempt(plan, st, mid, work, t, h, order, landing, coefficients, ratio,
                       n_history, resume)  # fmt: skip


def _ports_truncation_failure(st, mid, x_before):
    return None


def _mna_truncation_failure(st, mid, x_before):
    copy_into(st.fail_x, mid.x_new)
    copy_into(st.fail_prev, x_before)


def _ports_accept(plan, st, mid, work, t):
    return port_accept(plan, st, work, t)


def _mna_accept(plan, st, mid, work, t):
    return mna_accept(plan, st, mid, work, t)


def _loop_views(st, work, mid):
    return _ports_views if _ports(mid) else _mna_views


def _loop_start(plan, st, mid, resume):
    return _ports_start if _ports(mid) else _mna_start


def _at_pause(counters, mid):
    return _ports_pause if _ports(mid) else _mna_pause


def _step_begins(st, mid, work, resume):
    return _ports_step_begins if _ports(mid) else _mna_step_begins


def _attempt(plan, st, mid, work, t, h, order, landing, coefficients, ratio, n_history, resume):
    return _ports_attempt if _ports(mid) else _mna_attempt


def _truncation_failure(st, mid, x_before):
    return _ports_truncation_failure if _ports(mid) else _mna_truncation_failure


def _accept(plan, st, mid, work, t):
    return _ports_accept if _ports(mid) else _mna_accept


def _on_numba():
    """Register the stubs' overloads with numba (at import, or when numba is first imported)."""
    from numba.extending import overload

    overload(loop_views, inline="always")(_loop_views)
    overload(loop_start, inline="always")(_loop_start)
    overload(at_pause, inline="always")(_at_pause)
    overload(step_begins, inline="always")(_step_begins)
    overload(attempt, inline="always")(_attempt)
    overload(truncation_failure, inline="always")(_truncation_failure)
    overload(accept, inline="always")(_accept)


if not library_in_use():
    _on_numba()
