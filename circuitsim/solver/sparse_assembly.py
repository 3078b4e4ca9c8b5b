"""Adding per-iteration stamps to a cached sparse matrix without rebuilding it from triplets.

Building a scipy sparse matrix from triplets and adding two of them costs about half a
millisecond of Python and index bookkeeping, more than SuperLU's factorization of a 300-unknown
MNA matrix. The matrices of one circuit all live on one sparsity structure (constant stamps,
reactive stamps, gmin shunts, switch and diode positions), so this keeps that structure once,
holds each cached base matrix as a data array aligned to it, and adds stamps with
``np.add.at`` at precomputed positions. The structure grows (rarely, on first sight of a new
position) and then the aligned copies are rebuilt.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import scipy.sparse as sp


class SparseAssembler:
    """CSC matrices of size (n, n) on a shared, growing sparsity structure.

    Parameters
    ----------
    size : int
        n, the number of unknowns.
    cache_size : int
        How many aligned base matrices to keep.
    """

    def __init__(self, size: int, cache_size: int = 8):
        self.size = size
        self.cache_size = cache_size
        self.keys = np.zeros(0, dtype=np.int64)  # column-major positions c * n + r, sorted
        self.indices = np.zeros(0, dtype=np.int32)
        self.indptr = np.zeros(size + 1, dtype=np.int32)
        self._aligned: OrderedDict = OrderedDict()

    def _positions(self, keys: np.ndarray) -> np.ndarray | None:
        pos = np.searchsorted(self.keys, keys)
        if pos.size and (pos.max() >= self.keys.size or np.any(self.keys[pos] != keys)):
            return None
        return pos

    def _grow(self, keys: np.ndarray) -> None:
        self.keys = np.union1d(self.keys, keys)
        n = self.size
        self.indices = (self.keys % n).astype(np.int32)
        self.indptr = np.searchsorted(self.keys // n, np.arange(n + 1)).astype(np.int32)
        self._aligned.clear()

    def _base_data(self, key, base: sp.spmatrix) -> np.ndarray:
        data = self._aligned.get(key)
        if data is not None:
            self._aligned.move_to_end(key)
            return data
        coo = base.tocoo()
        keys = coo.col.astype(np.int64) * self.size + coo.row
        pos = self._positions(keys)
        if pos is None:
            self._grow(keys)
            pos = self._positions(keys)
        data = np.zeros(self.keys.size)
        np.add.at(data, pos, coo.data)
        self._aligned[key] = data
        if len(self._aligned) > self.cache_size:
            self._aligned.popitem(last=False)
        return data

    def add(
        self, key, base: sp.spmatrix, rows: np.ndarray, cols: np.ndarray, values: np.ndarray
    ) -> sp.csc_matrix:
        """``base + coo(values, (rows, cols))`` as a CSC matrix; ``key`` identifies ``base``."""
        keys = cols.astype(np.int64) * self.size + rows
        pos = self._positions(keys)
        if pos is None:
            self._grow(keys)
            pos = self._positions(keys)
        data = self._base_data(key, base)
        if pos is None or data.size != self.keys.size:  # the base itself grew the structure
            pos = self._positions(keys)
        data = data.copy()
        np.add.at(data, pos, values)
        import scipy.sparse as sp  # here: a dense system never gets an assembler

        return sp.csc_matrix((data, self.indices, self.indptr), shape=(self.size, self.size))
