"""The kernel's linear algebra: one factored base matrix and low-rank updates (Woodbury).

Every matrix the transient needs is

    A = B + U diag(d) V^T,    B = G + a0_ref M + W diag(g_ref) W^T   (factored once)

with the columns of U (n x r) and rows of V^T (r x n) being, in this order: the junction ports
(``e_anode - e_cathode`` in both), the switch ports (the same), and the linear charges (U the
columns of E where dq/dt enters, V^T the rows of Q that make the charge). ``d`` is the change
since the factorization: junction and switch conductances minus their reference values, and
``a0 - a0_ref`` for every charge. So a new step size, a switch toggling or a diode turning on
never refactors: each solve is a solve with B (kept as its inverse, one BLAS matrix-vector
product) and a small dense system on the *active* columns (those whose update is not
negligible). ``Z = B^-1 U`` and ``K = V^T Z`` are kept with the factorization.

The inverse is accurate enough because every accepted solution is checked by one step of
iterative refinement against the full matrix (:func:`refine`); a failed check refactors at the
present values (then d = 0 and the solve is a plain product with the new inverse).
"""

from __future__ import annotations

import numpy as np
from numba import njit

# A column whose update changes the solution by less than this relative amount is left out
# of the small system (|d_i K_ii| below it: below double-precision round-off of the result).
NEGLIGIBLE = 1e-15


@njit(cache=True)
def rebuild(fac, plan, a0, values):
    """Factor B at port values ``values`` (shape (r,)) and step coefficient a0 (1/s) into
    ``fac`` (a :class:`~circuitsim.solver.compiled.plan.Factors`, overwritten).
    Raises numpy.linalg.LinAlgError when B is singular.
    """
    B = fac.B
    B[:, :] = plan.G + a0 * plan.M
    nports = plan.port_p.size
    for k in range(nports):
        p, q, g = plan.port_p[k], plan.port_n[k], values[k]
        if p >= 0:
            B[p, p] += g
        if q >= 0:
            B[q, q] += g
        if p >= 0 and q >= 0:
            B[p, q] -= g
            B[q, p] -= g
    fac.Binv[:, :] = np.linalg.inv(B)
    fac.Z[:, :] = np.dot(fac.Binv, plan.U)
    fac.ZT[:, :] = fac.Z.T
    fac.K[:, :] = np.dot(plan.VT, fac.Z)
    count = 0
    for i in range(B.shape[0]):
        fac.b_ptr[i] = count
        for j in range(B.shape[1]):
            if B[i, j] != 0.0:
                fac.b_idx[count] = j
                fac.b_val[count] = B[i, j]
                count += 1
    fac.b_ptr[B.shape[0]] = count
    md = fac.ZdT.shape[0]
    fac.ZdT[:, :] = fac.ZT[:md]
    fac.KdT[:, :] = fac.K[:, :md].T
    for j in range(md):
        fac.zrel[j] = np.max(np.abs(fac.ZdT[j]) / plan.abs_tol)
    fac.Zq[:, :] = fac.Z[:, nports:]
    fac.Kq[:, :] = fac.K[:, nports:]
    fac.yc[:] = np.dot(fac.Binv, plan.rhs_const)
    fac.cc[:] = np.dot(plan.VT, fac.yc)
    if plan.src_unit.shape[1]:
        fac.Yb[:, :] = np.dot(fac.Binv, plan.src_unit)
        fac.Cb[:, :] = np.dot(plan.VT, fac.Yb)
    fac.ref[:] = values
    fac.ref[nports:] = a0


@njit(cache=True)
def source_solution(yc, cc, Yb, Cb, Zq, Kq, values, hist_lin, y0, c0):
    """y0 = B^-1 rhs0 and c0 = V^T y0 for rhs0 = constant sources + time-dependent sources
    at ``values`` - E hist_lin, from the responses kept with the factorization."""
    y0[:] = yc
    c0[:] = cc
    for k in range(values.size):
        v = values[k]
        if v != 0.0:
            for i in range(y0.size):
                y0[i] += v * Yb[i, k]
            for i in range(c0.size):
                c0[i] += v * Cb[i, k]
    if hist_lin.size:
        y0 -= np.dot(Zq, hist_lin)
        c0 -= np.dot(Kq, hist_lin)


@njit(cache=True)
def active_columns(d, K):
    """Indices of the columns whose update is not negligible."""
    count = 0
    idx = np.empty(d.size, np.int64)
    for i in range(d.size):
        if d[i] != 0.0 and abs(d[i] * K[i, i]) > NEGLIGIBLE:
            idx[count] = i
            count += 1
    return idx[:count]


@njit(cache=True)
def update(y, c, d, K, ZT, active):
    """x = y - Z_A s with (I + D_AA K_AA) s = D_AA c_A; ok=False if the small system is
    singular.

    y : B^-1 r (n,);  c : V^T y (r,);  ZT : Z transposed (r, n).
    """
    m = active.size
    if m == 0:
        return y.copy(), True
    small = np.empty((m, m))
    rhs = np.empty(m)
    for a in range(m):
        i = active[a]
        for b in range(m):
            small[a, b] = d[i] * K[i, active[b]]
        small[a, a] += 1.0
        rhs[a] = d[i] * c[i]
    s = _gauss(small, rhs)
    if not np.all(np.isfinite(s)):
        return y.copy(), False
    x = y.copy()
    for a in range(m):
        col = active[a]
        sa = s[a]
        for row in range(y.size):
            x[row] -= ZT[col, row] * sa
    return x, True


@njit(cache=True)
def _gauss(a, b):
    """Solve the small dense system a s = b by Gaussian elimination with partial pivoting
    (a and b are scratch, overwritten); NaN when a pivot vanishes."""
    m = b.size
    for k in range(m):
        p = k
        big = abs(a[k, k])
        for i in range(k + 1, m):
            if abs(a[i, k]) > big:
                big, p = abs(a[i, k]), i
        if big == 0.0:
            return np.full(m, np.nan)
        if p != k:
            for j in range(m):
                a[k, j], a[p, j] = a[p, j], a[k, j]
            b[k], b[p] = b[p], b[k]
        for i in range(k + 1, m):
            f = a[i, k] / a[k, k]
            if f != 0.0:
                for j in range(k + 1, m):
                    a[i, j] -= f * a[k, j]
                b[i] -= f * b[k]
    s = np.empty(m)
    for k in range(m - 1, -1, -1):
        acc = b[k]
        for j in range(k + 1, m):
            acc -= a[k, j] * s[j]
        s[k] = acc / a[k, k]
    return s


@njit(cache=True)
def csr_matvec(ptr, idx, val, x, out):
    """out = A x for A in CSR form (ptr, idx, val), shape (rows,)."""
    for i in range(out.size):
        acc = 0.0
        for k in range(ptr[i], ptr[i + 1]):
            acc += val[k] * x[idx[k]]
        out[i] = acc
    return out


@njit(cache=True)
def add_u_columns(ut, weights, first, out):
    """out += U[:, first:first + len(weights)] @ weights; ``ut`` = U^T in CSR form (its rows
    are U's columns)."""
    ptr, idx, val = ut
    for j in range(weights.size):
        w = weights[j]
        if w != 0.0:
            row = first + j
            for k in range(ptr[row], ptr[row + 1]):
                out[idx[k]] += val[k] * w
    return out


@njit(cache=True)
def refine(b_ptr, b_idx, b_val, Binv, K, ZT, vt, ut, x, d, rhs, tol, fraction):
    """One step of iterative refinement of x against the full matrix B + U diag(d) V^T.

    B in CSR form (b_*) and as its inverse; ``vt``, ``ut``: V^T and U^T in CSR form. Returns
    (x + correction, True) when every component of the correction is within
    ``fraction * tol``, else (x, False).
    """
    res = rhs - csr_matvec(b_ptr, b_idx, b_val, x, np.empty(x.size))
    vx = csr_matvec(vt[0], vt[1], vt[2], x, np.empty(d.size))
    add_u_columns(ut, -d * vx, 0, res)
    y = np.dot(Binv, res)
    c = csr_matvec(vt[0], vt[1], vt[2], y, np.empty(d.size))
    corr, ok = update(y, c, d, K, ZT, active_columns(d, K))
    if not ok:
        return x, False
    for i in range(x.size):
        if abs(corr[i]) > fraction * tol[i]:
            return x, False
    return x + corr, True
