"""Newton iteration limits as ngspice applies them: its NIiter raises any limit below 100 to
100 (``SimulationOptions.itl_floor``), so ``.options itl4=3`` or the default itl4 = 10 give 100
iterations per time point, and our step sequences follow ngspice's."""

from __future__ import annotations

import numpy as np
import pytest

from circuitsim.netlist.circuit import Circuit
from circuitsim.solver import SimulationOptions, simulate, transient
from circuitsim.solver.errors import CircuitInputError
from tests.solver.conftest import requires_ngspice
from tests.solver.test_compiled_chain import chain_circuit
from tests.solver.test_compiled_kernel import KERNELS, diode_sine


def test_effective_limits_are_raised_to_the_floor():
    opts = SimulationOptions(itl1=3, itl4=10)
    assert (opts.itl_floor, opts.op_iterations, opts.transient_iterations) == (100, 100, 100)
    opts = SimulationOptions(itl1=300, itl4=150)
    assert (opts.op_iterations, opts.transient_iterations) == (300, 150)
    for no_floor in (0, 1):
        opts = SimulationOptions(itl1=3, itl4=2, itl_floor=no_floor)
        assert (opts.op_iterations, opts.transient_iterations) == (3, 2)
    # ngspice accepts itl4=0 (its NIiter makes it 100); without a floor at least one iteration
    assert SimulationOptions(itl4=0).transient_iterations == 100
    assert SimulationOptions(itl4=0, itl_floor=0).transient_iterations == 1


@pytest.mark.parametrize(
    "bad", [{"itl_floor": -1}, {"itl_floor": 2.5}, {"itl_floor": True}, {"itl4": -1}, {"itl1": -3}]
)
def test_bad_iteration_limits_are_named(bad):
    (name,) = bad
    with pytest.raises(CircuitInputError, match=name):
        SimulationOptions(**bad)


def test_itl_floor_is_not_read_from_options_cards():
    """ngspice has no such option: a netlist cannot lower the floor (as it cannot in ngspice)."""
    circuit = Circuit(options={"itl4": 3, "itl_floor": 0})
    opts = SimulationOptions.from_circuit(circuit)
    assert (opts.itl4, opts.itl_floor, opts.transient_iterations) == (3, 100, 100)


def run(kernel: str, **limits):
    w = transient(diode_sine(), 1e-5, 1e-3, options=SimulationOptions(kernel=kernel, **limits))
    assert w.stats["kernel"] == kernel
    return w


@pytest.mark.parametrize("kernel", KERNELS)
def test_low_itl4_runs_as_ngspice_runs_it(kernel):
    """itl4 = 3 under the default floor is the run of itl4 = 10 and of itl4 = 100, time point
    for time point; without the floor the same itl4 = 3 fails Newton and cuts steps (measured
    on the python loop: 122 steps, 7 rejected, against 106 and 0), so the floor is what makes
    them equal."""
    low = run(kernel, itl4=3)
    for other in (run(kernel, itl4=10), run(kernel, itl4=100, itl_floor=0)):
        assert np.array_equal(low.time, other.time)
        for name in low.names:
            assert np.array_equal(low[name], other[name]), name
        assert low.stats["newton_iterations"] == other.stats["newton_iterations"]
    unfloored = run(kernel, itl4=3, itl_floor=0)
    assert unfloored.stats["rejected"] > low.stats["rejected"]
    assert len(unfloored.time) > len(low.time)


@requires_ngspice
def test_chain_takes_ngspice_step_count(tmp_path):
    """The four-mass chain over 5 s (16 diodes, from uic): with ngspice's effective iteration
    limit our time points are within 2 % of ngspice's (its ``rusage`` counts 3891 accepted
    steps, 44 rejected; ours with itl4 = 100 before the floor: 3889 steps, 51 rejected); with a
    limit of 10 iterations we took 6.4 % more (4141 steps, 198 rejected; docs/solver.md,
    "Profile at scale")."""
    from circuitsim.interop.ngspice import run_ngspice

    circuit = chain_circuit(tmp_path, 4, 5.0)
    ours = simulate(circuit, SimulationOptions.from_circuit(circuit))
    theirs = run_ngspice(circuit, ["v(x1)"])
    # time points written (neither engine writes t = 0 for a uic run)
    assert abs(len(ours.time) - len(theirs.time)) <= 0.02 * len(theirs.time), (
        len(ours.time),
        len(theirs.time),
    )
