"""The MNA kernel's pivot orders, found by sparse_order.py (our minimum degree and threshold
pivoting, compiled/pivot_search.py) for the compiled loop: at its start, when it asks for a
new one (newton.FACTOR), and the message of a singular matrix. No scipy: the MNA kernel's
process does not load it."""

from __future__ import annotations

import numpy as np

from circuitsim.solver.compiled.failures import singular_row
from circuitsim.solver.compiled.sparse_lu import SparseLU
from circuitsim.solver.compiled.terminal_plan import entry_pattern, entry_values
from circuitsim.solver.system import MnaSystem


def reorder(plan, st, a0: float, search=None) -> int:
    """A new pivot order (sparse_order.repivot) at the present matrix, in place in st.lu, as
    the MNA loop asks (newton.FACTOR); 0, or nonzero when it has no room for the fill or is
    singular. ``search``: the run's (sparse_order.pivot_orders)."""
    g_switch = np.where(np.asarray(st.state, dtype=bool), plan.g_switch[:, 0], plan.g_switch[:, 1])
    values = np.concatenate((st.gd, g_switch))
    extra = entry_values(plan.terms, st.terms)
    from circuitsim.solver.compiled.sparse_order import repivot

    try:
        return repivot(st.lu, plan.port_p, plan.port_n, values, a0, extra, changing_ports(plan),
                       search)  # fmt: skip
    except np.linalg.LinAlgError:  # singular
        return 2


def pivot_order(plan, gd, state, a0, terms, constant, spare: float = 1.5,
                search=None) -> list[SparseLU]:  # fmt: skip
    """sparse_order.pivot_orders at the junction conductances ``gd``, switch states
    ``state``, a0 and the multi-terminal elements' state ``terms`` (with room for ``spare``
    times the fill in L and U, for later orders): the chosen order first; ``constant``:
    (G, M), sparse (:func:`constant_parts`); ``search``: the run's (pivot_orders)."""
    from circuitsim.solver.compiled.sparse_order import pivot_orders

    values, extra = present_values(plan, gd, state, terms)
    G, M = constant
    return pivot_orders(G, M, plan.port_p, plan.port_n, values, a0, spare, extra,
                        changing_ports(plan), search)  # fmt: skip


def changing_ports(plan) -> np.ndarray:
    """(nports,) bool: the ports whose conductance changes at every Newton iteration, the
    charged junctions (the switches' change at their toggles)."""
    return np.concatenate([plan.charged, np.zeros(plan.sw.shape[0], dtype=bool)])


def constant_parts(system: MnaSystem) -> tuple:
    """The system's G and M in numpy's compressed columns (duplicates summed, no stored
    zeros), without a dense scan (n^2 entries: 2 x 6.6 million at the 64-mass chain's 2562
    unknowns) or scipy."""
    return system.compressed("G"), system.compressed("M")


def present_values(plan, gd, state, terms):
    """The ports' conductances and the extra entries (rows, cols, values) at these states."""
    g_switch = np.where(np.asarray(state, dtype=bool), plan.g_switch[:, 0], plan.g_switch[:, 1])
    values = np.concatenate([np.asarray(gd, dtype=float), g_switch])
    return values, (*entry_pattern(plan.terms), entry_values(plan.terms, terms))


def singular_message(system, plan, gd, state, a0, terms) -> str:
    """describe_singular for the whole matrix at these device states (dense: an error path)."""
    from circuitsim.solver.compiled.sparse_order import present_matrix

    values, extra = present_values(plan, gd, state, terms)
    G, M = constant_parts(system)
    matrix = present_matrix(G, M, plan.port_p, plan.port_n, values, a0, extra)
    return system.describe_singular(singular_row(matrix.toarray()))
