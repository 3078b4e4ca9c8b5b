"""Newton iterations as a low-rank update of a factored matrix (Woodbury identity).

When every nonlinear stamp of an iteration is a conductance between two nodes (junctions), the
iteration matrix is ``A = B + W diag(g) W^T``: B the cached base matrix (constant stamps,
reactive companions, switch states), W the m incidence columns ``e_p - e_n``. Then

    A^-1 r = y - Z (diag(1/g) + W^T Z)^-1 W^T y,   y = B^-1 r,   Z = B^-1 W

so B is factored and Z computed once per base (once per step size), and each Newton
iteration costs one solve with B's factors and an m x m dense solve instead of a fresh sparse
factorization. Every solution is checked by its residual against A; when the check fails (an
ill-conditioned B) or B is singular (a node held only by junctions), the caller factors A
directly.
"""

from __future__ import annotations

import numpy as np

RESIDUAL_LIMIT = 1e-11  # relative to |A| |x| + |r| (infinity norms)


class LowRankSolver:
    """Factors of one base matrix and its products with one set of ports."""

    def __init__(self, base, lu, p: np.ndarray, n: np.ndarray):
        size = base.shape[0]
        m = p.size
        w = np.zeros((size + 1, m))
        columns = np.arange(m)
        np.add.at(w, (p, columns), 1.0)
        np.add.at(w, (n, columns), -1.0)
        self.base, self.lu, self.p, self.n = base, lu, p, n
        z = np.asarray(lu.solve(w[:size]))
        self.z = z
        z_ext = np.vstack([z, np.zeros((1, m))])
        self.coupling = z_ext[p] - z_ext[n]  # W^T B^-1 W, shape (m, m)
        self.base_norm = float(abs(base).sum(axis=1).max())

    def matches(self, p: np.ndarray, n: np.ndarray) -> bool:
        """Whether these ports are the ones Z was computed for."""
        return p.size == self.p.size and np.array_equal(p, self.p) and np.array_equal(n, self.n)

    def solve(self, g: np.ndarray, rhs: np.ndarray) -> np.ndarray | None:
        """x with (B + W diag(g) W^T) x = rhs, or None if the residual check fails."""
        if not np.all(g > 0):
            return None
        y = self.lu.solve(rhs)
        y_ext = np.append(y, 0.0)
        kernel = self.coupling + np.diag(1.0 / g)
        try:
            t = np.linalg.solve(kernel, y_ext[self.p] - y_ext[self.n])
        except np.linalg.LinAlgError:
            return None
        x = y - self.z @ t
        x_ext = np.append(x, 0.0)
        current = g * (x_ext[self.p] - x_ext[self.n])
        residual = np.append(self.base @ x - rhs, 0.0)
        np.add.at(residual, self.p, current)
        np.add.at(residual, self.n, -current)
        scale = (self.base_norm + 2 * g.max()) * np.abs(x).max() + np.abs(rhs).max()
        if not np.abs(residual[:-1]).max() <= RESIDUAL_LIMIT * scale:
            return None
        return x
