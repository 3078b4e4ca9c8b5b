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


SWITCHED = """* a switch closed by a DC control from t = 0, started from uic
V1 in 0 DC 1
VC c 0 DC 1
S1 in a c 0 SMOD
.model SMOD SW(VT=0.5 VH=0 RON=1 ROFF=1e9)
R1 a b 1k
C1 b 0 1u IC=0
.tran 10u 5m uic
.end
"""


@pytest.mark.parametrize("kernel", KERNELS)
def test_first_step_from_uic_locates_no_switch_transition(kernel):
    """The uic start holds v(c) = 0 V though VC fixes it at 1 V: no crossing happened, so the
    first step is the nominal one, min(tstop / 100, tstep) / 100 as ngspice's (it was cut
    towards the 'crossing' down to ~1e-14 s), and nothing is rejected there."""
    circuit = parse_netlist(SWITCHED)
    w = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=kernel))
    assert w.time[0] == pytest.approx(min(5e-3 / 100, 10e-6) / 100, rel=1e-12)
    exact = 1.0 - np.exp(-w.time / 1e-3)  # v(b): R1 C1 charged through the closed switch
    np.testing.assert_allclose(w["v(b)"], exact, atol=2e-3)


@requires_ngspice
def test_first_switched_step_from_uic_is_ngspices(tmp_path):
    path = tmp_path / "switched.cir"
    path.write_text(SWITCHED)
    theirs = run_ngspice(path, ["v(b)"])
    ours = simulate(parse_netlist(SWITCHED))
    assert ours.time[0] == pytest.approx(theirs.time[0], rel=1e-12)
