"""LU factorization and solve: LAPACK for small dense systems, SuperLU past a size.

Small systems go straight to LAPACK ``dgetrf``/``dgetrs`` (no argument checking, no copies
beyond the one factor), several times cheaper than ``scipy.linalg.lu_factor`` for the 20-150
unknowns of an op-amp circuit. The engine runs with OpenBLAS held to one thread
(:mod:`circuitsim.solver.threads`); docs/solver.md has the dense/sparse crossover measurement
behind ``SimulationOptions.dense_limit``.
"""

from __future__ import annotations

from functools import cache
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import scipy.sparse as sp


@cache
def lapack_lu() -> tuple:
    """scipy's LAPACK ``dgetrf`` and ``dgetrs``, looked up at the first factorization (not at
    import: a ports-kernel run of a uic circuit factors nothing here, and its process then
    does not load scipy)."""
    from scipy.linalg import get_lapack_funcs

    return tuple(get_lapack_funcs(("getrf", "getrs"), dtype=np.float64))


class SingularPivot(Exception):
    """Raised by a factorization: ``index`` is the unknown whose pivot vanished (or None)."""

    def __init__(self, index: int | None):
        super().__init__(index)
        self.index = index


class DenseLU:
    """LU factors of a dense (n, n) matrix (the matrix is left untouched)."""

    def __init__(self, matrix: np.ndarray):
        getrf, self._getrs = lapack_lu()
        lu, piv, info = getrf(matrix, overwrite_a=False)
        if info > 0:
            raise SingularPivot(info - 1)
        if info < 0:
            raise SingularPivot(None)
        self._lu, self._piv = lu, piv

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """x with A x = rhs, shape (n,)."""
        x, _ = self._getrs(self._lu, self._piv, rhs)
        return x


class SparseLU:
    """SuperLU factors of a sparse (n, n) matrix."""

    def __init__(self, matrix: sp.spmatrix):
        import scipy.sparse as sp
        from scipy.sparse.linalg import splu

        try:
            self._lu = splu(sp.csc_matrix(matrix))
        except RuntimeError:
            raise SingularPivot(_empty_line(matrix)) from None

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """x with A x = rhs, shape (n,)."""
        return self._lu.solve(rhs)


def _empty_line(matrix: sp.spmatrix) -> int | None:
    """An all-zero column (or row) of ``matrix``, the likeliest floating unknown, or None."""
    import scipy.sparse as sp

    csc = sp.csc_matrix(matrix)
    csc.eliminate_zeros()
    for counts in (np.diff(csc.indptr), np.diff(sp.csr_matrix(csc).indptr)):
        empty = np.flatnonzero(counts == 0)
        if empty.size:
            return int(empty[0])
    return None


def factor(matrix) -> DenseLU | SparseLU:
    """Factor a dense ndarray with LAPACK or a scipy sparse matrix with SuperLU."""
    if isinstance(matrix, np.ndarray):
        return DenseLU(matrix)
    return SparseLU(matrix)
