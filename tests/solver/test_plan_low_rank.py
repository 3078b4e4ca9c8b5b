"""The kernel plan's low-rank columns, built sparse, against their dense definition.

U = [W, E_lin] and V^T = [W^T; Q_lin]: W's column k is e_p - e_n of port k (junctions, then
switches; ground rows left out), E_lin the system's E at the linear charges' columns, Q_lin
its Q at their rows. The reference here builds them densely from the system's matrices, as
the plan did before it was made sparse.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from circuitsim.netlist.reader import read_netlist
from circuitsim.solver.compiled.plan import build_plan, low_rank_columns
from circuitsim.solver.engine import build_system

GOLDEN = Path(__file__).parent / "golden"


def dense_reference(system, port_p, port_n, lin):
    """(U, VT), dense, from the definition."""
    n, r = system.size, port_p.size
    E = system.compressed("E").toarray()[:, lin]
    Q = system.compressed("Q").toarray()[lin]
    W = np.zeros((n, r))
    for k in range(r):
        if port_p[k] >= 0:
            W[port_p[k], k] += 1.0
        if port_n[k] >= 0:
            W[port_n[k], k] -= 1.0
    return np.hstack([W, E]), np.vstack([W.T, Q])


def csr_of(matrix):
    """(ptr, idx, val) of a dense matrix, row by row, columns ascending."""
    ptr, idx, val = [0], [], []
    for row in matrix:
        (cols,) = np.nonzero(row)
        idx.extend(cols)
        val.extend(row[cols])
        ptr.append(len(idx))
    return np.array(ptr), np.array(idx, dtype=np.int64), np.array(val)


def plan_of(path: Path, dense: bool):
    circuit = read_netlist(path)
    system = build_system(circuit, None)
    tran = circuit.transient
    max_step = tran.tmax or tran.tstop / 50
    plan, _ = build_plan(system, np.array([tran.tstop]), tran.tstop, max_step,
                         1e-11 * max_step, False, dense)  # fmt: skip
    return system, plan


@pytest.mark.parametrize(
    "name", ["precision_rectifier.cir", "switch.cir", "rlc.cir", "nested.cir", "halfwave.cir"]
)
def test_the_compressed_columns_are_those_of_the_dense_definition(name):
    for dense in (True, False):
        system, plan = plan_of(GOLDEN / name, dense)
        U, VT = dense_reference(system, plan.port_p, plan.port_n, plan.lin_slots)
        assert U.shape[1] > 0
        for got, want in (
            ((plan.UT_ptr, plan.UT_idx, plan.UT_val), csr_of(U.T)),
            ((plan.VT_ptr, plan.VT_idx, plan.VT_val), csr_of(VT)),
        ):
            for a, b in zip(got, want, strict=True):
                assert np.array_equal(a, b)
        if dense:  # the ports kernel's dense copies, rows contiguous
            assert np.array_equal(plan.U, U) and np.array_equal(plan.VT, VT)
            assert plan.U.flags.c_contiguous and plan.VT.flags.c_contiguous
        else:  # the MNA kernel's plan holds none
            assert plan.U.size == 0 and plan.VT.size == 0


def test_a_port_between_one_node_and_itself_has_no_entry():
    # e_p - e_n is zero: the dense sum left no entry, nor may the compressed form
    system, plan = plan_of(GOLDEN / "precision_rectifier.cir", False)
    port_p = np.concatenate([plan.port_p, [0]])
    port_n = np.concatenate([plan.port_n, [0]])
    U, V = low_rank_columns(system, port_p, port_n, plan.lin_slots)
    new_column = port_p.size - 1
    assert U.ptr[new_column + 1] == U.ptr[new_column]  # no entries in the new port's column
    assert V.ptr[new_column + 1] == V.ptr[new_column]
