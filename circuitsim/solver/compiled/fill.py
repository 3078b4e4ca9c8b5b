"""The fill of L and U of a sparse matrix factored without pivoting, from its pattern alone.

The MNA kernel's pivot orders (compiled/sparse_order.py) need, for each order SuperLU
proposes, the pattern of L and U of the permuted matrix factored in the natural order (the
kernel's refactor, compiled/sparse_lu.py). A left-looking LU computes column j from the L
columns k < j with U[k, j] != 0, so column j of L + U holds the rows that A's column j reaches
in the graph whose edges lead from k to the rows of L's column k (Gilbert and Peierls). This
module walks that graph once per column; it replaces a second, symbolic SuperLU pass on
generic values, and gives the exact pattern (no stored zeros, which the refactor would skip
anyway: the factors' values are the same bit for bit). :func:`reach_sets` finds, on that
pattern, the columns a partial refactor redoes when given columns change.
"""

from __future__ import annotations

import numpy as np

from circuitsim.solver.compiled.sparse_lu import WORD
from circuitsim.solver.jit import njit


@njit(cache=True)
def _grown(array, needed):
    """``array`` with room for ``needed`` entries (doubled), its entries kept."""
    out = np.empty(max(needed, 2 * array.size), dtype=array.dtype)
    out[: array.size] = array
    return out


@njit(cache=True, inline="always")
def _reach(i, j, mark, found, count, stack, top):
    """Row ``i`` reached for column ``j``: listed in ``found`` once (and put on ``stack`` if
    above j, its L column to be followed); the new (count, top)."""
    if mark[i] != j:
        mark[i] = j
        found[count] = i
        count += 1
        if i < j:
            stack[top] = i
            top += 1
    return count, top


@njit(cache=True)
def lu_pattern(a_ptr, a_row):
    """The patterns of L and U of the (n, n) matrix of compressed-column pattern ``a_ptr``,
    ``a_row`` factored without pivoting: (l_ptr, l_row, u_ptr, u_row), L strictly lower, U
    with its rows ascending in each column and the diagonal last (always present)."""
    n = a_ptr.size - 1
    mark = np.full(n, -1, dtype=np.int64)  # mark[i] == j: row i found for column j
    stack = np.empty(n, dtype=np.int64)
    found = np.empty(n, dtype=np.int64)
    l_ptr = np.zeros(n + 1, dtype=np.int64)
    u_ptr = np.zeros(n + 1, dtype=np.int64)
    l_row = np.empty(a_row.size + n, dtype=np.int64)
    u_row = np.empty(a_row.size + n, dtype=np.int64)
    nl = 0
    nu = 0
    for j in range(n):
        mark[j] = j  # the diagonal: U's last entry of the column
        count = 0
        top = 0
        for e in range(a_ptr[j], a_ptr[j + 1]):
            count, top = _reach(a_row[e], j, mark, found, count, stack, top)
        while top > 0:  # the rows the L columns of the rows found above j reach
            top -= 1
            k = stack[top]
            for f in range(l_ptr[k], l_ptr[k + 1]):
                count, top = _reach(l_row[f], j, mark, found, count, stack, top)
        rows = np.sort(found[:count])
        if nl + count > l_row.size:
            l_row = _grown(l_row, nl + count)
        if nu + count + 1 > u_row.size:
            u_row = _grown(u_row, nu + count + 1)
        for i in rows:
            if i < j:
                u_row[nu] = i
                nu += 1
            else:
                l_row[nl] = i
                nl += 1
        u_row[nu] = j
        nu += 1
        l_ptr[j + 1] = nl
        u_ptr[j + 1] = nu
    return l_ptr, l_row[:nl].copy(), u_ptr, u_row[:nu].copy()


@njit(cache=True)
def reach_sets(u_ptr, u_row, seed_ptr, seed_col):
    """For each set s of columns (``seed_col[seed_ptr[s]:seed_ptr[s + 1]]``), the columns a
    change of their entries makes sparse_lu.refactor_marked redo: those columns, and column j
    whenever U[k, j] != 0 for a redone k (the scan a refactor would make, done once per
    order). Returns (reach, first): reach (nsets, words) uint64 as ``SparseLU.port_reach``,
    first (nsets,) int64 the first word of each that is not zero (words for an empty set)."""
    n = u_ptr.size - 1
    words = (n + WORD - 1) // WORD
    nsets = seed_ptr.size - 1
    reach = np.zeros((nsets, words), dtype=np.uint64)
    first = np.full(nsets, words, dtype=np.int64)
    marked = np.zeros(n, dtype=np.bool_)
    for s in range(nsets):
        start = n
        for e in range(seed_ptr[s], seed_ptr[s + 1]):
            marked[seed_col[e]] = True
            start = min(start, seed_col[e])
        for j in range(start, n):
            for e in range(u_ptr[j], u_ptr[j + 1] - 1):
                marked[j] |= marked[u_row[e]]
            if marked[j]:
                reach[s, j // WORD] |= np.uint64(1) << np.uint64(j % WORD)
        marked[start:] = False
        if start < n:
            first[s] = start // WORD
    return reach, first


FILL_FUNCTIONS = (lu_pattern, reach_sets)  # called from Python at a run's start
