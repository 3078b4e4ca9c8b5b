"""The ports kernel's factorization of a large circuit: SuperLU, called from the compiled loop.

:func:`~circuitsim.solver.compiled.lowrank.rebuild` inverts B densely (n^3, and n^2 memory for
B and its inverse), which past a hundred-odd unknowns costs more than the whole time loop. The
ports kernel needs no inverse: only B^-1 applied to the low-rank columns U, the constant
right-hand side and the sources' unit right-hand sides (r + 1 + ns columns). So above
``SPARSE_FROM`` unknowns the loop factors B = G + a0 M + W diag(g) W^T with SuperLU and solves
for those columns; numba cannot call SuperLU, so the loop returns to Python for it
(newton.FACTOR; :func:`factor_sparse`) and is re-entered where it stopped.
"""

from __future__ import annotations

import numpy as np

from circuitsim.solver.compiled.newton import FACTORIZATIONS, VERSION

# Unknowns from which the ports kernel factors sparsely. Measured (docs/solver.md): one dense
# rebuild took 0.09 ms at 54 unknowns and 4.6 ms at 162, SuperLU's about 1 ms at 162.
SPARSE_FROM = 100


def sparse_port_factors(
    G, M, U, VT, port_p, port_n, values, a0, rhs_const, src_unit, abs_tol,
    Z, ZT, K, ZdT, KdT, zrel, Zq, Kq, yc, cc, Yb, Cb, ref,
) -> int:  # fmt: skip
    """Factor B at port values ``values`` (shape (r,)) and step coefficient ``a0`` (1/s) and
    fill the factorization's arrays in place (:class:`~circuitsim.solver.compiled.plan.Factors`
    without B and its inverse). Returns 0, or 1 when B is singular (nothing filled).
    """
    import scipy.sparse as sp  # here: a small circuit's process never loads scipy
    from scipy.sparse.linalg import splu

    n = G.shape[0]
    nports = port_p.size
    g = values[:nports]
    rows, cols, data = [], [], []
    for a, b, sign in ((port_p, port_p, 1.0), (port_n, port_n, 1.0),
                       (port_p, port_n, -1.0), (port_n, port_p, -1.0)):  # fmt: skip
        keep = (a >= 0) & (b >= 0)
        rows.append(a[keep])
        cols.append(b[keep])
        data.append(sign * g[keep])
    ports = sp.csc_matrix(
        (np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
    )
    B = sp.csc_matrix(G + a0 * M) + ports
    try:
        lu = splu(B)
    except RuntimeError:
        return 1
    r = U.shape[1]
    rhs = np.empty((n, r + 1 + src_unit.shape[1]))
    rhs[:, :r] = U
    rhs[:, r] = rhs_const
    rhs[:, r + 1 :] = src_unit
    solution = lu.solve(rhs)
    if not np.all(np.isfinite(solution)):
        return 1
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
    """What newton.factor_now does in compiled code, with SuperLU: factor at the present port
    values (junction conductances st.gd, switch states st.state) and ``a0`` (1/s) into
    st.fac and bump the factorization version.

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
