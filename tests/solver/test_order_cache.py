"""The MNA kernel's earlier pivot orders (compiled/order_cache.py): when a pivot becomes too
small, an order kept from before that suits the present matrix is taken instead of a new
SuperLU order; one that does not suit is never taken."""

from types import SimpleNamespace

import numpy as np

from circuitsim.solver.compiled import sparse_lu as slu
from circuitsim.solver.compiled.order_cache import EarlierOrders

# a 2 x 2 block whose pivot order flips when the port conductance crosses the other entry
G = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
M = np.zeros((3, 3))
PORT_P, PORT_N = np.array([0, 2]), np.array([-1, -1])
OFF, ON = np.array([1e-9, 1.0]), np.array([1e4, 1.0])
PLAN = SimpleNamespace(g_switch=np.zeros((0, 2)), terms=SimpleNamespace(kind=np.zeros(0)))


def refactors(lu, g) -> bool:
    slu.assemble(lu.a_val, lu.g_val, lu.m_val, 0.0, lu.port_pos, g, np.zeros(0))
    return slu.refactor(lu.a_ptr, lu.a_row, lu.a_val, lu.l_ptr, lu.l_row, lu.l_val, lu.u_ptr,
                        lu.u_row, lu.u_val, lu.work, lu.dirty, True) < 0  # fmt: skip


def state(g):
    return SimpleNamespace(state=np.zeros(0, dtype=bool), gd=g, terms=None)


def test_the_order_before_a_flip_is_taken_again_when_the_matrix_flips_back():
    lu = slu.analyse(G, M, PORT_P, PORT_N, OFF, 0.0)
    orders = EarlierOrders()
    assert orders.suited(PLAN, state(ON), 0.0) is None  # nothing kept yet
    assert not refactors(lu, ON)
    orders.keep(lu)  # the order made at OFF, before it is reordered in place at ON
    assert slu.repivot(lu, PORT_P, PORT_N, ON, 0.0) == 0
    assert refactors(lu, ON) and not refactors(lu, OFF)
    again = orders.suited(PLAN, state(OFF), 0.0)
    assert again is not None and orders.reused == 1 and not orders.kept
    # it solves the matrix at OFF
    b = np.array([1.0, 2.0, 3.0])
    x = np.zeros(3)
    assert refactors(again, OFF)
    slu.lu_solve(again.l_ptr, again.l_row, again.l_val, again.u_ptr, again.u_row, again.u_val,
             again.row_to, again.col_of, b, again.work, x)  # fmt: skip
    dense = slu.present_matrix(G, M, PORT_P, PORT_N, OFF, 0.0).toarray()
    assert np.allclose(dense @ x, b, rtol=0, atol=1e-12)
    # the order made at ON does not suit OFF: not taken
    orders.keep(lu)
    assert orders.suited(PLAN, state(OFF), 0.0) is None and len(orders.kept) == 1
