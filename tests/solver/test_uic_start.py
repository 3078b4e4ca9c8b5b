"""A ``uic`` transient starts from initial conditions that are not a solution of the circuit
(only .ic nodes and IC= charges are set; every other node is at 0 V): like ngspice, no t = 0
point is returned, and the first point is the first step's solution."""

import numpy as np
import pytest

from circuitsim.interop.ngspice import run_ngspice
from circuitsim.netlist.reader import parse_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.variants import simulate_variants
from tests.solver.conftest import requires_ngspice

# C1 discharges through R1 from 2 V (tau = 1 ms); E1 buffers it onto node b
NETLIST = """* uic start
C1 a 0 1u IC=2
R1 a 0 1k
E1 b 0 a 0 1
R2 b 0 1k
.tran 10u 1m uic
.end
"""
KERNELS = ["python", "compiled", "ports"]


@pytest.mark.parametrize("kernel", KERNELS)
def test_uic_run_returns_solutions_only(kernel):
    circuit = parse_netlist(NETLIST)
    w = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=kernel, reltol=1e-6))
    assert w.time[0] > 0.0
    exact = 2.0 * np.exp(-w.time / 1e-3)  # v(a) = v(b) from the first point on
    np.testing.assert_allclose(w["v(a)"], exact, rtol=0, atol=2e-4)
    np.testing.assert_allclose(w["v(b)"], exact, rtol=0, atol=2e-4)


def test_uic_sweep_variants_start_after_zero_too():
    circuit = parse_netlist(NETLIST)
    (alone,) = simulate_variants([circuit], ["v(b)"])
    single = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="ports"))
    np.testing.assert_array_equal(alone.time, single.time)
    assert alone.time[0] > 0.0


def test_operating_point_start_keeps_its_t0_point():
    circuit = parse_netlist(NETLIST.replace(" uic", "").replace(" IC=2", ""))
    w = simulate(circuit)
    assert w.time[0] == 0.0


@requires_ngspice
def test_uic_first_points_agree_with_ngspice(tmp_path):
    path = tmp_path / "uic.cir"
    path.write_text(NETLIST)
    theirs = run_ngspice(path, ["v(a)", "v(b)"])
    ours = simulate(parse_netlist(NETLIST))
    assert theirs.time[0] > 0.0 and ours.time[0] > 0.0
    early = theirs.time < 2e-5
    for name in ("v(a)", "v(b)"):
        np.testing.assert_allclose(
            np.interp(theirs.time[early], ours.time, ours[name]), theirs[name][early], atol=1e-4
        )
