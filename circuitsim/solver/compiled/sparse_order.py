"""The MNA kernel's pivot order and fill pattern, found in Python and our compiled search
(compiled/sparse_lu.py factors and solves on them in compiled code).

- :func:`analyse` (once per run, and again by :func:`repivot` only when a pivot has become
  too small): up to ``OWN_ORDER_LIMIT`` unknowns our search (compiled/pivot_search.py: a
  matching by size, minimum degree, threshold partial pivoting 0.01 preferring the matched
  row) on the present matrix gives the row and column permutations; above ``SUPERLU_FROM``
  SuperLU does too, once for each column order of ``SUPERLU_ORDERS``. The pattern of L and
  U without pivoting follows from each (compiled/fill.py), and the order whose Newton
  iteration costs fewest operations (:func:`iteration_cost`) is kept; a run's later orders
  come from the search that made its first (``search``).

The matrix is ``A = G + a0 M + sum_k g_k w_k w_k^T + T`` (w_k = e_p - e_n: junction and
switch ports; T: the entries of multi-terminal devices, ``extra`` below, at fixed (row,
column) positions); its pattern is that of every matrix of the run, whatever the values.
G and M are :class:`~circuitsim.solver.compressed.Compressed`: no scipy here.
"""

from __future__ import annotations

import numpy as np

from circuitsim.solver.compiled.fill import lu_pattern, reach_sets
from circuitsim.solver.compiled.pivot_search import (
    maximum_matching,
    minimum_degree,
    threshold_pivots,
)
from circuitsim.solver.compiled.sparse_lu import SparseLU
from circuitsim.solver.compressed import Compressed, unique

# up to SUPERLU_FROM unknowns, our own pivot order (compiled/pivot_search.py: minimum degree
# on A + A^T with a matching by size on the diagonal); above OWN_ORDER_LIMIT, SuperLU's
# column orders (COLAMD, MMD_AT_PLUS_A); between them both are offered and the cheaper kept
# (iteration_cost), and the run's later orders come from that search alone (pivot_orders'
# ``search``). Neither wins everywhere there: a refactor took 2.1 ms on SuperLU's order against
# 0.28 ms on ours at the TL074 chain of 64 masses (11 782 unknowns), but the TL074 lattice of
# 32 masses (7552) ran in 17.3 s on SuperLU's against 27.2 on ours, the ideal lattice of 32
# (1724) in 0.79 against 1.12 s. OWN_ORDER_LIMIT bounds minimum degree's elimination graph,
# n^2 / 8 bytes (50 MB there). docs/solver.md, "Our pivot order".
SUPERLU_FROM = 1000
OWN_ORDER_LIMIT = 20_000
SUPERLU_ORDERS = ("COLAMD", "MMD_AT_PLUS_A")
# SuperLU's orders: the first is kept unless another's iteration costs less than
# ORDER_MARGIN of its own
ORDER_MARGIN = 0.8
# a column takes its matched row while that is at least this fraction of the largest
# candidate, else the largest (SuperLU's diag_pivot_thresh). At 0.1 the orders made when a
# pivot had become too small left the matched rows and filled: 1.5-4.7 times the first order's
# operations on the TL074 chain of 64 masses, whose run took 24 s; at 0.01 9.3 s (one
# process each, 2026-12-03). Still ten times sparse_lu.PIVOT_THRESHOLD, ngspice's 1e-3.
PIVOT_PREFERENCE = 0.01


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


def present_matrix(G, M, port_p, port_n, values, a0,
                   extra=None) -> Compressed:  # fmt: skip
    """A = G + a0 M + W diag(values) W^T + T (values: port conductances; ``extra`` =
    (rows, cols, values) of T, ground entries (-1) left out); stored zeros kept. G and M:
    anything :meth:`Compressed.of` takes."""
    G, M = Compressed.of(G), Compressed.of(M)
    n = G.shape[0]
    rows, cols, signs, which = port_stamps(n, port_p, port_n)
    e_row, e_col, e_val = _no_extra() if extra is None else extra
    e_row, e_col = np.asarray(e_row, dtype=np.int64), np.asarray(e_col, dtype=np.int64)
    inside = (e_row >= 0) & (e_col >= 0)
    g_row, g_col, g_val = G.triplets()
    m_row, m_col, m_val = M.triplets()
    return Compressed.from_triplets(
        np.concatenate([g_row, m_row, rows, e_row[inside]]),
        np.concatenate([g_col, m_col, cols, e_col[inside]]),
        np.concatenate([g_val, a0 * m_val, signs * np.asarray(values)[which],
                        np.asarray(e_val)[inside]]),
        (n, n), drop_zeros=False,
    )  # fmt: skip


def analyse(G, M, port_p, port_n, values, a0, spare: float = 1.0, extra=None,
            changing=None, search=None) -> SparseLU:  # fmt: skip
    """The pivot order at the present values and the fixed pattern it gives; L and U get
    room for ``spare`` times their fill (a later order, :func:`repivot`, may need more).
    ``extra``: (rows, cols, values) of entries besides G, M and the ports (multi-terminal
    devices; -1: ground, left out), part of the pattern whatever their values. ``changing``:
    (nports,) bool, the ports whose conductance changes at every Newton iteration (the
    charged junctions; default none), whose columns the choice of order weighs. ``search``:
    as for :func:`pivot_orders`.

    Raises
    ------
    np.linalg.LinAlgError
        The present matrix is singular.
    """
    return pivot_orders(G, M, port_p, port_n, values, a0, spare, extra, changing, search)[0]


def pivot_orders(G, M, port_p, port_n, values, a0, spare: float = 1.0, extra=None,
                 changing=None, search=None) -> list[SparseLU]:  # fmt: skip
    """:func:`analyse`'s pivot order, then the others (above SUPERLU_FROM unknowns: one per
    column order of ``SUPERLU_ORDERS`` on which the matrix is not singular, and ours up to
    OWN_ORDER_LIMIT), for a later matrix that the chosen one does not suit
    (compiled/order_cache.py).

    ``search``: a dict kept by one run (order_cache.EarlierOrders.search). The first call
    records in ``search["kind"]`` which search ("ours" or "superlu") made the chosen order;
    later calls search that way alone, so that a new order at a too-small pivot costs one
    search, not both (SuperLU's pair took 7 s at 11 782 unknowns).

    Raises
    ------
    np.linalg.LinAlgError
        The present matrix is singular.
    """
    G, M = Compressed.of(G), Compressed.of(M)
    n = G.shape[0]
    extra = _no_extra() if extra is None else extra
    e_row, e_col = (np.asarray(e, dtype=np.int64) for e in extra[:2])
    A = present_matrix(G, M, port_p, port_n, values, a0, (e_row, e_col, extra[2]))
    changing = np.zeros(len(port_p), dtype=bool) if changing is None else changing
    orders, best_cost, chosen = [], np.inf, None
    # A keeps its stored zeros: its pattern is that of every matrix of the run (G, M, all
    # port stamps and the extra entries, whatever the values)
    for row_to, col_rank, kind in _permutations(A, (search or {}).get("kind")):
        candidate = _on_order(G, M, port_p, port_n, e_row, e_col, A, row_to, col_rank,
                              spare)  # fmt: skip
        cost = iteration_cost(candidate, changing)
        if not orders or cost < ORDER_MARGIN * best_cost:
            orders.insert(0, (candidate, kind))
            best_cost, chosen = cost, kind
        else:
            orders.append((candidate, kind))
    if not orders:
        raise np.linalg.LinAlgError(f"singular matrix ({n} unknowns): no pivot order")
    if search is not None:
        search.setdefault("kind", chosen)
    # the others of the chosen search only: a kept order of the other one would be taken
    # again at the first too-small pivot (order_cache.py), and it was the costlier
    return [lu for lu, kind in orders if kind == chosen]


def _permutations(A: Compressed, kind: str | None = None):
    """(row_to, col_rank, search) of each pivot order of the present matrix ``A`` (row i of A
    to row ``row_to[i]``, column j to column ``col_rank[j]``; search "superlu" or "ours"):
    ours up to SUPERLU_FROM unknowns, SuperLU's above OWN_ORDER_LIMIT (one per column order
    on which A is not singular), both between, SuperLU's first; only ``kind``'s when it is
    given and offered at this size."""
    n = A.shape[0]
    superlu, ours = n > min(SUPERLU_FROM, OWN_ORDER_LIMIT), n <= OWN_ORDER_LIMIT
    kinds = [k for k, offered in (("superlu", superlu), ("ours", ours)) if offered]
    for search in [kind] if kind in kinds else kinds:
        found = _superlu_permutations(A) if search == "superlu" else _own_permutation(A)
        for row_to, col_rank in found:
            yield row_to, col_rank, search


def search_trial() -> None:
    """Our search on a 2 x 2 matrix: its compiled functions compiled (or loaded) for the types
    of a run, so that a process that builds the start-up library has them whatever the size
    of its circuit (a run above OWN_ORDER_LIMIT never calls them)."""
    A = Compressed.from_triplets([0, 1, 1], [0, 0, 1], [1.0, 2.0, 3.0], (2, 2))
    for _ in _own_permutation(A):
        pass


def _own_permutation(A: Compressed):
    n = A.shape[0]
    row_of = maximum_matching(A.ptr, A.row, _by_size(A))
    if np.any(row_of < 0):  # structurally singular
        return
    place = np.empty(n, dtype=np.int64)
    place[row_of] = np.arange(n, dtype=np.int64)
    col_order = minimum_degree(n, A.ptr, place[A.row])
    row_to, failed = threshold_pivots(A.ptr, A.row, A.val, col_order, row_of,
                                      PIVOT_PREFERENCE)  # fmt: skip
    if failed < 0:  # else no pivot for a column: singular at these values
        col_rank = np.empty(n, dtype=np.int64)
        col_rank[col_order] = np.arange(n, dtype=np.int64)
        yield row_to, col_rank


def _superlu_permutations(A: Compressed):
    from scipy.sparse.linalg import splu

    for column_order in SUPERLU_ORDERS:
        try:
            # no equilibration: refactor's pivot test is on the unscaled columns
            lu = splu(A.scipy(), permc_spec=column_order, diag_pivot_thresh=PIVOT_PREFERENCE,
                      options={"Equil": False})  # fmt: skip
        except RuntimeError:  # "Factor is exactly singular"
            continue
        yield np.asarray(lu.perm_r, dtype=np.int64), np.asarray(lu.perm_c, dtype=np.int64)


def _by_size(A: Compressed) -> np.ndarray:
    """A's entries (positions) by their magnitude relative to the largest of their column,
    largest first: the matching then pairs each column with a row that stays large whatever
    the devices do (an ideal op-amp's gain entry, a node's own conductances)."""
    columns = A.columns()
    scale = np.zeros(A.shape[1])
    np.maximum.at(scale, columns, np.abs(A.val))
    size = np.abs(A.val) / np.where(scale > 0, scale, 1.0)[columns]
    return np.argsort(-size, kind="stable").astype(np.int64)


def _on_order(G, M, port_p, port_n, e_row, e_col, pattern, row_to, col_rank,
              spare: float) -> SparseLU:  # fmt: skip
    """The SparseLU of the pivot order (row i of A to row ``row_to[i]``, column j to column
    ``col_rank[j]``), on the run's ``pattern`` (its entries' places; values unused)."""
    n = G.shape[0]
    col_of = np.argsort(col_rank)
    p_row, p_col, _ = pattern.triplets()
    permuted = Compressed.from_triplets(row_to[p_row], col_rank[p_col], 1.0, (n, n))
    a_ptr, a_row = permuted.ptr, permuted.row
    l_ptr, l_row, u_ptr, u_row = lu_pattern(a_ptr, a_row)
    # every stored entry of P, with its positions for G, M and the ports: entries are
    # sorted by (column, row), so the key column * n + row finds them by bisection
    entry_col = permuted.columns()
    keys = entry_col * n + a_row

    def positions(i, j) -> np.ndarray:
        return np.searchsorted(keys, col_rank[j] * n + row_to[i])

    def scatter(matrix: Compressed) -> np.ndarray:
        rows, cols, values = matrix.triplets()
        out = np.zeros(a_row.size)
        np.add.at(out, positions(rows, cols), values)
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
    m_cols = unique(entry_col[m_val != 0])
    extra_cols = unique(entry_col[extra_pos[extra_pos >= 0]])
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
    sets = [unique(row[row >= 0]) for row in stamped] + [m_cols, extra_cols]
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
    changed = unique(np.concatenate([lu.entry_col[stamped[stamped >= 0]], lu.extra_cols]))
    # the columns a refactor redoes: the changed ones and those their U rows reach
    reach, _ = reach_sets(lu.u_ptr, lu.u_row, np.array([0, changed.size], dtype=np.int64),
                          changed.astype(np.int64))  # fmt: skip
    bits = np.unpackbits(reach[0].astype("<u8").view(np.uint8), bitorder="little")
    reached = np.flatnonzero(bits[:n])
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


def repivot(lu: SparseLU, port_p, port_n, values, a0, extra_val=None, changing=None,
            search=None) -> int:  # fmt: skip
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
    G = Compressed.from_triplets(rows, cols, lu.g_val, (n, n))
    M = Compressed.from_triplets(rows, cols, lu.m_val, (n, n))
    extra_val = np.zeros(lu.extra_row.size) if extra_val is None else extra_val
    # G's and M's stored zeros drop out here: the extra entries put their positions back
    new = analyse(G, M, port_p, port_n, values, a0,
                  extra=(lu.extra_row, lu.extra_col, extra_val), changing=changing,
                  search=search)  # fmt: skip
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
