"""Dense and sparse paths give the same answers; the BLAS thread limit is restored."""

import numpy as np
import pytest

from circuitsim.netlist.circuit import (
    Capacitor,
    Circuit,
    Diode,
    Model,
    Pulse,
    Resistor,
    VoltageSource,
)
from circuitsim.solver import SimulationOptions, transient
from circuitsim.solver.threads import _openblas_controls, single_threaded_blas


def ladder(n: int) -> Circuit:
    c = Circuit(
        elements=[VoltageSource("V1", "n0", "0", waveform=Pulse(0, 1, 1e-6, 1e-7, 1e-7, 1.0))]
    )
    for i in range(1, n):
        c.add(
            Resistor(f"R{i}", f"n{i - 1}", f"n{i}", 100.0), Capacitor(f"C{i}", f"n{i}", "0", 1e-9)
        )
    c.add(Diode("D1", f"n{n - 1}", "0", "dm"))
    c.models["dm"] = Model("dm", "D", {"is": 1e-14})
    return c


def test_sparse_and_dense_agree():
    c = ladder(30)
    # dense_limit chooses the reference engine's algebra (the compiled kernel is dense only)
    dense = transient(c, 1e-7, 2e-5, options=SimulationOptions(dense_limit=1000, kernel="python"))
    sparse = transient(c, 1e-7, 2e-5, options=SimulationOptions(dense_limit=0, kernel="python"))
    assert np.array_equal(dense.time, sparse.time) or len(dense.time) == len(sparse.time)
    assert np.max(np.abs(dense["n29"] - np.interp(dense.time, sparse.time, sparse["n29"]))) < 1e-9


def test_thread_limit_is_restored():
    controls = _openblas_controls()
    if not controls:
        pytest.skip("no OpenBLAS found in this process")
    before = [get() for get, _ in controls]
    with single_threaded_blas():
        assert all(get() == 1 for get, _ in controls)
    assert [get() for get, _ in controls] == before


def test_sparse_path_matches_dense_on_the_precision_rectifier():
    # High-gain VCVS loops closed only through diodes: the sparse assembly must reproduce
    # the dense path (same time points, same waveforms to rounding).
    from pathlib import Path

    from circuitsim.netlist.reader import read_netlist
    from circuitsim.solver import simulate

    circuit = read_netlist(Path(__file__).parent / "golden" / "precision_rectifier.cir")
    dense = simulate(circuit, SimulationOptions(reltol=1e-6, dense_limit=1000, kernel="python"))
    sparse = simulate(circuit, SimulationOptions(reltol=1e-6, dense_limit=0, kernel="python"))
    assert len(dense.time) == len(sparse.time)
    assert np.max(np.abs(dense["out"] - sparse["out"])) < 1e-6


def test_ports_kernel_inverse_and_products_match_lapack_and_blas():
    """lowrank.invert / multiply / matvec (the ports kernel's own loops, so that it never
    loads scipy's LAPACK) against numpy's LAPACK and BLAS, on an MNA-like matrix that needs
    row swaps (zero diagonal entries)."""
    from circuitsim.solver.compiled.lowrank import invert, matvec, multiply

    rng = np.random.default_rng(7)
    n = 40
    B = np.where(rng.random((n, n)) < 0.15, rng.normal(size=(n, n)), 0.0) + 3 * np.eye(n)
    B[[0, 5, 9], [0, 5, 9]] = 0.0  # op-amp rows: no diagonal entry
    B[0, 1] = B[5, 2] = B[9, 3] = 2.0
    inverse = invert(B, np.empty((n, n)))
    assert np.allclose(inverse, np.linalg.inv(B), rtol=1e-12, atol=1e-12)
    assert np.allclose(inverse @ B, np.eye(n), atol=1e-12)
    U, x = rng.normal(size=(n, 7)), rng.normal(size=n)
    assert np.allclose(multiply(inverse, U, np.empty((n, 7))), inverse @ U, atol=1e-12)
    assert np.allclose(matvec(inverse, x, np.empty(n)), inverse @ x, atol=1e-12)


def test_ports_kernel_inverse_refuses_a_singular_matrix():
    from circuitsim.solver.compiled.lowrank import invert

    B = np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 1.0]])
    with pytest.raises(np.linalg.LinAlgError):
        invert(B, np.empty((3, 3)))
