"""Sparse LU of the whole MNA matrix with a fixed pivot order, refactored in compiled code.

What ngspice's Sparse 1.3 does per Newton iteration: the matrix keeps its pattern from one
iteration to the next (the devices change values, never positions), so the ordering and the
fill pattern are found once and every later factorization is numeric only.

- :func:`analyse` (Python, once per run and again only when a pivot has become too small):
  SuperLU (``scipy.sparse.linalg.splu``, COLAMD column order, threshold partial pivoting) on
  the present matrix gives the row and column permutations; a second symbolic pass on the
  permuted pattern with generic values gives the pattern of L and U without pivoting.
- :func:`refactor` (numba): left-looking LU on that pattern, no pivoting; it reports a pivot
  smaller than ``PIVOT_THRESHOLD`` times the largest entry of its column, on which the caller
  analyses again at the present values. :func:`refactor_marked` redoes only the columns that
  can differ from the present factors: those whose entries changed (:func:`mark_changed`: a
  port whose conductance changed, every charge column when a0 did, the multi-terminal
  devices' columns) and those whose U column reaches a redone one (their L and U are
  computed from it), found through U's rows; the others' L and U are what a whole refactor
  would compute again, bit for bit.
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
import scipy.sparse as sp
from numba import njit
from scipy.sparse.linalg import splu

# a pivot below this fraction of its column's largest entry asks for a new pivot order (the
# relative threshold of ngspice's spOrderAndFactor, PivRelThreshold 1e-3)
PIVOT_THRESHOLD = 1e-3
COLUMN_ORDER = "COLAMD"  # SuperLU's column order for the pivot order (permc_spec)


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
    dirty: np.ndarray  # (n,) bool scratch: the columns to redo, False between calls


def port_stamps(n: int, port_p: np.ndarray, port_n: np.ndarray):
    """(rows, cols, signs, port) of the four stamps of every port (ground entries left out)."""
    rows, cols, signs, which = [], [], [], []
    for k, (p, m) in enumerate(zip(port_p, port_n, strict=True)):
        for (i, j), sign in (((p, p), 1.0), ((m, m), 1.0), ((p, m), -1.0), ((m, p), -1.0)):
            if i >= 0 and j >= 0:
                rows.append(i)
                cols.append(j)
                signs.append(sign)
                which.append(k)
    return (np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64),
            np.array(signs), np.array(which, dtype=np.int64))  # fmt: skip


def _no_extra():
    empty = np.zeros(0, dtype=np.int64)
    return empty, empty, np.zeros(0)


def present_matrix(G, M, port_p, port_n, values, a0, extra=None) -> sp.csc_matrix:
    """A = G + a0 M + W diag(values) W^T + T as a sparse matrix (values: port conductances;
    ``extra`` = (rows, cols, values) of T, ground entries (-1) left out)."""
    n = G.shape[0]
    rows, cols, signs, which = port_stamps(n, port_p, port_n)
    ports = sp.coo_matrix((signs * values[which], (rows, cols)), shape=(n, n))
    e_row, e_col, e_val = _no_extra() if extra is None else extra
    inside = (e_row >= 0) & (e_col >= 0)
    terminals = sp.coo_matrix((e_val[inside], (e_row[inside], e_col[inside])), shape=(n, n))
    return sp.csc_matrix(sp.csc_matrix(G) + a0 * sp.csc_matrix(M) + ports + terminals)


def analyse(G, M, port_p, port_n, values, a0, spare: float = 1.0, extra=None) -> SparseLU:
    """The pivot order at the present values and the fixed pattern it gives; L and U get
    room for ``spare`` times their fill (a later order, :func:`repivot`, may need more).
    ``extra``: (rows, cols, values) of entries besides G, M and the ports (multi-terminal
    devices; -1: ground, left out), part of the pattern whatever their values.

    Raises
    ------
    np.linalg.LinAlgError
        The present matrix is singular.
    """
    n = G.shape[0]
    # sparse once: a dense G or M (the plan's) scanned at each use cost 13 ms a scan at 1282
    # unknowns, 6 scans per order
    G, M = sp.csc_matrix(G), sp.csc_matrix(M)
    extra = _no_extra() if extra is None else extra
    e_row, e_col = (np.asarray(e, dtype=np.int64) for e in extra[:2])
    A = present_matrix(G, M, port_p, port_n, values, a0, (e_row, e_col, extra[2]))
    try:
        # no equilibration: refactor's pivot test is on the unscaled columns
        lu = splu(A, permc_spec=COLUMN_ORDER, diag_pivot_thresh=0.1, options={"Equil": False})
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise np.linalg.LinAlgError(str(exc)) from None
    row_to = np.asarray(lu.perm_r, dtype=np.int64)
    col_rank = np.asarray(lu.perm_c, dtype=np.int64)  # column j of A is column col_rank[j]
    col_of = np.argsort(col_rank)
    # the pattern of every matrix of the run: G, M and all port stamps, whatever the values
    rows, cols, _, _ = port_stamps(n, port_p, port_n)
    inside = (e_row >= 0) & (e_col >= 0)
    rows, cols = np.concatenate([rows, e_row[inside]]), np.concatenate([cols, e_col[inside]])
    ones = np.ones(rows.size)
    pattern = (abs(G) + abs(M) + sp.csc_matrix((ones, (rows, cols)), shape=(n, n))).tocoo()
    pattern = sp.csc_matrix(
        (np.ones(pattern.nnz), (row_to[pattern.row], col_rank[pattern.col])),
        shape=(n, n),
    )
    pattern.sum_duplicates()
    pattern.sort_indices()
    # L and U of the permuted pattern without pivoting: generic values (no cancellation) on
    # it, and a diagonal that dominates so that SuperLU keeps the natural order
    rng = np.random.default_rng(0)
    generic = pattern.copy()
    generic.data = 1.0 + rng.random(generic.nnz)
    generic = generic + sp.identity(n, format="csc") * (2.0 * n)
    symbolic = splu(generic.tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                    options={"SymmetricMode": True})  # fmt: skip
    if not (np.array_equal(symbolic.perm_r, np.arange(n))
            and np.array_equal(symbolic.perm_c, np.arange(n))):  # fmt: skip
        raise AssertionError("sparse_lu.analyse: the symbolic pass pivoted")
    L = sp.csc_matrix(symbolic.L)
    L.sort_indices()
    U = sp.csc_matrix(symbolic.U)
    U.sort_indices()
    L = sp.tril(L, k=-1, format="csc")
    L.sort_indices()
    # every stored entry of P, with its positions for G, M and the ports: entries are
    # sorted by (column, row), so the key column * n + row finds them by bisection
    a_ptr, a_row = pattern.indptr.astype(np.int64), pattern.indices.astype(np.int64)
    keys = np.repeat(np.arange(n, dtype=np.int64), np.diff(a_ptr)) * n + a_row

    def positions(i, j) -> np.ndarray:
        return np.searchsorted(keys, col_rank[j] * n + row_to[i])

    def scatter(matrix) -> np.ndarray:
        coo = sp.coo_matrix(matrix)
        out = np.zeros(a_row.size)
        np.add.at(out, positions(coo.row, coo.col), coo.data)
        return out

    port_pos = -np.ones((len(port_p), 4), dtype=np.int64)
    for slot, (i, j) in enumerate(((port_p, port_p), (port_n, port_n),
                                   (port_p, port_n), (port_n, port_p))):  # fmt: skip
        i, j = np.asarray(i, dtype=np.int64), np.asarray(j, dtype=np.int64)
        stamped = (i >= 0) & (j >= 0)
        port_pos[stamped, slot] = positions(i[stamped], j[stamped])
    extra_pos = -np.ones(e_row.size, dtype=np.int64)
    extra_pos[inside] = positions(e_row[inside], e_col[inside])
    l_count = np.diff(L.indptr)
    flops = float(np.sum(l_count * np.diff(U.indptr)) + L.nnz)
    m_val = scatter(M)
    entry_col = np.repeat(np.arange(n, dtype=np.int64), np.diff(a_ptr))
    return SparseLU(
        a_ptr=a_ptr,
        a_row=a_row,
        a_val=np.zeros(a_row.size),
        g_val=scatter(G),
        m_val=m_val,
        port_pos=port_pos,
        l_ptr=L.indptr.astype(np.int64),
        l_row=_room(L.indices, spare),
        l_val=np.zeros(_room(L.indices, spare).size),
        u_ptr=U.indptr.astype(np.int64),
        u_row=_room(U.indices, spare),
        u_val=np.zeros(_room(U.indices, spare).size),
        row_to=row_to,
        col_of=col_of,
        work=np.zeros(n),
        flops=flops,
        extra_row=e_row,
        extra_col=e_col,
        extra_pos=extra_pos,
        entry_col=entry_col,
        m_cols=np.unique(entry_col[m_val != 0]),
        extra_cols=np.unique(entry_col[extra_pos[extra_pos >= 0]]),
        factored=np.full(len(port_p) + 1, np.nan),
        dirty=np.zeros(n, dtype=np.bool_),
    )


def _room(indices: np.ndarray, spare: float) -> np.ndarray:
    out = np.zeros(int(indices.size * spare) + 1, dtype=np.int64)
    out[: indices.size] = indices
    return out


def repivot(lu: SparseLU, port_p, port_n, values, a0, extra_val=None) -> int:
    """A new pivot order at the present values (``extra_val``: of the extra entries, zero if
    not given), written into ``lu``'s arrays in place (the compiled Newton asks for it when
    a pivot has become too small, and goes on with it).
    Returns 0, or 1 when L and U have not room enough for the new fill (the caller then
    makes new arrays with :func:`analyse`).

    Raises
    ------
    np.linalg.LinAlgError
        The present matrix is singular.
    """
    n = lu.row_to.size
    rows = np.argsort(lu.row_to)[lu.a_row]  # the present P's entries back in A's numbering
    cols = lu.col_of[np.repeat(np.arange(n), np.diff(lu.a_ptr))]
    G = sp.csc_matrix((lu.g_val, (rows, cols)), shape=(n, n))
    M = sp.csc_matrix((lu.m_val, (rows, cols)), shape=(n, n))
    extra_val = np.zeros(lu.extra_row.size) if extra_val is None else extra_val
    # G's and M's stored zeros drop out here: the extra entries put their positions back
    new = analyse(G, M, port_p, port_n, values, a0, extra=(lu.extra_row, lu.extra_col, extra_val))
    used_l, used_u = new.l_ptr[-1], new.u_ptr[-1]
    if used_l > lu.l_row.size or used_u > lu.u_row.size:
        return 1
    for name in ("a_ptr", "a_row", "g_val", "m_val", "port_pos", "l_ptr", "u_ptr", "row_to",
                 "col_of", "extra_pos", "entry_col", "factored"):  # fmt: skip
        getattr(lu, name)[...] = getattr(new, name)
    # the same columns hold M and the extra entries in any order (sizes kept), not their places
    lu.m_cols[...] = new.m_cols
    lu.extra_cols[...] = new.extra_cols
    lu.l_row[:used_l] = new.l_row[:used_l]
    lu.u_row[:used_u] = new.u_row[:used_u]
    return 0


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
def mark_changed(entry_col, port_pos, m_cols, extra_cols, factored, dirty, gd, g_sw_present,
                 a0) -> int:  # fmt: skip
    """Mark in ``dirty`` the columns of P whose entries can differ from those the present
    factors were made from, and record the values about to be factored in ``factored``.
    Returns ALL_COLUMNS (no valid factors: refactor them all), else the first column marked
    (n, the size of ``dirty``, when none is: the factors hold). Exact comparisons: a
    conductance or a0 equal bit for bit stamps the same entries. (Marks without a branch:
    listing each column once cost a mispredicted branch per stamp.)"""
    nports = factored.size - 1
    md = gd.size
    every = np.isnan(factored[nports])
    first = dirty.size
    for c in extra_cols:  # the multi-terminal devices' entries: at every iteration
        dirty[c] = True
        first = min(first, c)
    if a0 != factored[nports]:
        factored[nports] = a0
        for c in m_cols:
            dirty[c] = True
            first = min(first, c)
    for k in range(nports):
        g = gd[k] if k < md else g_sw_present[k - md]
        if g != factored[k]:  # also when factored[k] is NaN
            factored[k] = g
            for slot in range(4):
                pos = port_pos[k, slot]
                if pos >= 0:
                    c = entry_col[pos]
                    dirty[c] = True
                    first = min(first, c)
    return ALL_COLUMNS if every else first


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
def refactor(a_ptr, a_row, a_val, l_ptr, l_row, l_val, u_ptr, u_row, u_val, work, dirty,
             every) -> int:  # fmt: skip
    """Left-looking LU of P (compressed columns) on the fixed pattern: -1 when done, else the
    column whose pivot is below PIVOT_THRESHOLD of its column (a new pivot order is due).
    U's diagonal is stored inverted (the solves multiply by it). Unless ``every``, only the
    columns marked in ``dirty`` and those whose U column reaches a redone one are computed
    (:func:`refactor_marked` from column 0); ``dirty`` is cleared."""
    if not every:
        return refactor_marked(a_ptr, a_row, a_val, l_ptr, l_row, l_val, u_ptr, u_row, u_val,
                               work, dirty, 0)  # fmt: skip
    for j in range(a_ptr.size - 1):
        if _factor_column(j, a_ptr, a_row, a_val, l_ptr, l_row, l_val, u_ptr, u_row, u_val,
                          work):  # fmt: skip
            dirty[:] = False
            return j
    dirty[:] = False
    return -1


@njit(cache=True)
def refactor_marked(a_ptr, a_row, a_val, l_ptr, l_row, l_val, u_ptr, u_row, u_val, work,
                    dirty, first) -> int:  # fmt: skip
    """:func:`refactor` of the columns marked in ``dirty`` (by :func:`mark_changed`, the
    first of them ``first``; none before it can be reached) and of those they reach: column
    j is computed from the columns k with U[k, j] != 0, so it is redone when one of those
    is. In ascending order, the others keep their factors, which depend on nothing redone:
    bit for bit what a whole refactor computes. The test of a column's U entries has no
    branch per entry (the reach followed through U's rows, listed, then sorted, cost 1.5-2
    times a whole refactor when many columns were marked). -1 when done, else the column of
    a too small pivot; ``dirty`` is cleared."""
    n = a_ptr.size - 1
    column = -1
    for j in range(first, n):
        if column < 0 and not dirty[j]:
            reached = False
            for e in range(u_ptr[j], u_ptr[j + 1] - 1):
                reached |= dirty[u_row[e]]
            dirty[j] = reached
        if dirty[j] and column < 0:
            if _factor_column(j, a_ptr, a_row, a_val, l_ptr, l_row, l_val, u_ptr, u_row, u_val,
                              work):  # fmt: skip
                column = j
    for j in range(first, n):
        dirty[j] = False
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
