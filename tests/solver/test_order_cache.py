"""The MNA kernel's earlier pivot orders (compiled/order_cache.py): when a pivot becomes too
small, an order kept from before that suits the present matrix is taken instead of a new
SuperLU order; one that does not suit is never taken."""

from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from numba import njit
from numba.core import event

from circuitsim.netlist.reader import read_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.compiled import sparse_lu as slu
from circuitsim.solver.compiled import sparse_order
from circuitsim.solver.compiled.order_cache import EarlierOrders
from circuitsim.solver.errors import KernelCompileWarning

# a 2 x 2 block whose pivot order flips when the port conductance crosses the other entry
G = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
M = np.zeros((3, 3))
PORT_P, PORT_N = np.array([0, 2]), np.array([-1, -1])
OFF, ON = np.array([1e-9, 1.0]), np.array([1e4, 1.0])
TL074_WHEELSET = Path(__file__).parents[2] / "netlists" / "wheelset_flange_tl074_ngspice.cir"
PLAN = SimpleNamespace(g_switch=np.zeros((0, 2)), terms=SimpleNamespace(kind=np.zeros(0)))


def refactors(lu, g) -> bool:
    slu.assemble(lu.a_val, lu.g_val, lu.m_val, 0.0, lu.port_pos, g, np.zeros(0))
    return slu.refactor(lu.a_ptr, lu.a_row, lu.a_val, lu.l_ptr, lu.l_row, lu.l_val, lu.u_ptr,
                        lu.u_row, lu.u_val, lu.work, lu.redo, True) < 0  # fmt: skip


def state(g):
    return SimpleNamespace(state=np.zeros(0, dtype=bool), gd=g, terms=None)


def test_the_order_before_a_flip_is_taken_again_when_the_matrix_flips_back():
    lu = sparse_order.analyse(G, M, PORT_P, PORT_N, OFF, 0.0)
    orders = EarlierOrders()
    assert orders.suited(PLAN, state(ON), 0.0) is None  # nothing kept yet
    assert not refactors(lu, ON)
    orders.keep(lu)  # the order made at OFF, before it is reordered in place at ON
    assert sparse_order.repivot(lu, PORT_P, PORT_N, ON, 0.0) == 0
    assert refactors(lu, ON) and not refactors(lu, OFF)
    again = orders.suited(PLAN, state(OFF), 0.0)
    assert again is not None and orders.reused == 1 and not orders.kept
    # it solves the matrix at OFF
    b = np.array([1.0, 2.0, 3.0])
    x = np.zeros(3)
    assert refactors(again, OFF)
    slu.lu_solve(again.l_ptr, again.l_row, again.l_val, again.u_ptr, again.u_row, again.u_val,
             again.row_to, again.col_of, b, again.work, x)  # fmt: skip
    dense = sparse_order.present_matrix(G, M, PORT_P, PORT_N, OFF, 0.0).toarray()
    assert np.allclose(dense @ x, b, rtol=0, atol=1e-12)
    # the order made at ON does not suit OFF: not taken
    orders.keep(lu)
    assert orders.suited(PLAN, state(OFF), 0.0) is None and len(orders.kept) == 1


def test_the_trials_compiled_code_is_compiled_at_the_start_announced_with_the_kernel(monkeypatch):
    """assemble is inlined into the MNA kernel, so the kernel's compile leaves no machine code
    for the trials' calls from Python: on a cold cache the first trial of an earlier order
    compiled it in the middle of the run, unannounced (measured: 1.1 s at load 10). A fresh
    dispatcher without a cache stands for the cold cache here: it must compile once, after
    the announcement and before the first trial."""
    from circuitsim.solver.compiled import order_cache, runner

    # SuperLU's COLAMD orders, as measured (our own order, which the runner takes for this
    # circuit's 266 unknowns, and SuperLU's minimum degree on A + A^T need no new order
    # before 1.3 s)
    monkeypatch.setattr(sparse_order, "OWN_ORDER_LIMIT", 0)
    monkeypatch.setattr(sparse_order, "SUPERLU_ORDERS", ("COLAMD",))
    circuit = read_netlist(TL074_WHEELSET)
    # the first trial of an earlier order: at 1.19 s (measured with the MNA kernel's chord;
    # 0.63 s before it)
    tran = circuit.transient
    circuit.analyses = [replace(tran, tstop=1.3) if a is tran else a for a in circuit.analyses]
    # with Newton limited to 10 iterations (itl_floor=0), as measured: under the floor of 100
    # the run to 0.7 s tried no earlier order
    options = SimulationOptions.from_circuit(circuit, kernel="compiled", itl_floor=0)
    simulate(circuit, options)  # the kernel itself compiled or loaded before
    cold = njit(inline="always")(slu.assemble.py_func)  # nothing compiled, no cache
    monkeypatch.setattr(order_cache, "assemble", cold)
    monkeypatch.setattr(runner, "_ANNOUNCED", set())
    events: list[str] = []
    notice = runner.compile_notice
    monkeypatch.setattr(runner, "compile_notice", lambda kind: events.append(kind) or notice(kind))
    suited = EarlierOrders.suited

    def trial(self, plan, st, a0):
        if self.kept:  # a trial that assembles
            events.append("trial")
        return suited(self, plan, st, a0)

    monkeypatch.setattr(EarlierOrders, "suited", trial)

    class Compiles(event.Listener):
        def on_start(self, ev):
            if ev.data["dispatcher"] is cold:
                events.append("compile")

        def on_end(self, ev):
            pass

    with pytest.warns(KernelCompileWarning, match="compiling the MNA kernel"):
        with event.install_listener("numba:compile", Compiles()):
            waves = simulate(circuit, options)
    assert waves.stats["kernel"] == "compiled"
    assert events[:2] == ["compiled", "compile"]
    assert events.count("compile") == 1 and events.count("trial") >= 1
