"""The ports kernel's sparse factorization (compiled/sparse_factors.py): B^-1 of many
right-hand sides on our pivot order and LU, against numpy's dense solve (the ports kernel's
runs on it: test_compiled_chain.py, test_compiled_kernel.py; a start-up library's process of
one loads no scipy: test_startup_library.py)."""

from __future__ import annotations

import numpy as np

from circuitsim.solver.compiled.sparse_factors import sparse_solve
from tests.solver.test_pivot_search import random_matrix


def port_matrix(n: int, port_p, port_n, g) -> np.ndarray:
    """W diag(g) W^T, W's columns e_p - e_n (a -1 node: ground, left out), densely."""
    out = np.zeros((n, n))
    for p, m, value in zip(port_p, port_n, g, strict=True):
        w = np.zeros(n)
        if p >= 0:
            w[p] += 1.0
        if m >= 0:
            w[m] -= 1.0
        out += value * np.outer(w, w)
    return out


def test_the_sparse_solve_is_numpys_dense_solve():
    """An op-amp-like matrix (zero diagonal entries, so pivoting is needed), ports between
    nodes and to ground, 40 right-hand sides: the solutions agree with numpy's LAPACK to
    round-off."""
    n = 60
    G = random_matrix(n, 7, density=0.05)
    G[np.arange(0, n, 3), np.arange(0, n, 3)] = 0.0  # no diagonal there: the matching's rows
    M = np.diag(np.where(np.arange(n) % 2 == 0, 1e-6, 0.0))
    port_p = np.array([0, 5, 9, 20, 33], dtype=np.int64)
    port_n = np.array([1, -1, 40, -1, 2], dtype=np.int64)
    g = np.array([1e-12, 3.0, 0.5, 1e3, 2e-3])
    a0 = 2e4
    rhs = np.random.default_rng(3).standard_normal((40, n))
    B = G + a0 * M + port_matrix(n, port_p, port_n, g)
    solved = sparse_solve(G, M, port_p, port_n, g, a0, rhs)
    expected = np.linalg.solve(B, rhs.T).T
    assert solved is not None
    assert np.allclose(solved, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())


def test_a_singular_matrix_gives_no_solution():
    """Two rows that differ by a factor (numerically singular), and a node with no entry at
    all (structurally singular): None, as SuperLU's 'exactly singular' was."""
    G = np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 1.0]])
    none = np.zeros(0, dtype=np.int64)
    assert sparse_solve(G, np.zeros((3, 3)), none, none, np.zeros(0), 1.0, np.eye(3)) is None
    G = np.diag([1.0, 0.0, 1.0])
    assert sparse_solve(G, np.zeros((3, 3)), none, none, np.zeros(0), 1.0, np.eye(3)) is None

