"""A sweep variant's values do not depend on the machine's speed: its compiled loop returns to
Python after fixed step counts, not after a measured second of work (which made a study's
variants of more than 20,000 steps differ in round-off between runs on a loaded machine)."""

import itertools
from types import SimpleNamespace

import numpy as np
import pytest

from circuitsim.compare.sweep import sweep_circuits
from circuitsim.mechanics import load_model
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.compiled import runner
from circuitsim.solver.variants import simulate_variants
from circuitsim.synthesis.options import SynthesisOptions


def clock(seconds_per_call):
    """A fake perf_counter: each call ``seconds_per_call`` later (a fast or a slow machine)."""
    ticks = itertools.count()
    return lambda: next(ticks) * seconds_per_call


@pytest.fixture(scope="module")
def long_variants():
    """Two wheelset variants past the critical speed, 8 s: more than 20,000 steps each."""
    model = load_model()
    systems = [
        model.system(parameters={"V": v, "a": 0.0, "y0": 0.005}, nonlinear={"flange": True})
        for v in (58.0, 60.0)
    ]
    return sweep_circuits(systems, SynthesisOptions(t_stop=8.0))


# a fast machine (the first chunk's rate is capped: no further return) and a slow one (a
# second of work is a thousand steps: a return every thousand)
FAST, SLOW = 1e-9, 5.0


def set_clock(monkeypatch, seconds_per_call):
    monkeypatch.setattr(runner, "time", SimpleNamespace(perf_counter=clock(seconds_per_call)))


def run(variants, monkeypatch, seconds_per_call):
    set_clock(monkeypatch, seconds_per_call)
    probes = [f"v({variants.scale_map.states['y'].node})"]
    return simulate_variants(variants.circuits, probes, workers=1)


def test_variant_values_do_not_depend_on_the_clock(long_variants, monkeypatch):
    fast = run(long_variants, monkeypatch, FAST)
    slow = run(long_variants, monkeypatch, SLOW)
    for a, b in zip(fast, slow, strict=True):
        assert a.stats["accepted"] + a.stats["rejected"] > runner.FIRST_PAUSE
        np.testing.assert_array_equal(a.time, b.time)
        for name in a.signals:
            np.testing.assert_array_equal(a.signals[name], b.signals[name])


def test_a_single_run_does_not_depend_on_the_clock_either(long_variants, monkeypatch):
    """A single run still pauses by the clock (every second of work, for the wall-time limit
    and Ctrl-C), but a pause no longer restarts the loop's caches: the slow machine's run,
    paused every thousand steps, equals the fast one's bit for bit (before, they differed in
    round-off)."""
    circuit = long_variants.circuits[0]
    # no wall-time limit: the slow clock's 5 s per reading would pass the default 600 s
    # after 120 readings, long before the run's end (the limit reads the same clock)
    options = SimulationOptions.from_circuit(circuit, kernel="ports", max_wall_time=None)
    runs = []
    for seconds in (FAST, SLOW):
        set_clock(monkeypatch, seconds)
        runs.append(simulate(circuit, options))
    a, b = runs
    assert a.stats["accepted"] + a.stats["rejected"] > runner.FIRST_PAUSE + 1000
    np.testing.assert_array_equal(a.time, b.time)
    for name in a.signals:
        np.testing.assert_array_equal(a.signals[name], b.signals[name])
