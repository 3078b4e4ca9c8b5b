"""Probes: checked before the run, and only their unknowns recorded, by every loop."""

import numpy as np
import pytest

from circuitsim.netlist.reader import parse_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.errors import CircuitInputError

RECTIFIER = """* probes
V1 in 0 SIN(0 1 1k)
R1 in a 1k
D1 a b DX
C1 b 0 1u
R2 b 0 10k
.model DX D(is=1e-14)
.tran 10u 3m
.end
"""


def test_an_unknown_probe_is_refused_before_the_run(monkeypatch):
    from circuitsim.solver.compiled import runner

    def no_run(*args, **kwargs):
        raise AssertionError("the run started")

    monkeypatch.setattr(runner, "run_ports", no_run)
    monkeypatch.setattr(runner, "run_compiled", no_run)
    with pytest.raises(CircuitInputError, match=r"no signal v\(nope\); have v\(in\)"):
        simulate(parse_netlist(RECTIFIER), probes=["v(b)", "v(nope)"])


@pytest.mark.parametrize("kernel", ["ports", "compiled", "python"])
def test_probed_signals_are_those_of_the_full_run(kernel, monkeypatch):
    circuit = parse_netlist(RECTIFIER)
    options = SimulationOptions.from_circuit(circuit, kernel=kernel)
    full = simulate(circuit, options)
    from circuitsim.solver import engine
    from circuitsim.solver.compiled import runner

    recorded = []
    original_state, original_loop = runner._loop_state, engine.run_transient

    def spy(kind, start, plan, rows, capacity, *more):
        loop_state = original_state(kind, start, plan, rows, capacity, *more)
        recorded.append(loop_state[1].out_x.shape[1])  # the loop's output table's columns
        return loop_state

    def reference_spy(*args, **kwargs):
        times, solutions = original_loop(*args, **kwargs)
        recorded.append(solutions.shape[1])
        return times, solutions

    monkeypatch.setattr(runner, "_loop_state", spy)
    monkeypatch.setattr(engine, "run_transient", reference_spy)
    probed = simulate(circuit, options, probes=["B", "i(v1)"])
    assert probed.names == ["v(b)", "i(v1)"]
    for name in probed.names:
        assert np.array_equal(probed[name], full[name])
    assert recorded == [2]  # the two unknowns recorded, not all of them
