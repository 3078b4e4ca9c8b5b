"""A compiled loop's pauses (its returns to Python to check the wall-time limit and Ctrl-C,
after a number of attempted steps sized from the measured rate, so after a machine-dependent
number) must not change the run: a run paused every hundred attempts equals one that never
pauses, bit for bit, on both compiled kernels. Before, every return restarted the ports loop's
caches (H ieq, the recorded unknowns' junction part), which moved the results in round-off
(about 1e-12 V on the wheelset) by the machine's load."""

from __future__ import annotations

import numpy as np
import pytest

from circuitsim.solver import SimulationOptions, simulate
from tests.solver.test_compiled_chain import chain_circuit

pytest.importorskip("numba")


@pytest.mark.parametrize(
    "kernel, masses", [("ports", 1), ("ports", 2), ("ports", 4), ("compiled", 4)]
)
def test_a_run_paused_every_hundred_attempts_equals_an_unpaused_run(
    tmp_path, monkeypatch, kernel, masses
):
    from circuitsim.solver.compiled import runner

    circuit = chain_circuit(tmp_path, masses, 2.0)
    options = SimulationOptions.from_circuit(circuit, kernel=kernel)
    monkeypatch.setattr(runner, "FIRST_PAUSE", 10**9)
    whole = simulate(circuit, options)
    monkeypatch.setattr(runner, "FIRST_PAUSE", 37)
    monkeypatch.setattr(runner, "PAUSE_SECONDS", 0.0)  # then every 100 attempts
    paused = simulate(circuit, options)
    assert paused.stats["kernel"] == whole.stats["kernel"] == kernel
    assert paused.stats["accepted"] == whole.stats["accepted"]
    assert np.array_equal(paused.time, whole.time)
    for name, values in whole.signals.items():
        assert np.array_equal(paused.signals[name], values), name
