"""Port-space algebra of the ports kernel: Newton on the junction voltages alone.

The factorization of lowrank.py (``B`` at reference port values, ``K = V^T B^-1 U``) gives,
for the r port quantities ``p = V^T x`` (junction voltages J, then switch voltages and linear
charges R),

    (I + K D) p = c,    c = V^T B^-1 rhs,    x = B^-1 rhs - Z D p

with D the port values' change since the factorization (lowrank.py). Within one
*configuration* (step coefficient a0 and switch states fixed) D_R is constant and the R rows
can be eliminated once (a Schur complement):

    F = (I + K_RR D_R)^-1,   G = D_R F,   H = K_JJ - K_JR G K_RJ

so that a Newton iteration is one md x md solve (md = number of junctions; 4 for the wheelset)

    (I + H D_J) p_J = e0 - H ieq,    e0 = c0_J - K_JR G c0_R,

with ``c0`` the port response of the sources and the charge history (once per time point) and
``ieq`` the junctions' companion currents. The R ports and any wanted unknown follow from the
junction current deviation ``j = ieq + D_J p_J``:

    p_R = F c0_R - F K_RJ j,    x_i = y0_i - Z_iJ j - Z_iR (D_R p_R).

Nothing of size n is touched inside Newton; the unknowns are formed only where they are
recorded (every accepted point, or only the probed rows of a sweep).

The per-time-point and per-iteration formulas above are port_newton.py's steps, compiled
without numba's reference counting and inlined into the loop (port_steps.py). Here remain what
runs rarely (configure, h_column), once per point (all_unknowns) or once per control node and
probe (unknown).
"""

from __future__ import annotations

import numpy as np

from circuitsim.solver.compiled.newton import JUNCTION_NEGLIGIBLE
from circuitsim.solver.jit import njit


@njit(cache=True)
def configure(K, md, dR, F, G, bound) -> bool:
    """Eliminate the R ports at their value changes ``dR`` (shape (rR,)).

    Fills F = (I + K_RR D_R)^-1 and G = D_R F (rR x rR), so that H = K_JJ - K_JR G K_RJ, and
    ``bound`` (md,), an upper bound of max_i |H_ik| for each column k. H itself is formed
    column by column when a column is needed (:func:`h_column`): a circuit with many
    junctions needs few of them, and forming all would cost md^2 rR at every new step size.
    False when I + K_RR D_R is singular.
    """
    rR = dR.size
    a = np.empty((rR, 2 * rR))
    for i in range(rR):
        for k in range(rR):
            a[i, k] = K[md + i, md + k] * dR[k]
            a[i, rR + k] = 0.0
        a[i, i] += 1.0
        a[i, rR + i] = 1.0
    for k in range(rR):  # Gauss-Jordan with partial pivoting
        p = k
        big = abs(a[k, k])
        for i in range(k + 1, rR):
            if abs(a[i, k]) > big:
                big, p = abs(a[i, k]), i
        if big == 0.0 or not np.isfinite(big):
            return False
        if p != k:
            for j in range(2 * rR):
                a[k, j], a[p, j] = a[p, j], a[k, j]
        inv = 1.0 / a[k, k]
        for j in range(2 * rR):
            a[k, j] *= inv
        for i in range(rR):
            f = a[i, k]
            if i != k and f != 0.0:
                for j in range(2 * rR):
                    a[i, j] -= f * a[k, j]
    for i in range(rR):
        for k in range(rR):
            F[i, k] = a[i, rR + k]
            G[i, k] = dR[i] * a[i, rR + k]
    # bound_k = max_i |K_JJ[i, k]| + sum_s u_s |K_RJ[s, k]|, u_s = sum_r max_i |K_JR[i, r]| |G_rs|
    u = np.zeros(rR)
    for r in range(rR):
        big = 0.0
        for i in range(md):
            big = max(big, abs(K[i, md + r]))
        for s in range(rR):
            u[s] += big * abs(G[r, s])
    for k in range(md):
        big = 0.0
        for i in range(md):
            big = max(big, abs(K[i, k]))
        for s in range(rR):
            big += u[s] * abs(K[md + s, k])
        bound[k] = big
    return True


@njit(cache=True)
def h_column(K, G, md, k, H, hcol, t) -> None:
    """Column k of H = K_JJ - K_JR G K_RJ into H[:, k], and max_i |H_ik| into hcol[k]
    (t: scratch, shape (rR,))."""
    rR = t.size
    for s in range(rR):
        acc = 0.0
        for q in range(rR):
            acc += G[s, q] * K[md + q, k]
        t[s] = acc
    big = 0.0
    for i in range(md):
        acc = K[i, k]
        for s in range(rR):
            acc -= K[i, md + s] * t[s]
        H[i, k] = acc
        big = max(big, abs(acc))
    hcol[k] = big


@njit(cache=True, inline="always")
def unknown(i, yc, Yb, Zq, Z, src_values, hist_lin, jv, w) -> float:
    """Unknown i >= 0 of the present solution: y0_i - Z_iJ j - Z_iR w (no early return for
    ground: a branch out of an inlined loop nest measured 7x slower in its caller's loop)."""
    acc = yc[i]
    for k in range(src_values.size):
        acc += Yb[i, k] * src_values[k]
    for k in range(hist_lin.size):
        acc -= Zq[i, k] * hist_lin[k]
    md = jv.size
    for k in range(md):
        acc -= Z[i, k] * jv[k]
    for k in range(w.size):
        acc -= Z[i, md + k] * w[k]
    return acc


@njit(cache=True, inline="always")
def all_unknowns(x, yc, Yb, ZT, src_values, hist_lin, jv, w, md, yJ, j_applied, zrel, full):
    """Every unknown of the present solution into x (shape (n,)), column by column.

    The junction columns' part ``yJ = Z_J j`` is kept between calls and updated only by the
    junctions whose current deviation j changed enough to move some unknown by more than
    JUNCTION_NEGLIGIBLE of its absolute tolerance (``zrel``: max_i |Z_ik| / tol_i); ``full``
    recomputes it (a new factorization). R columns with w = 0 (a0 at the factored value) are
    skipped.
    """
    n = x.size
    if full:
        for i in range(n):
            yJ[i] = 0.0
        for k in range(md):
            j_applied[k] = 0.0
    for k in range(md):
        delta = jv[k] - j_applied[k]
        if delta != 0.0 and (full or abs(delta) * zrel[k] > JUNCTION_NEGLIGIBLE):
            for i in range(n):
                yJ[i] += ZT[k, i] * delta
            j_applied[k] = jv[k]
    for i in range(n):
        x[i] = yc[i] - yJ[i]
    for k in range(src_values.size):
        s = src_values[k]
        if s != 0.0:
            for i in range(n):
                x[i] += Yb[i, k] * s
    nl = hist_lin.size
    rR = w.size
    for k in range(rR):
        wk = w[k]
        if wk != 0.0:
            for i in range(n):
                x[i] -= ZT[md + k, i] * wk
    for k in range(nl):  # the charge history: the last nl columns
        hk = hist_lin[k]
        if hk != 0.0:
            for i in range(n):
                x[i] -= ZT[md + rR - nl + k, i] * hk
