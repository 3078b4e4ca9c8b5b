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


def test_a_single_run_pauses_by_the_clock_and_differs_in_round_off(long_variants, monkeypatch):
    """What the fixed pauses remove (and that the test above would see it)."""
    circuit = long_variants.circuits[0]
    runs = []
    for seconds in (FAST, SLOW):
        set_clock(monkeypatch, seconds)
        runs.append(simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="ports")))
    node = f"v({long_variants.scale_map.states['y'].node})"
    a, b = runs
    same = a.time.shape == b.time.shape and np.array_equal(a.signals[node], b.signals[node])
    assert not same
    t = np.linspace(0.0, float(min(a.time[-1], b.time[-1])), 2001)
    y = [np.interp(t, w.time, w.signals[node]) for w in runs]
    assert np.max(np.abs(y[0] - y[1])) < 1e-3 * np.max(np.abs(y[0]))  # within tolerance
