"""The ports kernel's factorization: one factored base matrix for low-rank updates.

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

The ports kernel (ports.py, port_steps.py) solves with these in port space; the MNA kernel
(mna_steps.py) uses only the two sparse products below.
"""

from __future__ import annotations

import numpy as np
from numpy.linalg import LinAlgError

from circuitsim.solver.jit import njit

# A column whose update changes the solution by less than this relative amount is left out
# of the small system (|d_i K_ii| below it: below double-precision round-off of the result).
NEGLIGIBLE = 1e-15

# B is inverted and multiplied by loops of our own (invert, multiply, matvec), not by numpy's
# linalg: numba's LAPACK and BLAS are scipy's (scipy.linalg.cython_lapack, imported at the
# first call); without scipy a whole simulate process of the ideal wheelset took 0.23
# against 0.37 s of CPU (docs/performance.md section 6). The loops invert B only below
# sparse_factors.SPARSE_FROM = 100 unknowns (a sparse LU above).


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
    invert(B, fac.Binv)
    multiply(fac.Binv, plan.U, fac.Z)
    fac.ZT[:, :] = fac.Z.T
    multiply(plan.VT, fac.Z, fac.K)
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
    matvec(fac.Binv, plan.rhs_const, fac.yc)
    matvec(plan.VT, fac.yc, fac.cc)
    if plan.src_unit.shape[1]:
        multiply(fac.Binv, plan.src_unit, fac.Yb)
        multiply(plan.VT, fac.Yb, fac.Cb)
    fac.ref[:] = values
    fac.ref[nports:] = a0


@njit(cache=True)
def invert(B, out):
    """out = B^-1, shapes (n, n), by Gauss-Jordan elimination with partial pivoting (rows
    swapped to the largest remaining entry of each column; B is left untouched).

    Raises
    ------
    numpy.linalg.LinAlgError
        A column has no nonzero pivot left: B is singular (as numpy.linalg.inv raises).
    """
    n = B.shape[0]
    a = B.copy()
    out[:, :] = 0.0
    for i in range(n):
        out[i, i] = 1.0
    for k in range(n):
        row, big = k, abs(a[k, k])
        for i in range(k + 1, n):
            if abs(a[i, k]) > big:
                row, big = i, abs(a[i, k])
        if big == 0.0:
            raise LinAlgError("Matrix is singular to machine precision.")
        if row != k:
            for j in range(n):
                a[k, j], a[row, j] = a[row, j], a[k, j]
                out[k, j], out[row, j] = out[row, j], out[k, j]
        pivot = a[k, k]
        for j in range(k, n):
            a[k, j] /= pivot
        for j in range(n):
            out[k, j] /= pivot
        for i in range(n):
            factor = a[i, k]
            if i != k and factor != 0.0:
                for j in range(k, n):
                    a[i, j] -= factor * a[k, j]
                for j in range(n):
                    out[i, j] -= factor * out[k, j]
    return out


@njit(cache=True)
def multiply(A, X, out):
    """out = A X, shapes (m, k) (k, p) -> (m, p), skipping A's zero entries."""
    out[:, :] = 0.0
    for i in range(A.shape[0]):
        for k in range(A.shape[1]):
            a = A[i, k]
            if a != 0.0:
                for j in range(X.shape[1]):
                    out[i, j] += a * X[k, j]
    return out


@njit(cache=True)
def matvec(A, x, out):
    """out = A x, shapes (m, k) (k,) -> (m,)."""
    for i in range(A.shape[0]):
        acc = 0.0
        for k in range(A.shape[1]):
            acc += A[i, k] * x[k]
        out[i] = acc
    return out


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
