"""Sparse matrices in compressed columns with numpy alone.

The MNA kernel needs a circuit's constant matrices, its charge matrices and its pivot orders
in sparse form, and no more than that form: building, summing and multiplying.
scipy.sparse costs a process 0.1-0.2 s of CPU to import (docs/performance.md, section 6),
more than a small circuit's whole run; the numpy reference loop still takes scipy's forms
(:meth:`Compressed.scipy`), built from these.
"""

from __future__ import annotations

import numpy as np


class Compressed:
    """A (rows, columns) matrix by columns: column j's rows are ``row[ptr[j]:ptr[j + 1]]``,
    ascending, with their values in ``val``; no row twice in a column.

    Parameters
    ----------
    ptr : ndarray of int64, shape (columns + 1,)
    row : ndarray of int64, shape (nnz,)
    val : ndarray of float, shape (nnz,)
    shape : tuple of int
        (rows, columns).
    """

    __slots__ = ("ptr", "row", "val", "shape", "_columns")

    def __init__(self, ptr, row, val, shape):
        self.ptr, self.row, self.val = ptr, row, val
        self.shape = (int(shape[0]), int(shape[1]))
        self._columns = None

    @classmethod
    def from_triplets(cls, rows, cols, values, shape, drop_zeros: bool = True) -> Compressed:
        """The matrix whose entries are the sums of the triplets' values (in the triplets'
        order); entries that sum to zero left out when ``drop_zeros``."""
        rows = np.asarray(rows, dtype=np.int64)
        cols = np.asarray(cols, dtype=np.int64)
        values = np.broadcast_to(np.asarray(values, dtype=float), rows.shape)
        n_rows, n_cols = shape
        keys, where = np.unique(cols * n_rows + rows, return_inverse=True)
        sums = np.bincount(where, weights=values, minlength=keys.size)
        if drop_zeros:
            kept = sums != 0.0
            keys, sums = keys[kept], sums[kept]
        col = keys // max(n_rows, 1)
        ptr = np.zeros(n_cols + 1, dtype=np.int64)
        np.cumsum(np.bincount(col, minlength=n_cols), out=ptr[1:])
        return cls(ptr, keys - col * n_rows, sums, (n_rows, n_cols))

    @classmethod
    def from_dense(cls, array: np.ndarray) -> Compressed:
        """The nonzero entries of a dense matrix."""
        cols, rows = np.nonzero(np.asarray(array).T)
        return cls.from_triplets(rows, cols, array[rows, cols], array.shape)

    @classmethod
    def of(cls, matrix) -> Compressed:
        """``matrix`` (Compressed, a dense array or a scipy sparse matrix) as Compressed."""
        if isinstance(matrix, Compressed):
            return matrix
        if isinstance(matrix, np.ndarray):
            return cls.from_dense(matrix)
        coo = matrix.tocoo()
        return cls.from_triplets(coo.row, coo.col, coo.data, coo.shape)

    @property
    def nnz(self) -> int:
        return int(self.row.size)

    def columns(self) -> np.ndarray:
        """(nnz,) int64: the column of each entry."""
        if self._columns is None:
            self._columns = np.repeat(np.arange(self.shape[1], dtype=np.int64), np.diff(self.ptr))
        return self._columns

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        """The product with a vector of (columns,)."""
        return np.bincount(self.row, weights=self.val * x[self.columns()],
                           minlength=self.shape[0])  # fmt: skip

    def triplets(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rows, cols, values) of the entries, by column."""
        return self.row, self.columns(), self.val

    def toarray(self) -> np.ndarray:
        out = np.zeros(self.shape)
        rows, cols, values = self.triplets()
        out[rows, cols] = values
        return out

    def take_rows(self, rows: np.ndarray) -> Compressed:
        """The matrix of the given rows, in that order (each once)."""
        new = np.full(self.shape[0], -1, dtype=np.int64)
        new[rows] = np.arange(len(rows))
        r, c, v = self.triplets()
        kept = new[r] >= 0
        return Compressed.from_triplets(new[r[kept]], c[kept], v[kept],
                                        (len(rows), self.shape[1]))  # fmt: skip

    def scipy(self, form: str = "csc"):
        """scipy's sparse matrix (``form`` "csc" or "csr") of the same entries."""
        import scipy.sparse as sp

        matrix = sp.csc_matrix((self.val, self.row, self.ptr), shape=self.shape)
        return matrix if form == "csc" else matrix.tocsr()


def unique(values) -> np.ndarray:
    """The distinct values, ascending: ``np.unique`` without the import of numpy.ma that
    numpy 2's ``np.unique`` makes at its first call (11 ms of a process's start)."""
    values = np.sort(np.asarray(values).ravel())
    if values.size == 0:
        return values
    return values[np.concatenate(([True], values[1:] != values[:-1]))]


def product(a: Compressed, b: Compressed) -> Compressed:
    """The matrix product a @ b (zeros left out)."""
    b_rows, b_cols, b_vals = b.triplets()
    counts = np.diff(a.ptr)[b_rows]  # a's column k's entries, for every entry (k, j) of b
    total = int(counts.sum())
    ends = np.cumsum(counts)
    index = np.repeat(a.ptr[b_rows] - (ends - counts), counts) + np.arange(total)
    return Compressed.from_triplets(
        a.row[index], np.repeat(b_cols, counts), a.val[index] * np.repeat(b_vals, counts),
        (a.shape[0], b.shape[1]),
    )  # fmt: skip
