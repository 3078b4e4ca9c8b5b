"""The ports kernel's return to Python for a factorization (newton.FACTOR): above SPARSE_FROM
unknowns SuperLU factors in Python and the loop goes on where it stopped, bit for bit.

Forced on a circuit small enough for the compiled dense factorization (the same arithmetic
either way), a run that returns for every refactor must give exactly the steps and values of
the run that makes them inside the loop. Both run with fixed pauses: the loop's other returns
(every ~1 s of work by default) restart its local caches, which moves round-off."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from circuitsim.solver import SimulationOptions
from circuitsim.solver.engine import build_system
from tests.solver.test_compiled_chain import chain_circuit

pytest.importorskip("numba")


def test_a_run_that_returns_for_its_factorizations_takes_the_same_steps(tmp_path, monkeypatch):
    from circuitsim.solver.compiled import newton, ports_start, run_ports_from, runner

    circuit = chain_circuit(tmp_path, 1, 5.0)  # 42 unknowns: dense
    system = build_system(circuit, SimulationOptions.from_circuit(circuit, kernel="ports"))
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
    assert returned["factor_returns"] == inside["factorizations"] - 1
    # measured: one refactor at the step's refactor test, one before a second Newton attempt
    assert resumed_at[newton.AT_REFACTOR_TEST] >= 1
    assert resumed_at[newton.AT_SECOND_ATTEMPT] >= 1
    for key in ("accepted", "rejected", "newton_iterations", "factorizations", "configurations"):
        assert returned[key] == inside[key], key
    assert np.array_equal(times_returned, times)
    assert np.array_equal(values_returned, values)
