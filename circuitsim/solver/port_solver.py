"""Newton iterations confined to the junction ports: a residual-checked low-rank update.

When every nonlinear device is a conductance g between two nodes plus a current (a junction's
companion ``i = g v + ieq``), the Newton system is

    (B + W diag(g) W^T) x = r0 - W ieq

with B the cached base matrix (constant stamps, reactive companions, switch states), W the m
port incidence columns ``e_p - e_n`` and r0 the x-independent right-hand side. The solver
factors ``B' = B + W diag(g_ref) W^T`` once, at the conductances ``g_ref`` of the iteration
that built it, keeps ``Z = B'^-1 W`` (n x m) and ``K = W^T Z`` (m x m), solves ``y0 = B'^-1
r0`` once per right-hand side (once per time step), and every Newton iteration is then an
m x m solve: with ``dg = g - g_ref`` and port voltages ``v = W^T x``,

    (I + K diag(dg)) v = W^T y0 - K ieq,    x = y0 - Z (ieq + dg v)

(the Woodbury identity). Why g_ref and not g = 0: with the junctions removed, an ideal op-amp
whose loop closes only through diodes (a precision rectifier) is an open loop of gain 1e6, and
updates from that base lose digits; a base taken at a real linearization keeps such loops
closed while the junctions stay near their state. Updated solutions are checked by one step of
iterative refinement against the full matrix (:meth:`PortSolver.refine`): the correction is
an estimate of their error, which must be far below Newton's tolerance; on failure the caller
rebuilds the factors at the present conductances, which makes the update exact (dg = 0) at
the cost of one factorization, what a direct solve costs anyway.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from circuitsim.solver.linalg import factor, lapack_lu

# An updated solution is accepted when its error estimate (one refinement step) is below this
# fraction of Newton's tolerance in every unknown.
REFINE_FRACTION = 1e-3


class Ports:
    """The junction ports of a circuit: incidence and its transposes, shape (n, m)."""

    def __init__(self, size: int, p: np.ndarray, n: np.ndarray):
        m = p.size
        self.size, self.m = size, m
        self.p, self.n = p, n
        rows = np.stack([p, p, n, n]).ravel()
        cols = np.stack([p, n, p, n]).ravel()  # (p,p) (p,n) (n,p) (n,n)
        keep = (rows >= 0) & (cols >= 0)
        self._rows, self._cols, self._keep = rows[keep], cols[keep], keep
        self._signs = np.repeat([1.0, -1.0, -1.0, 1.0], m)[keep]

    @cached_property
    def w(self) -> np.ndarray:
        """W, shape (n, m): column k is e_p - e_n of port k (ground rows left out). Dense, so
        made at its first use (the reference loop's): n m entries, 0.25 GB at the TL074
        chain of 64 masses, which the compiled kernels never ask for."""
        w = np.zeros((self.size + 1, self.m))
        columns = np.arange(self.m)
        np.add.at(w, (self.p, columns), 1.0)
        np.add.at(w, (self.n, columns), -1.0)
        return np.ascontiguousarray(w[: self.size])

    @cached_property
    def wt(self) -> np.ndarray:
        """W^T, shape (m, n), rows contiguous."""
        return np.ascontiguousarray(self.w.T)

    def voltages(self, x: np.ndarray) -> np.ndarray:
        """Port voltages ``W^T x``, shape (m,)."""
        return self.wt @ x

    def stamped(self, base, g: np.ndarray):
        """``base + W diag(g) W^T`` (dense ndarray or CSC matrix)."""
        if isinstance(base, np.ndarray):
            return base + (self.w * g) @ self.wt
        import scipy.sparse as sp

        values = np.tile(g, 4)[self._keep] * self._signs
        shape = (self.size, self.size)
        return (base + sp.csc_matrix((values, (self._rows, self._cols)), shape=shape)).tocsc()


class PortSolver:
    """Factors of one base matrix, updated at the junction ports.

    Parameters
    ----------
    base : ndarray, shape (n, n), or scipy sparse matrix
        B: every stamp except the junctions'.
    ports : Ports
    g_ref : ndarray, shape (m,)
        Junction conductances (S) to factor at.
    """

    def __init__(self, base, ports: Ports, g_ref: np.ndarray):
        self.base = base
        self.ports = ports
        self.rebuilds = -1
        self.rebuild(g_ref)

    def rebuild(self, g_ref: np.ndarray) -> None:
        """Refactor at new reference conductances (raises SingularPivot if singular)."""
        ports = self.ports
        self.rebuilds += 1
        shifted = ports.stamped(self.base, g_ref)
        self.lu = factor(shifted)
        self.shifted = shifted  # CSC products are as cheap as CSR ones
        self.g_ref = g_ref.copy()
        self.z = np.asarray(self.lu.solve(ports.w)).reshape(ports.w.shape)
        self.k = ports.wt @ self.z
        self._rhs = None
        self._y0 = self._v0 = None

    def _source_solution(self, rhs0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if rhs0 is not self._rhs:
            self._y0 = self.lu.solve(rhs0)
            self._v0 = self.ports.wt @ self._y0
            self._rhs = rhs0
        return self._y0, self._v0

    def solve(self, g: np.ndarray, ieq: np.ndarray, rhs0: np.ndarray) -> tuple[np.ndarray, bool]:
        """x with (B + W diag(g) W^T) x = rhs0 - W ieq, shape (n,).

        Returns
        -------
        x : ndarray, shape (n,)
        exact : bool
            True when g equals the reference conductances (a plain LU solve, no update).
        """
        y0, v0 = self._source_solution(rhs0)
        dg = g - self.g_ref
        self._dg, self._kernel = dg, None
        if not np.count_nonzero(dg):
            return y0 - self.z @ ieq, True
        kernel = self.k * dg
        kernel.flat[:: kernel.shape[0] + 1] += 1.0
        getrf, getrs = lapack_lu()
        lu, piv, info = getrf(kernel, overwrite_a=True)
        if info != 0:
            return np.full_like(y0, np.nan), False
        self._kernel = (lu, piv)
        v, _ = getrs(lu, piv, v0 - self.k @ ieq)
        return y0 - self.z @ (ieq + dg * v), False

    def refine(
        self, x: np.ndarray, g: np.ndarray, ieq: np.ndarray, rhs0: np.ndarray, tol: np.ndarray
    ) -> np.ndarray | None:
        """One step of iterative refinement of the last solution x; None if inaccurate.

        The residual of x against the full matrix A is solved through the same update; the
        correction is the error estimate of x. x is accepted (corrected) when every
        component's correction is within REFINE_FRACTION of ``tol`` (Newton's per-unknown
        tolerance, reltol |x| + vntol/abstol), so an update that lost digits never passes for
        a converged solution.
        """
        ports = self.ports
        dg = self._dg
        port = dg * (ports.wt @ x) + ieq
        residual = rhs0 - self.shifted @ x - ports.w @ port
        correction = self.lu.solve(residual)
        if self._kernel is not None:
            v, _ = lapack_lu()[1](*self._kernel, ports.wt @ correction)
            correction = correction - self.z @ (dg * v)
        if np.count_nonzero(np.abs(correction) > REFINE_FRACTION * tol):
            return None
        return x + correction
