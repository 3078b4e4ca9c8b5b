"""Earlier pivot orders of the MNA kernel, tried before a new order is searched for.

A circuit whose junctions switch back and forth (the |x| blocks of a generated circuit at
each zero crossing) makes a pivot too small at each switch, in the same few places: a new
order suits the matrix until the next crossing, where the order before it suits again. The
runner keeps the last few orders (copies of sparse_lu.SparseLU) and, when the kernel asks
for a new one (newton.FACTOR), first refactors the present matrix on each kept order; one
whose pivots all pass the threshold is taken, at the cost of a refactor instead of a new
search (sparse_order.py: milliseconds to tens of milliseconds, in Python and compiled code).

The trial calls compiled functions from Python. One of them (assemble) is inlined into the
kernel, so the kernel's compile leaves no machine code for a call from Python: the first
trial compiled it (1.1 s at load 10) without the kernel's announcement. The runner compiles
them when the run starts (:func:`compile_trial`), announced with the kernel's compile.
"""

from __future__ import annotations

import numpy as np

from circuitsim.solver.compiled.mna_terminals import stamp_terminals
from circuitsim.solver.compiled.sparse_lu import SparseLU, assemble, refactor

ORDERS_KEPT = 4  # the crossings of the Boyle macromodel wheelsets alternate between few


def copy_order(lu: SparseLU) -> SparseLU:
    """A copy of ``lu`` that later in-place reorders of ``lu`` leave alone."""
    return SparseLU(*(v.copy() if isinstance(v, np.ndarray) else v for v in lu))


class EarlierOrders:
    """The last ORDERS_KEPT pivot orders of one run, newest last."""

    def __init__(self) -> None:
        self.kept: list[SparseLU] = []
        self.reused = 0
        self.search: dict = {}  # which search makes the run's orders (sparse_order.pivot_orders)

    def keep(self, lu: SparseLU) -> None:
        """Remember ``lu`` (a copy: the caller is about to reorder it in place)."""
        self.kept.append(copy_order(lu))
        del self.kept[:-ORDERS_KEPT]

    def suited(self, plan, st, a0: float) -> SparseLU | None:
        """A kept order on which the kernel's present matrix (st's junction conductances,
        switch states and terminal slopes at a0) refactors, taken out of the kept ones
        (factored, as the kernel's next refactor will find it); None if none does."""
        for index, lu in enumerate(self.kept):
            if _refactors(plan, st, lu, a0):
                self.reused += 1
                return self.kept.pop(index)
        return None


def _refactors(plan, st, lu: SparseLU, a0: float) -> bool:
    """Whether the present matrix (as in :meth:`EarlierOrders.suited`) refactors on the
    order ``lu`` with every pivot above the threshold (``lu``'s values are overwritten)."""
    g_switch = np.where(np.asarray(st.state, dtype=bool), plan.g_switch[:, 0],
                        plan.g_switch[:, 1])  # fmt: skip
    assemble(lu.a_val, lu.g_val, lu.m_val, a0, lu.port_pos, st.gd, g_switch)
    if plan.terms.kind.size:
        stamp_terminals(plan.terms, st.terms, lu.extra_pos, lu.a_val)
    # whole (its factors are of another matrix); lu.factored stays NaN, set when the
    # order was given up, so the kernel's next refactor is whole too
    return refactor(lu.a_ptr, lu.a_row, lu.a_val, lu.l_ptr, lu.l_row, lu.l_val, lu.u_ptr,
                    lu.u_row, lu.u_val, lu.work, lu.redo, True) < 0  # fmt: skip


def python_called(plan) -> tuple:
    """The compiled functions a trial of ``plan``'s kernel calls from Python."""
    return (assemble, refactor, *((stamp_terminals,) if plan.terms.kind.size else ()))


def compile_trial(plan, st) -> None:
    """Compile :func:`python_called` for the types of this run, by a trial on a copy of the
    state's order (``st`` is left as it was); and our pivot search's (sparse_order.py)."""
    from circuitsim.solver.compiled.sparse_order import search_trial

    _refactors(plan, st, copy_order(st.lu), 1.0)
    search_trial()
