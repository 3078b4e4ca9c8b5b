"""Port-space algebra of the ports kernel: Newton on the junction voltages alone.

The factorization of lowrank.py (``B`` at reference port values, ``K = V^T B^-1 U``) gives,
for the r port quantities ``p = V^T x`` (junction voltages J, then switch voltages and linear
charges R),

    (I + K D) p = c,    c = V^T B^-1 rhs,    x = B^-1 rhs - Z D p

with D the port values' change since the factorization (lowrank.py). Within one
*configuration* (step coefficient a0 and switch states fixed) D_R is constant and the R rows
can be eliminated once (a Schur complement):

    F = (I + K_RR D_R)^-1,   H = K_JJ - K_JR D_R F K_RJ,   E_J = K_JR D_R F

so that a Newton iteration is one md x md solve (md = number of junctions; 4 for the wheelset)

    (I + H D_J) p_J = e0 - H ieq,    e0 = c0_J - E_J c0_R,

with ``c0`` the port response of the sources and the charge history (once per time point) and
``ieq`` the junctions' companion currents. The R ports and any wanted unknown follow from the
junction current deviation ``j = ieq + D_J p_J``:

    p_R = F c0_R - F K_RJ j,    x_i = y0_i - Z_iJ j - Z_iR (D_R p_R).

Nothing of size n is touched inside Newton; the unknowns are formed only where they are
recorded (every accepted point, or only the probed rows of a sweep).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def solve_small(a, b, out) -> bool:
    """Solve a out = b (m x m, partial pivoting); ``a`` and ``b`` are overwritten. False when
    a pivot vanishes or the result is not finite."""
    m = b.size
    for k in range(m):
        p = k
        big = abs(a[k, k])
        for i in range(k + 1, m):
            if abs(a[i, k]) > big:
                big, p = abs(a[i, k]), i
        if big == 0.0:
            return False
        if p != k:
            for j in range(m):
                a[k, j], a[p, j] = a[p, j], a[k, j]
            b[k], b[p] = b[p], b[k]
        pivot = a[k, k]
        for i in range(k + 1, m):
            f = a[i, k] / pivot
            if f != 0.0:
                for j in range(k + 1, m):
                    a[i, j] -= f * a[k, j]
                b[i] -= f * b[k]
    for k in range(m - 1, -1, -1):
        acc = b[k]
        for j in range(k + 1, m):
            acc -= a[k, j] * out[j]
        out[k] = acc / a[k, k]
        if not np.isfinite(out[k]):
            return False
    return True


@njit(cache=True)
def configure(K, md, dR, F, FK, H, EJ) -> bool:
    """Eliminate the R ports at their value changes ``dR`` (shape (rR,)): fill F, FK = F K_RJ,
    H and E_J. False when I + K_RR D_R is singular."""
    rR = dR.size
    a = np.empty((rR, rR))
    for i in range(rR):
        for k in range(rR):
            a[i, k] = K[md + i, md + k] * dR[k]
        a[i, i] += 1.0
    # F = a^-1, column by column (rR is small: the switches and the linear charges)
    for col in range(rR):
        work = a.copy()
        rhs = np.zeros(rR)
        rhs[col] = 1.0
        out = np.empty(rR)
        if not solve_small(work, rhs, out):
            return False
        for i in range(rR):
            F[i, col] = out[i]
    for i in range(rR):
        for j in range(md):
            acc = 0.0
            for k in range(rR):
                acc += F[i, k] * K[md + k, j]
            FK[i, j] = acc
    for i in range(md):
        for k in range(rR):
            acc = 0.0
            for m in range(rR):
                acc += K[i, md + m] * dR[m] * F[m, k]
            EJ[i, k] = acc
    for i in range(md):
        for j in range(md):
            acc = K[i, j]
            for k in range(rR):
                acc -= EJ[i, k] * K[md + k, j]
            H[i, j] = acc
    return True


@njit(cache=True, inline="always")
def time_point(cc, Cb, Kq, src_values, hist_lin, F, EJ, md, c0, e0, Fc0):
    """c0 = cc + Cb src - Kq hist_lin (shape (r,)), e0 = c0_J - E_J c0_R, Fc0 = F c0_R."""
    r = c0.size
    for i in range(r):
        acc = cc[i]
        for k in range(src_values.size):
            acc += Cb[i, k] * src_values[k]
        for k in range(hist_lin.size):
            acc -= Kq[i, k] * hist_lin[k]
        c0[i] = acc
    rR = r - md
    for i in range(md):
        acc = c0[i]
        for k in range(rR):
            acc -= EJ[i, k] * c0[md + k]
        e0[i] = acc
    for i in range(rR):
        acc = 0.0
        for k in range(rR):
            acc += F[i, k] * c0[md + k]
        Fc0[i] = acc


@njit(cache=True, inline="always")
def junction_solve(H, e0, ieq, dJ, a, b, pJ) -> bool:
    """p_J of (I + H D_J) p_J = e0 - H ieq; a (md, md) and b (md,) are scratch."""
    md = e0.size
    for i in range(md):
        acc = e0[i]
        for k in range(md):
            acc -= H[i, k] * ieq[k]
            a[i, k] = H[i, k] * dJ[k]
        a[i, i] += 1.0
        b[i] = acc
    return solve_small(a, b, pJ)


@njit(cache=True, inline="always")
def remaining_ports(Fc0, FK, ieq, dJ, pJ, dR, j, pR, w):
    """j = ieq + D_J p_J (junction current deviation, A), p_R and w = D_R p_R (shape (rR,))."""
    md = ieq.size
    for k in range(md):
        j[k] = ieq[k] + dJ[k] * pJ[k]
    for i in range(Fc0.size):
        acc = Fc0[i]
        for k in range(md):
            acc -= FK[i, k] * j[k]
        pR[i] = acc
        w[i] = dR[i] * acc


@njit(cache=True, inline="always")
def unknown(i, yc, Yb, Zq, Z, src_values, hist_lin, j, w) -> float:
    """Unknown i >= 0 of the present solution: y0_i - Z_iJ j - Z_iR w. (No early return for
    ground: a branch out of this inlined loop nest made the recording loop 7x slower.)"""
    acc = yc[i]
    for k in range(src_values.size):
        acc += Yb[i, k] * src_values[k]
    for k in range(hist_lin.size):
        acc -= Zq[i, k] * hist_lin[k]
    md = j.size
    for k in range(md):
        acc -= Z[i, k] * j[k]
    for k in range(w.size):
        acc -= Z[i, md + k] * w[k]
    return acc
