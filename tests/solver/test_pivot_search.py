"""Our own pivot orders (compiled/pivot_search.py, compiled/sparse_order.py) and numpy's
compressed matrices (solver/compressed.py): against dense algebra and scipy, and on the
MNA kernel's runs (which then load no scipy)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.compiled import sparse_order
from circuitsim.solver.compiled.fill import lu_pattern
from circuitsim.solver.compiled.pivot_search import (
    maximum_matching,
    minimum_degree,
    threshold_pivots,
)
from circuitsim.solver.compressed import Compressed, product
from circuitsim.solver.engine import build_system
from tests.solver.test_compiled_chain import chain_circuit


def random_matrix(n: int, seed: int, density: float = 0.1) -> np.ndarray:
    """A random sparse matrix with a permuted diagonal (structurally nonsingular)."""
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=density, random_state=seed).toarray()
    A[rng.permutation(n), np.arange(n)] += 1.0 + rng.random(n)
    return A


# --- numpy's compressed matrices -----------------------------------------------------------


def test_compressed_sums_duplicates_drops_zeros_and_multiplies_as_dense():
    rows = np.array([0, 2, 2, 1, 0, 1])
    cols = np.array([0, 1, 1, 2, 2, 2])
    values = np.array([1.0, 2.0, 3.0, 4.0, 5.0, -4.0])  # (1, 2) sums to zero
    a = Compressed.from_triplets(rows, cols, values, (3, 3))
    dense = np.zeros((3, 3))
    np.add.at(dense, (rows, cols), values)
    assert np.array_equal(a.toarray(), dense)
    assert a.nnz == 3  # (0, 0), (2, 1), (0, 2): the zero left out
    kept = Compressed.from_triplets(rows, cols, values, (3, 3), drop_zeros=False)
    assert kept.nnz == 4 and np.array_equal(kept.toarray(), dense)
    assert np.array_equal(a.take_rows(np.array([2, 0])).toarray(), dense[[2, 0]])
    x = np.array([1.0, -2.0, 0.5])
    assert np.allclose(a @ x, dense @ x, rtol=1e-15, atol=0)
    assert np.array_equal(a.scipy("csr").toarray(), dense)
    assert np.array_equal(Compressed.of(sp.csr_matrix(dense)).toarray(), dense)
    assert np.array_equal(Compressed.of(dense).toarray(), dense)


def test_the_product_is_the_dense_product():
    left, right = random_matrix(12, 1)[:, :7], random_matrix(12, 2)[:7]
    got = product(Compressed.of(left), Compressed.of(right)).toarray()
    assert np.allclose(got, left @ right, rtol=1e-14, atol=1e-15)


# --- the search --------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_matching_pairs_every_column_with_an_entry_of_its_own_row(seed):
    A = Compressed.of(random_matrix(40, seed, density=0.05))
    first = np.arange(A.nnz, dtype=np.int64)[::-1].copy()  # any order of offers
    row_of = maximum_matching(A.ptr, A.row, first)
    assert sorted(row_of) == list(range(40))  # a permutation
    dense = A.toarray()
    assert np.all(dense[row_of, np.arange(40)] != 0)


def test_the_matching_leaves_a_column_without_a_row_when_the_matrix_is_structurally_singular():
    dense = np.eye(4)
    dense[:, 3] = 0.0
    dense[0, 3] = 1.0  # columns 0 and 3 have row 0 only
    A = Compressed.of(dense)
    row_of = maximum_matching(A.ptr, A.row, np.arange(A.nnz, dtype=np.int64))
    assert np.count_nonzero(row_of < 0) == 1


def test_the_matching_takes_the_largest_entries_offered_first():
    # columns 0 and 1 both hold rows 0 and 1; offered by size, each takes its large entry
    dense = np.array([[1e-9, 5.0], [3.0, 1e-9]])
    A = Compressed.of(dense)
    by_size = np.argsort(-np.abs(A.val), kind="stable").astype(np.int64)
    assert maximum_matching(A.ptr, A.row, by_size).tolist() == [1, 0]


def test_minimum_degree_eliminates_an_arrow_matrix_without_fill():
    # node 0 joined to all others (an arrow): leaves first and the hub last give no fill,
    # the hub first would fill the whole matrix
    n = 9
    dense = np.eye(n)
    dense[0, :] = dense[:, 0] = 1.0
    A = Compressed.of(dense)
    order = minimum_degree(n, A.ptr, A.row)
    assert sorted(order) == list(range(n)) and 0 in order[-2:]  # (ties: the lower index)
    permuted = Compressed.of(dense[np.ix_(order, order)])
    l_ptr, _, u_ptr, _ = lu_pattern(permuted.ptr, permuted.row)
    assert l_ptr[-1] + u_ptr[-1] == permuted.nnz  # L + U hold A's entries only


def partial_pivoting(dense: np.ndarray, col_order: np.ndarray) -> list[int]:
    """The pivot rows of dense LU with partial pivoting (largest magnitude) in this column
    order: the independent reference."""
    work = dense[:, col_order].copy()
    free = list(range(dense.shape[0]))
    rows = []
    for k in range(dense.shape[0]):
        pivot = max(free, key=lambda r: abs(work[r, k]))
        rows.append(pivot)
        free.remove(pivot)
        factors = work[free, k] / work[pivot, k]
        work[free, k:] -= np.outer(factors, work[pivot, k:])
    return rows


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_threshold_one_without_preference_is_partial_pivoting(seed):
    dense = random_matrix(30, seed)
    A = Compressed.of(dense)
    col_order = np.random.default_rng(seed).permutation(30).astype(np.int64)
    none = np.full(30, -1, dtype=np.int64)
    row_to, failed = threshold_pivots(A.ptr, A.row, A.val, col_order, none, 1.0)
    assert failed == -1
    assert np.argsort(row_to).tolist() == partial_pivoting(dense, col_order)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_preferred_row_is_taken_while_large_enough(seed):
    n = 30
    dense = random_matrix(n, seed)
    A = Compressed.of(dense)
    col_order = np.arange(n, dtype=np.int64)
    preferred = maximum_matching(A.ptr, A.row, np.arange(A.nnz, dtype=np.int64))
    row_to, failed = threshold_pivots(A.ptr, A.row, A.val, col_order, preferred, 0.1)
    assert failed == -1
    row_of = np.argsort(row_to)
    work = dense.copy()
    free = list(range(n))
    taken = 0
    for k in range(n):  # each pivot: the preferred row if >= 0.1 of the largest, else it
        largest = max(abs(work[r, k]) for r in free)
        want = preferred[k]
        if want in free and abs(work[want, k]) >= 0.1 * largest:
            assert row_of[k] == want
            taken += 1
        else:
            assert abs(work[row_of[k], k]) == largest
        pivot = row_of[k]
        free.remove(pivot)
        work[free, k:] -= np.outer(work[free, k] / work[pivot, k], work[pivot, k:])
    assert taken > n // 2


def test_a_singular_matrix_names_the_column_without_a_pivot():
    dense = random_matrix(10, 5)
    dense[:, 6] = dense[:, 2] * 3.0  # column 6 is a multiple of column 2
    A = Compressed.of(dense)
    order = np.arange(10, dtype=np.int64)
    _, failed = threshold_pivots(A.ptr, A.row, A.val, order, np.full(10, -1, np.int64), 0.1)
    assert failed == 6


# --- on the MNA kernel ---------------------------------------------------------------------


def test_a_sparse_system_on_the_mna_kernel_never_builds_scipy_matrices(tmp_path):
    """Four masses (162 unknowns, above dense_limit): the MNA kernel's plan and pivot orders
    take the compressed parts; scipy's forms are built only at their first use."""
    circuit = chain_circuit(tmp_path, 4, 0.2)
    options = SimulationOptions.from_circuit(circuit, kernel="compiled")
    system = build_system(circuit, options)
    assert not system.dense
    from circuitsim.solver.compiled.runner import run_compiled

    stats: dict = {}
    run_compiled(system, 1e-3, 0.2, 0.0, 1e-3, True, None, stats)
    assert stats["kernel"] == "compiled" and stats["accepted"] > 50
    assert not {"G", "Q", "E", "M", "_assembler"} & set(vars(system))
    assert np.array_equal(system.G.toarray(), system.compressed("G").toarray())  # on demand


def test_our_order_and_superlus_give_the_same_run(tmp_path, monkeypatch):
    """The same chain of four masses with our pivot order and with SuperLU's: the traces
    agree to round-off (the orders differ, the matrices and the steps do not)."""
    circuit = chain_circuit(tmp_path, 4, 0.5)
    ours = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="compiled"))
    monkeypatch.setattr(sparse_order, "OWN_ORDER_LIMIT", 0)
    theirs = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="compiled"))
    assert ours.stats["accepted"] == theirs.stats["accepted"]
    for name in ("v(x1)", "v(x4)"):
        a, b = ours.signals[name], theirs.signals[name]
        assert np.max(np.abs(a - b)) <= 1e-6 * np.max(np.abs(b))


def test_the_search_trial_compiles_the_search_for_the_types_of_a_run(tmp_path):
    """A process that builds the start-up library after a run above OWN_ORDER_LIMIT never
    called the search; the trial does, with the argument types a run's call has (a build
    exports only the signatures compiled in its process)."""
    from circuitsim.solver.compiled import pivot_search

    sparse_order.search_trial()
    for function in pivot_search.SEARCH_FUNCTIONS:
        assert function.signatures, function
    circuit = chain_circuit(tmp_path, 4, 0.05)  # a run's calls: no new signature
    before = {f: list(f.signatures) for f in pivot_search.SEARCH_FUNCTIONS}
    simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="compiled"))
    assert {f: list(f.signatures) for f in pivot_search.SEARCH_FUNCTIONS} == before
