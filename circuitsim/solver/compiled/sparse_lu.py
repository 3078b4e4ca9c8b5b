"""Sparse LU of the whole MNA matrix with a fixed pivot order, refactored in compiled code.

What ngspice's Sparse 1.3 does per Newton iteration: the matrix keeps its pattern from one
iteration to the next (the devices change values, never positions), so the ordering and the
fill pattern are found once and every later factorization is numeric only.

- compiled/sparse_order.py (Python, once per run and again only when a pivot has become too
  small) finds the row and column permutations and the pattern of L and U without pivoting.
- :func:`refactor` (numba): left-looking LU on that pattern, no pivoting; it reports a pivot
  smaller than ``PIVOT_THRESHOLD`` times the largest entry of its column, on which the caller
  orders again at the present values. :func:`refactor_marked` redoes only the columns that
  can differ from the present factors: those whose entries changed (:func:`mark_changed`: a
  port whose conductance changed, every charge column when a0 did, the multi-terminal
  devices' columns) and those whose U column reaches a redone one (their L and U are
  computed from it); the others' L and U are what a whole refactor would compute again, bit
  for bit. Which columns a change reaches depends on the pattern only, so it is found once
  per order (compiled/fill.py, ``reach_sets``: for each port, for M and for the
  multi-terminal devices, a set of columns as the bits of 64-bit words), and
  :func:`mark_changed` takes the union of the sets of what changed.
- :func:`lu_solve` (numba): the two triangular solves with the permutations.

The matrix is ``A = G + a0 M + sum_k g_k w_k w_k^T + T`` (w_k = e_p - e_n: junction and
switch ports; T: the entries of multi-terminal devices, ``extra`` below, at fixed (row,
column) positions); its values in the permuted column-compressed order are assembled by
:func:`assemble` from the constant parts and the port conductances, through positions
computed once, and the extra entries are added at ``extra_pos`` (compiled/mna_terminals.py).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from circuitsim.solver.jit import library_in_use, njit

# a pivot below this fraction of its column's largest entry asks for a new pivot order (the
# relative threshold of ngspice's spOrderAndFactor, PivRelThreshold 1e-3)
PIVOT_THRESHOLD = 1e-3
# columns per word of a set of columns (bit j % WORD of word j // WORD: column j)
WORD = 64


class SparseLU(NamedTuple):
    """A fixed-pattern LU of the permuted matrix P = A[row_of, col_of] (n unknowns).

    ``a_*``: P in compressed columns; G, M and each port's four stamps as positions into
    ``a_val``. ``l_*``: the strictly lower part of L (unit diagonal), ``u_*``: U with its
    diagonal last in each column, stored as its inverse.
    """

    a_ptr: np.ndarray  # (n + 1,) int64
    a_row: np.ndarray  # (nnz,) int64
    a_val: np.ndarray  # (nnz,) the present values
    g_val: np.ndarray  # (nnz,) G's part of each entry
    m_val: np.ndarray  # (nnz,) M's part (times a0)
    port_pos: np.ndarray  # (nports, 4) int64: entries of (p,p), (n,n), (p,n), (n,p); -1 none
    l_ptr: np.ndarray
    l_row: np.ndarray
    l_val: np.ndarray
    u_ptr: np.ndarray
    u_row: np.ndarray
    u_val: np.ndarray
    row_to: np.ndarray  # (n,) int64: row i of A is row row_to[i] of P
    col_of: np.ndarray  # (n,) int64: column j of P is column col_of[j] of A
    work: np.ndarray  # (n,) scratch, zero between calls
    flops: float  # about the multiply-adds of one refactor (for profiles)
    extra_row: np.ndarray  # (ne,) int64: row and column in A of each extra entry (-1 ground)
    extra_col: np.ndarray
    extra_pos: np.ndarray  # (ne,) int64: its position in a_val (-1: a ground entry)
    entry_col: np.ndarray  # (nnz,) int64: the column of P of each entry
    m_cols: np.ndarray  # int64: the columns of P with an entry of M
    extra_cols: np.ndarray  # int64: the columns of P with an extra entry
    # the port conductances, then the a0, of the present factors (NaN: none, or a refactor
    # that stopped at a small pivot)
    factored: np.ndarray  # (nports + 1,)
    # the columns to redo when a port's conductance changes (its stamps' columns and those
    # they reach), when a0 does (M's), and at every iteration (the extra entries'); sets of
    # columns as (words,) uint64 (bit j % WORD of word j // WORD: column j), words = n / WORD
    # rounded up; port_from: each port's first word that is not zero
    port_reach: np.ndarray  # (nports, words) uint64
    port_from: np.ndarray  # (nports,) int64
    m_reach: np.ndarray  # (words,) uint64
    extra_reach: np.ndarray  # (words,) uint64
    redo: np.ndarray  # (words,) uint64 scratch: the columns to redo, zero between calls


@njit(cache=True, inline="always")
def assemble(a_val, g_val, m_val, a0, port_pos, gd, g_sw_present):
    """a_val = G + a0 M + the ports' stamps (junction conductances gd (md,), then the
    switches' present conductances (ms,))."""
    for e in range(a_val.size):
        a_val[e] = g_val[e] + a0 * m_val[e]
    md = gd.size
    for k in range(port_pos.shape[0]):
        g = gd[k] if k < md else g_sw_present[k - md]
        for slot in range(4):
            pos = port_pos[k, slot]
            if pos >= 0:
                a_val[pos] += g if slot < 2 else -g


# mark_changed's answer when there are no valid factors (else the first column it marked)
ALL_COLUMNS = -1


@njit(cache=True, inline="always")
def _add_set(redo, reach, start):
    """redo |= reach, from word ``start`` on."""
    for w in range(start, redo.size):
        redo[w] |= reach[w]


@njit(cache=True, inline="always")
def first_column(redo) -> int:
    """The first column in the set ``redo`` (WORD times its size when it is empty)."""
    for w in range(redo.size):
        if redo[w] != 0:
            return w * WORD + int(trailing_zeros(redo[w]))
    return redo.size * WORD


@njit(cache=True, inline="always")
def mark_changed(port_reach, port_from, m_reach, extra_reach, factored, redo, gd, g_sw_present,
                 a0, n) -> int:  # fmt: skip
    """Add to ``redo`` the columns of P whose factors can differ from those the present
    factors were made from (the reach sets of what changed: fill.reach_sets), and record
    the values about to be factored in ``factored``. Returns ALL_COLUMNS (no valid factors:
    refactor them all), else the first column marked (``n`` when none is: the factors
    hold). Exact comparisons: a conductance or a0 equal bit for bit stamps the same
    entries."""
    nports = factored.size - 1
    md = gd.size
    every = np.isnan(factored[nports])
    _add_set(redo, extra_reach, 0)  # the multi-terminal devices' entries: at every iteration
    if a0 != factored[nports]:
        factored[nports] = a0
        _add_set(redo, m_reach, 0)
    for k in range(nports):
        g = gd[k] if k < md else g_sw_present[k - md]
        if g != factored[k]:  # also when factored[k] is NaN
            factored[k] = g
            _add_set(redo, port_reach[k], port_from[k])
    return ALL_COLUMNS if every else min(first_column(redo), n)


@njit(cache=True, inline="always")
def _factor_column(j, a_ptr, a_row, a_val, l_ptr, l_row, l_val, u_ptr, u_row, u_val,
                   work) -> bool:  # fmt: skip
    """Column j of L and U from P's column j and the L columns k < j with U[k, j] != 0
    (left-looking); True when its pivot is below PIVOT_THRESHOLD of the column."""
    for e in range(a_ptr[j], a_ptr[j + 1]):
        work[a_row[e]] = a_val[e]
    last = u_ptr[j + 1] - 1  # the diagonal
    for e in range(u_ptr[j], last):  # rows k < j, ascending: a topological order
        k = u_row[e]
        ukj = work[k]
        u_val[e] = ukj
        work[k] = 0.0
        if ukj != 0.0:
            for f in range(l_ptr[k], l_ptr[k + 1]):
                work[l_row[f]] -= l_val[f] * ukj
    pivot = work[j]
    work[j] = 0.0
    inv = 1.0 / pivot if pivot != 0.0 else 0.0
    u_val[last] = inv
    largest = 0.0  # |L| entries above 1 / PIVOT_THRESHOLD: the pivot is too small
    for f in range(l_ptr[j], l_ptr[j + 1]):
        i = l_row[f]
        value = work[i] * inv
        l_val[f] = value
        largest = max(largest, abs(value))
        work[i] = 0.0
    return pivot == 0.0 or not largest <= 1.0 / PIVOT_THRESHOLD


@njit(cache=True)
def refactor(a_ptr, a_row, a_val, l_ptr, l_row, l_val, u_ptr, u_row, u_val, work, redo,
             every) -> int:  # fmt: skip
    """Left-looking LU of P (compressed columns) on the fixed pattern: -1 when done, else the
    column whose pivot is below PIVOT_THRESHOLD of its column (a new pivot order is due).
    U's diagonal is stored inverted (the solves multiply by it). Unless ``every``, only the
    columns in the set ``redo`` (:func:`refactor_marked`) are computed; ``redo`` is
    cleared."""
    if not every:
        return refactor_marked(a_ptr, a_row, a_val, l_ptr, l_row, l_val, u_ptr, u_row, u_val,
                               work, redo, 0)  # fmt: skip
    redo[:] = 0
    for j in range(a_ptr.size - 1):
        if _factor_column(j, a_ptr, a_row, a_val, l_ptr, l_row, l_val, u_ptr, u_row, u_val,
                          work):  # fmt: skip
            return j
    return -1


@njit(cache=True)
def refactor_marked(a_ptr, a_row, a_val, l_ptr, l_row, l_val, u_ptr, u_row, u_val, work,
                    redo, first) -> int:  # fmt: skip
    """:func:`refactor` of the columns in the set ``redo`` (by :func:`mark_changed`, the
    first of them ``first``): with each column, the columns it reaches (column j is
    computed from the columns k with U[k, j] != 0), so the others keep their factors, which
    depend on nothing redone: bit for bit what a whole refactor computes. In ascending
    order. -1 when done, else the column of a too small pivot; ``redo`` is cleared."""
    column = -1
    for w in range(first // WORD, redo.size):
        bits = redo[w]
        redo[w] = 0
        while bits != 0 and column < 0:
            j = w * WORD + int(trailing_zeros(bits))
            bits &= bits - np.uint64(1)
            if _factor_column(j, a_ptr, a_row, a_val, l_ptr, l_row, l_val, u_ptr, u_row, u_val,
                              work):  # fmt: skip
                column = j
    return column


@njit(cache=True)
def lu_solve(l_ptr, l_row, l_val, u_ptr, u_row, u_val, row_to, col_of, b, work, x):
    """x = A^-1 b through the factors of P (work: scratch of size n, zero on return)."""
    n = b.size
    for i in range(n):
        work[row_to[i]] = b[i]
    for j in range(n):  # L y = P_r b (unit diagonal)
        yj = work[j]
        if yj != 0.0:
            for f in range(l_ptr[j], l_ptr[j + 1]):
                work[l_row[f]] -= l_val[f] * yj
    for j in range(n - 1, -1, -1):  # U z = y, column by column
        last = u_ptr[j + 1] - 1
        zj = work[j] * u_val[last]  # the inverted diagonal
        work[j] = zj
        if zj != 0.0:
            for e in range(u_ptr[j], last):
                work[u_row[e]] -= u_val[e] * zj
    for j in range(n):
        x[col_of[j]] = work[j]
        work[j] = 0.0


@njit(cache=True)
def lu_solve_rows(l_ptr, l_row, l_val, u_ptr, u_row, u_val, row_to, col_of, b, work, x):
    """x[k] = A^-1 b[k] for each row k of b and x ((m, n)): :func:`lu_solve` of m
    right-hand sides in one call from Python."""
    for k in range(b.shape[0]):
        lu_solve(l_ptr, l_row, l_val, u_ptr, u_row, u_val, row_to, col_of, b[k], work, x[k])


def _on_numba():
    global trailing_zeros
    from numba.cpython.unsafe.numbers import trailing_zeros


trailing_zeros = None
if not library_in_use():
    _on_numba()
