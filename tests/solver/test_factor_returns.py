"""The ports kernel's return to Python for a factorization (newton.FACTOR): above SPARSE_FROM
unknowns the factorization is made sparse from Python (compiled/sparse_factors.py) and the
loop goes on where it stopped, bit for bit.

Forced on a circuit small enough for the compiled dense factorization (the same arithmetic
either way), a run that returns for every refactor must give exactly the steps and values of
the run that makes them inside the loop. Both run with fixed pauses: the loop's other returns
(every ~1 s of work by default) restart its local caches, which moves round-off."""

from __future__ import annotations

import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from circuitsim.solver import SimulationOptions
from circuitsim.solver.compiled import sparse_order
from circuitsim.solver.engine import build_system
from tests.solver.test_compiled_chain import chain_circuit

pytest.importorskip("numba")


def test_a_run_that_returns_for_its_factorizations_takes_the_same_steps(tmp_path, monkeypatch):
    from circuitsim.solver.compiled import newton, ports_start, run_ports_from, runner

    circuit = chain_circuit(tmp_path, 1, 5.0)  # 42 unknowns: dense
    # Newton limited to 10 iterations (itl_floor=0): its failures and cut steps make the
    # refactors (and second attempts) this test needs; under ngspice's limit of 100 this
    # chain runs on its first factorization alone (measured)
    options = SimulationOptions.from_circuit(circuit, kernel="ports", itl_floor=0)
    system = build_system(circuit, options)
    tran = circuit.transient
    start = ports_start(system, tran.tstep, tran.tstop, tran.tstart, tran.tmax, tran.uic)

    def simulate():
        stats: dict = {}
        times, values = run_ports_from(start, stats=stats, fixed_pauses=True)
        return times, values, stats

    times, values, inside = simulate()
    assert inside["factor_returns"] == 0
    assert inside["factorizations"] >= 3  # refactors during the run, not only the first

    resumed_at: Counter = Counter()
    factor = runner._factor

    def spy(plan, st, a0):
        resumed_at[int(st.ints[newton.RESUME_AT])] += 1
        factor(plan, st, a0)

    monkeypatch.setattr(runner, "factors_in_python", lambda state: True)
    monkeypatch.setattr(runner, "_factor", spy)
    times_returned, values_returned, returned = simulate()
    assert returned["factor_returns"] == inside["factorizations"]
    # measured: one refactor at the step's refactor test, one before a second Newton attempt
    assert resumed_at[newton.AT_REFACTOR_TEST] >= 1
    assert resumed_at[newton.AT_SECOND_ATTEMPT] >= 1
    for key in ("accepted", "rejected", "newton_iterations", "factorizations", "configurations"):
        assert returned[key] == inside[key], key
    assert np.array_equal(times_returned, times)
    assert np.array_equal(values_returned, values)


NO_COMPILE_SCRIPT = """
import sys
from pathlib import Path
from numba.core import event
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.compiled import sparse_order
from tests.solver.test_compiled_chain import chain_circuit


class Compiles(event.Listener):
    def __init__(self):
        self.names = []

    def on_start(self, ev):
        self.names.append(str(ev.data.get("dispatcher")))

    def on_end(self, ev):
        pass


compiles = Compiles()
event.register("numba:compile", compiles)
circuit = chain_circuit(Path(sys.argv[1]), 4, 0.5)
simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="compiled"))  # our orders
# SuperLU's COLAMD orders need new ones in this run: the loop returns for them
sparse_order.OWN_ORDER_LIMIT, sparse_order.SUPERLU_ORDERS = 0, ("COLAMD",)
for kernel in ("ports", "compiled"):
    waves = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=kernel))
    # pivot orders the MNA loop returned for: made anew, or kept ones taken again
    orders = waves.stats.get("pivot_orders", 0) + waves.stats.get("orders_reused", 0)
    print(kernel, waves.stats.get("factor_returns"), orders)
print("compiled:", compiles.names)
"""


def test_a_warm_process_compiles_nothing_for_its_factorizations(tmp_path):
    """numba compiles an objmode block in every process at its first call (the ports
    kernel's SuperLU call measured 0.46 s of CPU): the loops return to Python instead. A
    four-mass chain returns for its sparse factorizations on the ports kernel and for a new
    pivot order on the MNA kernel; once the kernels are cached, a new process compiles
    nothing."""
    from circuitsim.solver import simulate

    circuit = chain_circuit(tmp_path, 4, 0.5)
    for kernel in ("ports", "compiled"):  # the kernels cached (compiled here if they were not)
        simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=kernel))
    with pytest.MonkeyPatch.context() as patch:  # and the SuperLU orders the script takes
        patch.setattr(sparse_order, "OWN_ORDER_LIMIT", 0)
        patch.setattr(sparse_order, "SUPERLU_ORDERS", ("COLAMD",))
        simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="compiled"))
    root = Path(__file__).resolve().parents[2]
    done = subprocess.run(
        [sys.executable, "-c", NO_COMPILE_SCRIPT, str(tmp_path)],
        capture_output=True,
        text=True,
        cwd=root,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    ports, returns, _ = lines[0].split()
    assert ports == "ports" and int(returns) >= 1  # it did return for its factorizations
    compiled, _, orders = lines[1].split()
    assert compiled == "compiled" and int(orders) >= 2  # and for a new pivot order (an
    # earlier one tried from Python, sparse_order.pivot_orders' other order, or SuperLU's)
    assert lines[2] == "compiled: []"
