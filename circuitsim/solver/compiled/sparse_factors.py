"""The ports kernel's factorization of a large circuit: our sparse LU, called from Python.

:func:`~circuitsim.solver.compiled.lowrank.rebuild` inverts B densely (n^3, and n^2 memory for
B and its inverse), which past a hundred-odd unknowns costs more than the whole time loop. The
ports kernel needs no inverse: only B^-1 applied to the low-rank columns U, the constant
right-hand side and the sources' unit right-hand sides (r + 1 + ns columns). So above
``SPARSE_FROM`` unknowns the loop returns to Python (newton.FACTOR; :func:`factor_sparse`),
where B = G + a0 M + W diag(g) W^T is factored sparse at the present values (the MNA
kernel's pivot order and LU: compiled/sparse_order.py, compiled/sparse_lu.py; SuperLU's
order above sparse_order.OWN_ORDER_LIMIT unknowns) and solved for those columns; the loop
is re-entered where it stopped. A run makes few such factorizations (3 on the TL074
wheelset, docs/solver.md), so each finds its own pivot order.
"""

from __future__ import annotations

import numpy as np

from circuitsim.solver.compiled.fill import FILL_FUNCTIONS
from circuitsim.solver.compiled.newton import FACTORIZATIONS, VERSION
from circuitsim.solver.compiled.pivot_search import SEARCH_FUNCTIONS
from circuitsim.solver.compiled.sparse_lu import assemble, lu_solve_rows, refactor
from circuitsim.solver.compiled.sparse_order import analyse

# Unknowns from which the ports kernel factors sparsely. Measured (docs/solver.md): one dense
# rebuild took 0.09 ms at 54 unknowns and 4.6 ms at 162; the sparse factorization (order,
# LU and the solves) 1.1 ms at 162 (the ideal chain of 4) and 3.2 ms at 374 (TL074 chain of 2)
SPARSE_FROM = 100
# the compiled functions a sparse factorization calls from Python (the start-up library's)
SPARSE_FUNCTIONS = (*FILL_FUNCTIONS, *SEARCH_FUNCTIONS, assemble, refactor, lu_solve_rows)
_NO_SWITCHES = np.zeros(0)  # assemble's switch conductances: the ports' are all in g


def sparse_solve(G, M, port_p, port_n, g, a0: float, rhs: np.ndarray) -> np.ndarray | None:
    """B^-1 applied to each row of ``rhs`` ((m, n)), B = G + a0 M + W diag(g) W^T (``g``:
    the conductance of each port (p, n), S; ``a0``: 1/s); None when B is singular or the
    solution is not finite."""
    g = np.ascontiguousarray(g, dtype=float)
    try:
        lu = analyse(G, M, port_p, port_n, g, a0)
    except np.linalg.LinAlgError:
        return None
    assemble(lu.a_val, lu.g_val, lu.m_val, a0, lu.port_pos, g, _NO_SWITCHES)
    # the order was found on these values (pivots at least sparse_order.PIVOT_PREFERENCE,
    # 0.01, of their column's largest): a failure of refactor's test (1e-3) is a zero pivot
    if refactor(lu.a_ptr, lu.a_row, lu.a_val, lu.l_ptr, lu.l_row, lu.l_val, lu.u_ptr,
                lu.u_row, lu.u_val, lu.work, lu.redo, True) >= 0:  # fmt: skip
        return None
    solution = np.empty_like(rhs)
    lu_solve_rows(lu.l_ptr, lu.l_row, lu.l_val, lu.u_ptr, lu.u_row, lu.u_val, lu.row_to,
                  lu.col_of, rhs, lu.work, solution)  # fmt: skip
    return solution if np.all(np.isfinite(solution)) else None


def factor_trial() -> None:
    """:func:`sparse_solve` on a 2-unknown circuit: its compiled functions compiled (or
    loaded) for the types of a run, before the run needs them and in a process that builds
    the start-up library, whatever the size of its circuit."""
    G = np.array([[2.0, -1.0], [-1.0, 1.0]])
    port = np.array([1], dtype=np.int64), np.array([-1], dtype=np.int64)
    sparse_solve(G, np.eye(2), *port, np.array([1.0]), 1.0, np.eye(2))


def sparse_port_factors(
    G, M, U, VT, port_p, port_n, values, a0, rhs_const, src_unit, abs_tol,
    Z, ZT, K, ZdT, KdT, zrel, Zq, Kq, yc, cc, Yb, Cb, ref,
) -> int:  # fmt: skip
    """Factor B at port values ``values`` (shape (r,)) and step coefficient ``a0`` (1/s) and
    fill the factorization's arrays in place (:class:`~circuitsim.solver.compiled.plan.Factors`
    without B and its inverse). Returns 0, or 1 when B is singular (nothing filled).
    """
    r = U.shape[1]
    rhs = np.empty((r + 1 + src_unit.shape[1], G.shape[0]))
    rhs[:r] = U.T
    rhs[r] = rhs_const
    rhs[r + 1 :] = src_unit.T
    solved = sparse_solve(G, M, port_p, port_n, values[: port_p.size], a0, rhs)
    if solved is None:
        return 1
    solution = solved.T
    n = G.shape[0]
    nports = port_p.size
    Z[:, :] = solution[:, :r]
    ZT[:, :] = Z.T
    K[:, :] = VT @ Z
    md = ZdT.shape[0]
    ZdT[:, :] = ZT[:md]
    KdT[:, :] = K[:, :md].T
    zrel[:] = np.max(np.abs(ZdT) / abs_tol, axis=1) if md and n else 0.0
    Zq[:, :] = Z[:, nports:]
    Kq[:, :] = K[:, nports:]
    yc[:] = solution[:, r]
    cc[:] = VT @ yc
    Yb[:, :] = solution[:, r + 1 :]
    Cb[:, :] = VT @ Yb
    ref[:] = values
    ref[nports:] = a0
    return 0


def factor_sparse(plan, st, a0: float) -> None:
    """What newton.factor_now does in compiled code, sparse (:func:`sparse_solve`): factor
    at the present port values (junction conductances st.gd, switch states st.state) and
    ``a0`` (1/s) into st.fac and bump the factorization version.

    Raises
    ------
    numpy.linalg.LinAlgError
        The matrix is singular.
    """
    md, ms = st.gd.size, st.state.size
    values = np.empty(plan.VT.shape[0])
    values[:md] = st.gd
    values[md : md + ms] = np.where(st.state, plan.g_switch[:, 0], plan.g_switch[:, 1])
    values[md + ms :] = a0
    fac = st.fac
    singular = sparse_port_factors(
        plan.G, plan.M, plan.U, plan.VT, plan.port_p, plan.port_n, values, a0, plan.rhs_const,
        plan.src_unit, plan.abs_tol, fac.Z, fac.ZT, fac.K, fac.ZdT, fac.KdT, fac.zrel, fac.Zq,
        fac.Kq, fac.yc, fac.cc, fac.Yb, fac.Cb, fac.ref,
    )  # fmt: skip
    if singular:
        raise np.linalg.LinAlgError("singular matrix")
    st.ints[FACTORIZATIONS] += 1
    st.ints[VERSION] += 1
