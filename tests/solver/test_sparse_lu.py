"""The MNA kernel's sparse LU (compiled/sparse_lu.py) against dense solves: MNA-shaped
matrices with zero diagonals (voltage-source branches), port stamps that change by orders of
magnitude, and a new pivot order when a pivot becomes too small."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from circuitsim.solver.compiled import sparse_order
from circuitsim.solver.compiled.fill import reach_sets
from circuitsim.solver.compiled.sparse_lu import (
    ALL_COLUMNS,
    assemble,
    lu_solve,
    mark_changed,
    refactor,
    refactor_marked,
)
from circuitsim.solver.compiled.sparse_order import (
    ORDER_MARGIN,
    SUPERLU_ORDERS,
    _on_order,
    analyse,
    iteration_cost,
    pivot_orders,
    present_matrix,
    repivot,
)
from circuitsim.solver.compressed import Compressed


def mna_like(n: int, seed: int):
    """A random sparse matrix with a zero diagonal at every third unknown (like the branch
    rows of voltage sources), a capacitor-like M, and four ports (one to ground)."""
    rng = np.random.default_rng(seed)
    G = sp.random(n, n, density=4.0 / n, random_state=seed).toarray()
    G[np.arange(n), (np.arange(n) + 1) % n] += 1.0 + rng.random(n)
    G[np.arange(0, n, 3), np.arange(0, n, 3)] = 0.0
    M = np.zeros((n, n))
    M[5, 5], M[7, 7] = 1e-6, 2e-6
    return G, M, np.array([1, 4, -1, 10]), np.array([2, -1, 8, 11])


PORT_VALUES = np.array([1e-3, 5.0, 1e-12, 0.1])  # S: two junctions, a switch off, one on


def factor_and_solve(lu, a0, g_ports, b):
    md = 2  # the first two ports are "junctions", the others "switches"
    assemble(lu.a_val, lu.g_val, lu.m_val, a0, lu.port_pos, g_ports[:md], g_ports[md:])
    column = refactor(lu.a_ptr, lu.a_row, lu.a_val, lu.l_ptr, lu.l_row, lu.l_val, lu.u_ptr,
                      lu.u_row, lu.u_val, lu.work, lu.redo, True)  # fmt: skip
    x = np.zeros(b.size)
    if column < 0:
        lu_solve(lu.l_ptr, lu.l_row, lu.l_val, lu.u_ptr, lu.u_row, lu.u_val, lu.row_to,
                 lu.col_of, b, lu.work, x)  # fmt: skip
    return column, x


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_refactor_solves_as_a_dense_solve(seed):
    n, (G, M, port_p, port_n), values = 60, mna_like(60, seed), PORT_VALUES
    lu = analyse(G, M, port_p, port_n, values, 1e5)
    rng = np.random.default_rng(seed)
    for scale in (1.0, 3.0, 10.0):  # the same pattern at other port values
        g = values * (1.0 + scale * rng.random(4))
        b = rng.random(n)
        column, x = factor_and_solve(lu, 1e5, g, b)
        if column >= 0:  # a pivot became too small: a new order at these values, as the
            lu = analyse(G, M, port_p, port_n, g, 1e5)  # kernel makes
            column, x = factor_and_solve(lu, 1e5, g, b)
        assert column < 0
        dense = present_matrix(G, M, port_p, port_n, g, 1e5).toarray()
        reference = np.linalg.solve(dense, b)
        assert np.max(np.abs(x - reference)) <= 1e-9 * np.max(np.abs(reference))


def test_a_too_small_pivot_asks_for_a_new_order_that_then_solves():
    # a 2 x 2 block whose pivot order flips when the port conductance crosses the other entry
    G = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    M = np.zeros((3, 3))
    port_p, port_n = np.array([0, 2]), np.array([-1, -1])
    lu = analyse(G, M, port_p, port_n, np.array([1e-9, 1.0]), 0.0)
    b = np.array([1.0, 2.0, 3.0])
    g = np.array([1e4, 1.0])
    column, _ = factor_and_solve(lu, 0.0, g, b)
    assert column >= 0  # the order made at 1e-9 S does not suit 1e4 S
    assert repivot(lu, port_p, port_n, g, 0.0) == 0
    column, x = factor_and_solve(lu, 0.0, g, b)
    assert column < 0
    dense = present_matrix(G, M, port_p, port_n, g, 0.0).toarray()
    assert np.allclose(dense @ x, b, rtol=0, atol=1e-12)


def test_a_singular_matrix_is_reported():
    G = np.array([[1.0, 1.0], [1.0, 1.0]])
    with pytest.raises(np.linalg.LinAlgError):
        analyse(G, np.zeros((2, 2)), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64),
                np.zeros(0), 0.0)  # fmt: skip


def refactor_changed(lu, a0, g_ports, scan=False):
    """Assemble and refactor only what mark_changed marks (the MNA kernel's Newton;
    ``scan``: through refactor, from column 0, instead of refactor_marked from the first
    column marked); mark_changed's answer."""
    md = 2
    assemble(lu.a_val, lu.g_val, lu.m_val, a0, lu.port_pos, g_ports[:md], g_ports[md:])
    n = lu.a_ptr.size - 1
    first = mark_changed(lu.port_reach, lu.port_from, lu.m_reach, lu.extra_reach, lu.factored,
                         lu.redo, g_ports[:md], g_ports[md:], a0, n)  # fmt: skip
    every = first == ALL_COLUMNS
    if every or (scan and first < n):
        assert refactor(lu.a_ptr, lu.a_row, lu.a_val, lu.l_ptr, lu.l_row, lu.l_val, lu.u_ptr,
                        lu.u_row, lu.u_val, lu.work, lu.redo, every) < 0  # fmt: skip
    elif first < n:
        assert refactor_marked(lu.a_ptr, lu.a_row, lu.a_val, lu.l_ptr, lu.l_row, lu.l_val,
                               lu.u_ptr, lu.u_row, lu.u_val, lu.work, lu.redo,
                               first) < 0  # fmt: skip
    return first


@pytest.mark.parametrize("scan", [False, True])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_refactoring_the_changed_columns_gives_the_whole_refactor_bit_for_bit(seed, scan):
    n, (G, M, port_p, port_n), values = 60, mna_like(60, seed), PORT_VALUES
    partial = analyse(G, M, port_p, port_n, values, 1e5)
    whole = analyse(G, M, port_p, port_n, values, 1e5)
    assert refactor_changed(partial, 1e5, values, scan) == ALL_COLUMNS  # no factors yet
    assert refactor_changed(partial, 1e5, values, scan) == n  # nothing changed: kept
    rng = np.random.default_rng(seed)
    for a0, port in ((1e5, 0), (1e5, 1), (2e5, None), (2e5, 3), (3e5, 2)):
        g = values.copy()
        if port is not None:
            g[port] *= 1.0 + rng.random()
        assert 0 <= refactor_changed(partial, a0, g, scan) < n  # the first column marked
        assert not partial.redo.any()  # cleared for the next call
        column, _ = factor_and_solve(whole, a0, g, np.ones(n))
        assert column < 0
        used_l, used_u = whole.l_ptr[-1], whole.u_ptr[-1]
        assert np.array_equal(partial.l_val[:used_l], whole.l_val[:used_l])
        assert np.array_equal(partial.u_val[:used_u], whole.u_val[:used_u])
        values = g
    # and it does skip: after one port's change, the columns it does not reach keep what
    # they held (here a marker)
    partial.u_val[:] = np.nan
    g = values.copy()
    g[2] *= 2.0
    refactor_changed(partial, 3e5, g, scan)
    kept = np.count_nonzero(np.isnan(partial.u_val[: partial.u_ptr[-1]]))
    assert 0 < kept < partial.u_ptr[-1]


def test_iteration_cost_counts_the_reached_columns_and_the_solves():
    # a tridiagonal matrix in its natural order: L has (1, 0), (2, 1), (3, 2) and U the
    # diagonal and (0, 1), (1, 2), (2, 3); column j is computed from column j - 1
    n = 4
    G = sp.diags([np.full(n - 1, -1.0), np.full(n, 3.0), np.full(n - 1, -1.0)], [-1, 0, 1])
    G = Compressed.of(G)
    natural = np.arange(n, dtype=np.int64)
    port_p, port_n = np.array([0, 3]), np.array([-1, -1])
    lu = _on_order(G, Compressed.of(np.zeros((n, n))), port_p, port_n,
                   np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), G, natural,
                   natural, 1.0)  # fmt: skip
    solves = 3 + 7  # L's and U's entries
    assert iteration_cost(lu, np.array([False, False])) == solves
    # a port at node 3: column 3 alone, one L column (2's: 1 entry) and its own (none)
    assert iteration_cost(lu, np.array([False, True])) == 1 + solves
    # at node 0: every column (column 0 reaches 1, 2 and 3): 1 + 2 + 2 + 1
    assert iteration_cost(lu, np.array([True, False])) == 6 + solves


def test_the_reach_sets_hold_the_columns_a_refactor_redoes():
    # U of a tridiagonal matrix in its natural order: column j is computed from column
    # j - 1, so a change in column c is carried to every column from c on
    n = 70  # two words: columns 0-63 and 64-69
    u_ptr = np.concatenate([[0, 1], 2 * np.arange(1, n) + 1]).astype(np.int64)
    u_row = np.concatenate([[0]] + [[j - 1, j] for j in range(1, n)]).astype(np.int64)
    seed_ptr = np.array([0, 1, 2, 4, 4], dtype=np.int64)
    seed_col = np.array([0, 66, 65, 3], dtype=np.int64)
    reach, first = reach_sets(u_ptr, u_row, seed_ptr, seed_col)
    columns = [[j for j in range(n) if reach[s, j // 64] >> np.uint64(j % 64) & np.uint64(1)]
               for s in range(4)]  # fmt: skip
    assert columns == [list(range(n)), list(range(66, n)), list(range(3, n)), []]
    assert first.tolist() == [0, 1, 0, 2]  # the empty set: none (the number of words)


def test_between_the_limits_both_searches_are_offered_and_the_run_keeps_the_chosen_one(
    monkeypatch,
):
    n, (G, M, port_p, port_n), values = 60, mna_like(60, 1), PORT_VALUES
    monkeypatch.setattr(sparse_order, "SUPERLU_FROM", n - 1)  # n is between the limits
    changing = np.array([True, True, False, False])

    def orders_of(search):
        return pivot_orders(G, M, port_p, port_n, values, 1e5, changing=changing,
                            search=search)  # fmt: skip

    search: dict = {}
    chosen = orders_of(search)
    # each search alone (a run that recorded it)
    ours, superlu = orders_of({"kind": "ours"}), orders_of({"kind": "superlu"})
    assert len(ours) == 1 and len(superlu) == len(SUPERLU_ORDERS)
    cost_ours = iteration_cost(ours[0], changing)
    cost_superlu = iteration_cost(superlu[0], changing)
    # SuperLU's first; ours taken when it costs less than ORDER_MARGIN of it, and then the
    # run keeps its orders alone (the other search's would be tried first at a small pivot)
    expected = "ours" if cost_ours < ORDER_MARGIN * cost_superlu else "superlu"
    assert search == {"kind": expected}
    same = ours if expected == "ours" else superlu
    assert len(chosen) == len(same)
    for a, b in zip(chosen, same, strict=True):
        assert np.array_equal(a.col_of, b.col_of) and np.array_equal(a.row_to, b.row_to)
    # and a later call of the run searches that way alone
    assert len(orders_of(search)) == len(same)


@pytest.mark.parametrize("search", ["ours", "SuperLU"])
def test_the_pivot_order_of_fewer_operations_is_chosen_and_the_other_kept(search, monkeypatch):
    n, (G, M, port_p, port_n), values = 60, mna_like(60, 1), PORT_VALUES
    if search == "SuperLU":  # above the limit: SuperLU's column orders
        monkeypatch.setattr(sparse_order, "OWN_ORDER_LIMIT", n - 1)
    changing = np.array([True, True, False, False])
    orders = pivot_orders(G, M, port_p, port_n, values, 1e5, changing=changing)
    assert len(orders) == (1 if search == "ours" else len(SUPERLU_ORDERS))
    costs = [iteration_cost(lu, changing) for lu in orders]
    assert all(costs[0] <= cost / ORDER_MARGIN for cost in costs[1:])
    for lu in orders:  # each one solves the matrix
        b = np.arange(1.0, n + 1)
        column, x = factor_and_solve(lu, 1e5, values, b)
        assert column < 0
        dense = present_matrix(G, M, port_p, port_n, values, 1e5).toarray()
        assert np.allclose(dense @ x, b, rtol=1e-12, atol=0)
