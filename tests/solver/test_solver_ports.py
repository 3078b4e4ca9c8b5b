"""Newton at the junction ports (port_solver.py) against direct LU of the full matrix."""

from pathlib import Path

import numpy as np
import pytest

from circuitsim.netlist.reader import read_netlist
from circuitsim.solver import SimulationOptions
from circuitsim.solver.engine import build_system
from circuitsim.solver.linalg import factor
from circuitsim.solver.port_solver import Ports, PortSolver
from circuitsim.solver.transient import run_transient

GOLDEN = Path(__file__).parent / "golden"


def _run(name: str, ports: bool, **options):
    circuit = read_netlist(GOLDEN / name)
    opts = SimulationOptions.from_circuit(circuit, **options)
    system = build_system(circuit, opts)
    if not ports:
        system.ports = None  # the general path: a fresh LU of the full matrix per iteration
    tran = circuit.transient
    times, x = run_transient(system, tran.tstep, tran.tstop, tmax=tran.tmax, uic=tran.uic)
    return system, times, x


@pytest.mark.parametrize("name", ["precision_rectifier.cir", "halfwave.cir"])
def test_port_newton_reproduces_full_factorizations(name):
    # Precision rectifier: ideal (1e5) op-amp loops closed only through the diodes, the case
    # where updates from an open-loop base lose digits. Both paths run at reltol 1e-6.
    system, t_ports, x_ports = _run(name, ports=True)
    assert system.ports is not None
    _, t_full, x_full = _run(name, ports=False)
    assert abs(len(t_ports) - len(t_full)) <= 0.01 * len(t_full)
    span = np.ptp(x_full, axis=0) + 1e-9
    on_full = np.array([np.interp(t_full, t_ports, x_ports[:, k]) for k in range(x_full.shape[1])])
    assert np.max(np.abs(on_full.T - x_full) / span) < 2e-4
    # far fewer factorizations than Newton iterations
    assert system.factorizations < 0.5 * len(t_ports)


def _high_gain_rectifier_base(gain: float):
    """Dense MNA of the rectifier's half-wave stage without its diodes, and its two ports.

    Unknowns: v(n1), v(a), v(h), i(E1). R1 = 10k from a 1 V input (in the rhs), R2 = 10k h-n1,
    E1: v(a) = -gain v(n1). Ports: D1 n1 -> a, D2 a -> h.
    """
    g = 1e-4
    base = np.array(
        [
            [2 * g, 0.0, -g, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [-g, 0.0, g, 0.0],
            [gain, 1.0, 0.0, 0.0],
        ]
    )
    base[[0, 2], [0, 2]] += 1e-12  # gmin-like shunts keep h and n1 defined
    rhs0 = np.array([g * 1.0, 0.0, 0.0, 0.0])
    ports = Ports(4, np.array([0, 1]), np.array([1, 2]))
    return base, rhs0, ports


def test_update_is_exact_or_refused():
    # The base is factored with both diodes off (1e-12 S) and the update asked for one of
    # them on (0.04 S): an open loop of gain 1e6 closes through the update. Whatever refine
    # accepts must agree with a direct solve of the full matrix within its tolerance.
    base, rhs0, ports = _high_gain_rectifier_base(1e6)
    solver = PortSolver(base, ports, np.array([1e-12, 1e-12]))
    for g in ([0.04, 1e-12], [1e-12, 0.04], [0.04, 0.04], [1e-3, 2e-12]):
        g = np.array(g)
        ieq = np.array([-1e-3, 2e-4])
        x, exact = solver.solve(g, ieq, rhs0)
        assert not exact
        full = ports.stamped(base, g)
        direct = factor(full).solve(rhs0 - ports.w @ ieq)
        tol = 1e-6 * np.abs(direct) + 1e-9
        refined = solver.refine(x, g, ieq, rhs0, tol)
        if refined is not None:
            assert np.all(np.abs(refined - direct) <= tol)


def test_rebuilt_solver_is_a_plain_lu_solve():
    base, rhs0, ports = _high_gain_rectifier_base(1e6)
    g = np.array([0.04, 1e-12])
    ieq = np.array([-1e-3, 2e-4])
    solver = PortSolver(base, ports, np.array([1e-12, 1e-12]))
    solver.rebuild(g)
    x, exact = solver.solve(g, ieq, rhs0)
    assert exact
    direct = np.linalg.solve(ports.stamped(base, g), rhs0 - ports.w @ ieq)
    assert np.allclose(x, direct, rtol=1e-9, atol=1e-12)


def test_bypass_changes_node_voltages_only_within_tolerance():
    # .options bypass=1 keeps a junction's evaluation while its voltage and current stay
    # within tolerance; the node voltages move by far less than their range. (The supply
    # current's charging spikes are left out: a shifted step moves a spike sideways, which a
    # pointwise comparison reads as a large difference.)
    system, t_on, x_on = _run("halfwave.cir", ports=True, bypass=1)
    _, t_off, x_off = _run("halfwave.cir", ports=True, bypass=0)
    nodes = np.flatnonzero(system.voltage)
    span = np.ptp(x_off[:, nodes], axis=0)
    on_off = np.array([np.interp(t_off, t_on, x_on[:, k]) for k in nodes]).T
    assert np.max(np.abs(on_off - x_off[:, nodes]) / span) < 2e-4
