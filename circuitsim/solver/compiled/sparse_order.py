"""The MNA kernel's pivot order and fill pattern, found in Python (compiled/sparse_lu.py factors
and solves on them in compiled code).

- :func:`analyse` (once per run, and again by :func:`repivot` only when a pivot has become
  too small): SuperLU (``scipy.sparse.linalg.splu``, threshold partial pivoting 0.1, no
  equilibration) on the present matrix gives the row and column permutations, once for each
  column order of ``COLUMN_ORDERS``; the pattern of L and U without pivoting follows from
  each (compiled/fill.py), and the order whose Newton iteration costs fewest operations
  (:func:`iteration_cost`) is kept.

The matrix is ``A = G + a0 M + sum_k g_k w_k w_k^T + T`` (w_k = e_p - e_n: junction and
switch ports; T: the entries of multi-terminal devices, ``extra`` below, at fixed (row,
column) positions); its pattern is that of every matrix of the run, whatever the values.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order
from scipy.sparse.linalg import splu

from circuitsim.solver.compiled.fill import lu_pattern, reach_sets, upper_by_rows
from circuitsim.solver.compiled.sparse_lu import SparseLU

# SuperLU's column orders (permc_spec) tried for each pivot order; the first is kept unless
# another's iteration costs less than ORDER_MARGIN of its own (docs/solver.md, "The MNA
# kernel": what the choice changes on the golden netlists and the chains)
COLUMN_ORDERS = ("COLAMD", "MMD_AT_PLUS_A")
ORDER_MARGIN = 0.8


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


def analyse(G, M, port_p, port_n, values, a0, spare: float = 1.0, extra=None,
            changing=None) -> SparseLU:  # fmt: skip
    """The pivot order at the present values and the fixed pattern it gives; L and U get
    room for ``spare`` times their fill (a later order, :func:`repivot`, may need more).
    ``extra``: (rows, cols, values) of entries besides G, M and the ports (multi-terminal
    devices; -1: ground, left out), part of the pattern whatever their values. ``changing``:
    (nports,) bool, the ports whose conductance changes at every Newton iteration (the
    charged junctions; default none), whose columns the choice of order weighs.

    Raises
    ------
    np.linalg.LinAlgError
        The present matrix is singular.
    """
    return pivot_orders(G, M, port_p, port_n, values, a0, spare, extra, changing)[0]


def pivot_orders(G, M, port_p, port_n, values, a0, spare: float = 1.0, extra=None,
                 changing=None) -> list[SparseLU]:  # fmt: skip
    """:func:`analyse`'s pivot order, then the other column orders' (one per column order
    of ``COLUMN_ORDERS`` on which the matrix is not singular), for a later matrix that the
    chosen one does not suit (compiled/order_cache.py).

    Raises
    ------
    np.linalg.LinAlgError
        The present matrix is singular.
    """
    n = G.shape[0]
    # sparse once: a dense G or M scanned at each use cost 13 ms a scan at 1282 unknowns
    G, M = sp.csc_matrix(G), sp.csc_matrix(M)
    extra = _no_extra() if extra is None else extra
    e_row, e_col = (np.asarray(e, dtype=np.int64) for e in extra[:2])
    A = present_matrix(G, M, port_p, port_n, values, a0, (e_row, e_col, extra[2]))
    # the pattern of every matrix of the run: G, M and all port stamps, whatever the values
    rows, cols, _, _ = port_stamps(n, port_p, port_n)
    inside = (e_row >= 0) & (e_col >= 0)
    rows, cols = np.concatenate([rows, e_row[inside]]), np.concatenate([cols, e_col[inside]])
    ones = np.ones(rows.size)
    pattern = (abs(G) + abs(M) + sp.csc_matrix((ones, (rows, cols)), shape=(n, n))).tocoo()
    changing = np.zeros(len(port_p), dtype=bool) if changing is None else changing
    orders, best_cost = [], np.inf
    for column_order in COLUMN_ORDERS:
        try:
            # no equilibration: refactor's pivot test is on the unscaled columns
            lu = splu(A, permc_spec=column_order, diag_pivot_thresh=0.1,
                      options={"Equil": False})  # fmt: skip
        except RuntimeError:  # "Factor is exactly singular"
            continue
        candidate = _on_order(G, M, port_p, port_n, e_row, e_col, pattern, lu, spare)
        cost = iteration_cost(candidate, changing)
        if not orders or cost < ORDER_MARGIN * best_cost:
            orders.insert(0, candidate)
            best_cost = cost
        else:
            orders.append(candidate)
    if not orders:
        raise np.linalg.LinAlgError(f"singular matrix ({n} unknowns): no pivot order")
    return orders


def _on_order(G, M, port_p, port_n, e_row, e_col, pattern, lu, spare: float) -> SparseLU:
    """The SparseLU of the pivot order SuperLU's ``lu`` chose, on the run's ``pattern``."""
    n = G.shape[0]
    row_to = np.asarray(lu.perm_r, dtype=np.int64)
    col_rank = np.asarray(lu.perm_c, dtype=np.int64)  # column j of A is column col_rank[j]
    col_of = np.argsort(col_rank)
    permuted = sp.csc_matrix(
        (np.ones(pattern.nnz), (row_to[pattern.row], col_rank[pattern.col])), shape=(n, n)
    )
    permuted.sum_duplicates()
    permuted.sort_indices()
    l_ptr, l_row, u_ptr, u_row = lu_pattern(permuted.indptr.astype(np.int64),
                                            permuted.indices.astype(np.int64))  # fmt: skip
    # every stored entry of P, with its positions for G, M and the ports: entries are
    # sorted by (column, row), so the key column * n + row finds them by bisection
    a_ptr, a_row = permuted.indptr.astype(np.int64), permuted.indices.astype(np.int64)
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
    inside = (e_row >= 0) & (e_col >= 0)
    extra_pos = -np.ones(e_row.size, dtype=np.int64)
    extra_pos[inside] = positions(e_row[inside], e_col[inside])
    flops = float(np.sum(np.diff(l_ptr) * np.diff(u_ptr)) + l_row.size)
    m_val = scatter(M)
    entry_col = np.repeat(np.arange(n, dtype=np.int64), np.diff(a_ptr))
    m_cols = np.unique(entry_col[m_val != 0])
    extra_cols = np.unique(entry_col[extra_pos[extra_pos >= 0]])
    port_reach, port_from, m_reach, extra_reach = _reach(u_ptr, u_row, entry_col, port_pos,
                                                         m_cols, extra_cols)  # fmt: skip
    l_room, u_room = _room(l_row, spare), _room(u_row, spare)
    return SparseLU(
        a_ptr=a_ptr,
        a_row=a_row,
        a_val=np.zeros(a_row.size),
        g_val=scatter(G),
        m_val=m_val,
        port_pos=port_pos,
        l_ptr=l_ptr,
        l_row=l_room,
        l_val=np.zeros(l_room.size),
        u_ptr=u_ptr,
        u_row=u_room,
        u_val=np.zeros(u_room.size),
        row_to=row_to,
        col_of=col_of,
        work=np.zeros(n),
        flops=flops,
        extra_row=e_row,
        extra_col=e_col,
        extra_pos=extra_pos,
        entry_col=entry_col,
        m_cols=m_cols,
        extra_cols=extra_cols,
        factored=np.full(len(port_p) + 1, np.nan),
        port_reach=port_reach,
        port_from=port_from,
        m_reach=m_reach,
        extra_reach=extra_reach,
        redo=np.zeros(m_reach.size, dtype=np.uint64),
    )


def _reach(u_ptr, u_row, entry_col, port_pos, m_cols, extra_cols):
    """The reach sets of SparseLU (port_reach, port_from, m_reach, extra_reach): the columns
    each port's stamps are in, M's and the extra entries', and the columns they reach."""
    stamped = np.where(port_pos >= 0, entry_col[np.maximum(port_pos, 0)], -1)
    sets = [np.unique(row[row >= 0]) for row in stamped] + [m_cols, extra_cols]
    seed_ptr = np.concatenate([[0], np.cumsum([c.size for c in sets])]).astype(np.int64)
    seed_col = np.concatenate(sets).astype(np.int64)
    reach, first = reach_sets(u_ptr, u_row, seed_ptr, seed_col)
    return reach[:-2].copy(), first[:-2].copy(), reach[-2].copy(), reach[-1].copy()


def iteration_cost(lu: SparseLU, changing: np.ndarray) -> float:
    """About the multiply-adds of one Newton iteration on the order ``lu``: the refactor of
    the columns that the ``changing`` ports' and the multi-terminal devices' columns reach
    (sparse_lu.refactor_marked's columns when all of them changed), and the two triangular
    solves."""
    n = lu.row_to.size
    l_count = np.diff(lu.l_ptr)
    stamped = lu.port_pos[np.asarray(changing, dtype=bool)]
    changed = np.unique(np.concatenate([lu.entry_col[stamped[stamped >= 0]], lu.extra_cols]))
    # the graph k -> j of U[k, j] != 0 (column j is computed from column k), and a node n
    # that leads to every changed column
    ut_ptr, ut_col = upper_by_rows(lu.u_ptr, lu.u_row[: lu.u_ptr[-1]])
    sources = np.concatenate([np.repeat(np.arange(n), np.diff(ut_ptr)),
                              np.full(changed.size, n)])  # fmt: skip
    targets = np.concatenate([ut_col, changed])
    graph = sp.csr_matrix((np.ones(sources.size), (sources, targets)), shape=(n + 1, n + 1))
    reached = breadth_first_order(graph, n, directed=True, return_predecessors=False)
    reached = reached[reached < n]
    # column j: its U column's k < j each subtract L column k, then L column j is scaled
    u_used = lu.u_ptr[-1]
    u_col = np.repeat(np.arange(n), np.diff(lu.u_ptr))
    upper = lu.u_row[:u_used] != u_col
    per_column = np.bincount(u_col[upper], weights=l_count[lu.u_row[:u_used][upper]],
                             minlength=n) + l_count  # fmt: skip
    return float(per_column[reached].sum() + lu.l_ptr[-1] + u_used)


def _room(indices: np.ndarray, spare: float) -> np.ndarray:
    out = np.zeros(int(indices.size * spare) + 1, dtype=np.int64)
    out[: indices.size] = indices
    return out


def repivot(lu: SparseLU, port_p, port_n, values, a0, extra_val=None, changing=None) -> int:
    """A new pivot order at the present values (``extra_val``: of the extra entries, zero if
    not given; ``changing`` as for :func:`analyse`), written into ``lu``'s arrays in place
    (the compiled Newton asks for it when a pivot has become too small, and goes on with it).
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
    new = analyse(G, M, port_p, port_n, values, a0,
                  extra=(lu.extra_row, lu.extra_col, extra_val), changing=changing)  # fmt: skip
    used_l, used_u = new.l_ptr[-1], new.u_ptr[-1]
    if used_l > lu.l_row.size or used_u > lu.u_row.size:
        return 1
    for name in ("a_ptr", "a_row", "g_val", "m_val", "port_pos", "l_ptr", "u_ptr", "row_to",
                 "col_of", "extra_pos", "entry_col", "factored", "port_reach", "port_from",
                 "m_reach", "extra_reach"):  # fmt: skip
        getattr(lu, name)[...] = getattr(new, name)
    # the same columns hold M and the extra entries in any order (sizes kept), not their places
    lu.m_cols[...] = new.m_cols
    lu.extra_cols[...] = new.extra_cols
    lu.l_row[:used_l] = new.l_row[:used_l]
    lu.u_row[:used_u] = new.u_row[:used_u]
    return 0
