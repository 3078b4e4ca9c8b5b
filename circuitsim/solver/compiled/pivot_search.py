"""The MNA kernel's pivot orders found by our own code (compiled/sparse_order.py calls these
once per order; they replace SuperLU there, so the MNA kernel's process needs no scipy).

Three steps, the ones SuperLU takes for ``splu(A, permc_spec=..., diag_pivot_thresh=0.1)``:

- :func:`maximum_matching`: a row for every column, no row twice (a maximum transversal,
  Duff's depth-first search with a cheap first pass). MNA matrices of op-amp circuits have
  zeros on the diagonal (the rows of voltage sources and ideal op-amps); the matched rows are
  the pivots each column would rather take.
- :func:`minimum_degree`: a column order that keeps the fill small, by eliminating at each
  step a node of least degree in the elimination graph (held as bit sets, one row of 64-bit
  words per node: n^2 / 8 bytes, 0.8 MB at the 64-mass chain's 2562 unknowns). The graph is
  that of A + A^T with the matched rows on the diagonal, or of A^T A (each row a clique of
  its columns): SuperLU's MMD_AT_PLUS_A and COLAMD in spirit.
- :func:`threshold_pivots`: left-looking LU (Gilbert and Peierls) of the present matrix in
  that column order with threshold partial pivoting: the matched row whenever its magnitude
  is at least ``threshold`` times the column's largest candidate, else the largest. Only the
  row order is kept; compiled/fill.py then finds the pattern of L and U on it.
"""

from __future__ import annotations

import numpy as np

from circuitsim.solver.compiled.fill import _grown
from circuitsim.solver.jit import njit

_ONE = np.uint64(1)
_M1 = np.uint64(0x5555555555555555)
_M2 = np.uint64(0x3333333333333333)
_M4 = np.uint64(0x0F0F0F0F0F0F0F0F)
_H01 = np.uint64(0x0101010101010101)


@njit(cache=True, inline="always")
def _popcount(word):
    """The number of set bits of a uint64 (the SWAR sum of bit counts)."""
    word = word - ((word >> _ONE) & _M1)
    word = (word & _M2) + ((word >> np.uint64(2)) & _M2)
    word = (word + (word >> np.uint64(4))) & _M4
    return np.int64((word * _H01) >> np.uint64(56))


@njit(cache=True, inline="always")
def _link(adj, a, b):
    """Nodes a and b adjacent (both bit sets)."""
    adj[a, b >> 6] |= _ONE << np.uint64(b & 63)
    adj[b, a >> 6] |= _ONE << np.uint64(a & 63)


@njit(cache=True)
def minimum_degree(n, ptr, idx):
    """An elimination order of least degree first (ties: the lower index) on the graph of
    ``n`` nodes where node g is adjacent to ``idx[ptr[g]:ptr[g + 1]]`` and they to it (the
    graph of A + A^T from A's compressed columns), as an (n,) int64 array of the nodes in
    the order they are eliminated."""
    words = (n + 63) // 64
    adj = np.zeros((n, words), dtype=np.uint64)
    for g in range(n):
        for e in range(ptr[g], ptr[g + 1]):
            _link(adj, idx[e], g)
    for a in range(n):  # no loops
        adj[a, a >> 6] &= ~(_ONE << np.uint64(a & 63))
    degree = np.zeros(n, dtype=np.int64)
    for a in range(n):
        for w in range(words):
            degree[a] += _popcount(adj[a, w])
    alive = np.ones(n, dtype=np.bool_)
    order = np.empty(n, dtype=np.int64)
    for k in range(n):
        v = -1
        for a in range(n):
            if alive[a] and (v < 0 or degree[a] < degree[v]):
                v = a
        order[k] = v
        alive[v] = False
        # v's neighbours become a clique; the rows of live nodes hold live nodes only
        for w in range(words):
            bits = adj[v, w]
            while bits:
                low = bits & (~bits + _ONE)
                bits ^= low
                u = w * 64 + _popcount(low - _ONE)
                count = 0
                for x in range(words):
                    adj[u, x] |= adj[v, x]
                adj[u, u >> 6] &= ~(_ONE << np.uint64(u & 63))
                adj[u, v >> 6] &= ~(_ONE << np.uint64(v & 63))
                for x in range(words):
                    count += _popcount(adj[u, x])
                degree[u] = count
    return order


@njit(cache=True)
def maximum_matching(a_ptr, a_row, first):
    """A row for as many columns as can have one, no row twice, of the (n, n) pattern in
    compressed columns (``a_ptr``, ``a_row``): ``row_of`` (n,) int64, -1 where a column has
    none (the matrix is structurally singular). The entries are offered in the order
    ``first`` (positions into ``a_row``: the largest relative to their column first, so that
    the pairs are the pivots that hold whatever the devices do); a search for augmenting
    paths then matches the columns left."""
    n = a_ptr.size - 1
    row_of = np.full(n, -1, dtype=np.int64)
    col_of = np.full(n, -1, dtype=np.int64)  # the column each row is matched to
    column = np.empty(a_row.size, dtype=np.int64)
    for j in range(n):
        column[a_ptr[j] : a_ptr[j + 1]] = j
    for e in first:
        i, j = a_row[e], column[e]
        if row_of[j] < 0 and col_of[i] < 0:
            row_of[j] = i
            col_of[i] = j
    seen = np.full(n, -1, dtype=np.int64)  # seen[i] == j0: row i visited searching for j0
    stack = np.empty(n, dtype=np.int64)  # the columns of the present path
    place = np.empty(n, dtype=np.int64)  # the next entry to try of each
    for j0 in range(n):
        if row_of[j0] >= 0:
            continue
        top = 0
        stack[0] = j0
        place[0] = a_ptr[j0]
        free = -1
        while top >= 0 and free < 0:
            j = stack[top]
            deeper = False
            while place[top] < a_ptr[j + 1]:
                i = a_row[place[top]]
                place[top] += 1
                if seen[i] == j0:
                    continue
                seen[i] = j0
                if col_of[i] < 0:
                    free = i
                else:
                    top += 1
                    stack[top] = col_of[i]
                    place[top] = a_ptr[col_of[i]]
                    deeper = True
                break
            if free < 0 and not deeper:
                top -= 1
        if free < 0:
            continue
        # along the path each column takes the row that led to the next one
        i = free
        for t in range(top, -1, -1):
            j = stack[t]
            before = row_of[j]
            row_of[j] = i
            col_of[i] = j
            i = before
    return row_of


@njit(cache=True, inline="always")
def _enter(i, k, touched, pattern, count, x):
    """Row ``i`` in column k's pattern (its value zero when new); the new count."""
    if touched[i] != k:
        touched[i] = k
        pattern[count] = i
        count += 1
        x[i] = 0.0
    return count


@njit(cache=True)
def threshold_pivots(a_ptr, a_row, a_val, col_order, preferred, threshold):
    """The row of each pivot of the (n, n) matrix in compressed columns (``a_ptr``,
    ``a_row``, ``a_val``) factored in the column order ``col_order`` with threshold partial
    pivoting: column ``j`` takes row ``preferred[j]`` (-1: none) when that row is still free
    and its magnitude is at least ``threshold`` times the largest free one, else the largest.

    Returns
    -------
    row_to : ndarray of int64, shape (n,)
        Row i is the pivot of step ``row_to[i]`` (SuperLU's ``perm_r``).
    failed : int
        -1, or the column with no nonzero candidate (the matrix is singular).
    """
    n = a_ptr.size - 1
    row_to = np.full(n, -1, dtype=np.int64)
    pivot_row = np.empty(n, dtype=np.int64)
    l_ptr = np.zeros(n + 1, dtype=np.int64)
    l_row = np.empty(max(4 * a_row.size, 16), dtype=np.int64)
    l_val = np.empty(l_row.size)
    x = np.zeros(n)
    touched = np.full(n, -1, dtype=np.int64)  # touched[i] == k: row i in column k's pattern
    pattern = np.empty(n, dtype=np.int64)
    mark = np.full(n, -1, dtype=np.int64)  # mark[s] == k: step s reached for column k
    stack = np.empty(n, dtype=np.int64)
    place = np.empty(n, dtype=np.int64)
    post = np.empty(n, dtype=np.int64)  # the steps reached, in postorder
    for k in range(n):
        j = col_order[k]
        count = 0
        done = 0
        for e in range(a_ptr[j], a_ptr[j + 1]):
            i = a_row[e]
            count = _enter(i, k, touched, pattern, count, x)
            x[i] += a_val[e]
            root = row_to[i]
            if root < 0 or mark[root] == k:
                continue
            mark[root] = k  # depth-first from step root through the L columns
            top = 0
            stack[0] = root
            place[0] = l_ptr[root]
            while top >= 0:
                s = stack[top]
                if place[top] < l_ptr[s + 1]:
                    nxt = row_to[l_row[place[top]]]
                    place[top] += 1
                    if nxt >= 0 and mark[nxt] != k:
                        mark[nxt] = k
                        top += 1
                        stack[top] = nxt
                        place[top] = l_ptr[nxt]
                else:
                    post[done] = s
                    done += 1
                    top -= 1
        for q in range(done - 1, -1, -1):  # reverse postorder: each step after those it needs
            s = post[q]
            factor = x[pivot_row[s]]
            for e in range(l_ptr[s], l_ptr[s + 1]):
                r = l_row[e]
                count = _enter(r, k, touched, pattern, count, x)
                x[r] -= l_val[e] * factor
        largest = 0.0
        best = -1
        for q in range(count):
            r = pattern[q]
            if row_to[r] < 0 and abs(x[r]) > largest:
                largest = abs(x[r])
                best = r
        if best < 0:
            return row_to, j
        want = preferred[j]
        if want >= 0 and touched[want] == k and row_to[want] < 0:
            if abs(x[want]) >= threshold * largest:
                best = want
        row_to[best] = k
        pivot_row[k] = best
        pivot = x[best]
        if l_ptr[k] + count > l_row.size:
            l_row = _grown(l_row, l_ptr[k] + count)
            l_val = _grown(l_val, l_ptr[k] + count)
        used = l_ptr[k]
        for q in range(count):
            r = pattern[q]
            if row_to[r] < 0 and x[r] != 0.0:
                l_row[used] = r
                l_val[used] = x[r] / pivot
                used += 1
        l_ptr[k + 1] = used
    return row_to, -1


SEARCH_FUNCTIONS = (maximum_matching, minimum_degree, threshold_pivots)  # called from Python
