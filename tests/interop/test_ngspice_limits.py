"""The builtin engine's guards on the ngspice path: refused before ngspice starts, progress
while it runs, results that are not finite refused."""

import numpy as np
import pytest

from circuitsim.interop import ngspice as ngspice_module
from circuitsim.interop.ngspice import RunLimits, run_ngspice
from circuitsim.interop.ngspice_limits import tran_times
from circuitsim.solver.errors import CircuitInputError, NonFiniteError, RunSizeError
from circuitsim.solver.recording import check_finite
from tests.conftest import requires_ngspice
from tests.solver.test_run_guards import ladder


def _never_started(*args, **kwargs):
    raise AssertionError("ngspice was started")


@pytest.mark.parametrize(
    "tran, error, words",
    [
        (".tran 1e-30 1e-6", CircuitInputError, "resolution of time"),
        (".tran 1u 1e6", RunSizeError, "at least 1e+12 time steps"),
        (".tran 1n 1", RunSizeError, "at least 1e+09 time steps"),
    ],
)
def test_refused_before_ngspice_starts(monkeypatch, tran, error, words):
    monkeypatch.setattr(ngspice_module, "run_with_limit", _never_started)
    monkeypatch.setattr(ngspice_module.shutil, "which", lambda name: "/usr/bin/ngspice")
    with pytest.raises(error, match=words.replace("+", "\\+")):
        run_ngspice(ladder(2, tran))


def test_memory_refused_before_ngspice_starts(monkeypatch):
    monkeypatch.setattr(ngspice_module, "run_with_limit", _never_started)
    monkeypatch.setattr(ngspice_module.shutil, "which", lambda name: "/usr/bin/ngspice")
    # 1e6 + 1 points of 100 signals and the time: 808 MB
    limits = RunLimits(max_memory=500e6, signals=100)
    with pytest.raises(RunSizeError, match="808 MB") as caught:
        run_ngspice(ladder(2, ".tran 1u 1"), limits=limits)
    assert caught.value.limit == "max_memory" and "--max-memory" in str(caught.value)


def test_tran_card_read_from_the_deck():
    assert tran_times(["R1 a 0 1k", ".TRAN 1u 20 0 2u UIC"]) == (1e-6, 20.0, 0.0, 2e-6)
    assert tran_times([".tran 10m 1"]) == (0.01, 1.0, 0.0, None)
    assert tran_times([".tran {step} 1"]) is None  # ngspice evaluates parameters
    assert tran_times(["R1 a 0 1k"]) is None


def test_results_that_are_not_finite_are_refused():
    time = np.linspace(0, 1, 5)
    signals = {"v(a)": np.array([1.0, 2, 3, 4, 5]), "v(b)": np.array([0.0, 1, np.inf, 1, 0])}
    with pytest.raises(NonFiniteError, match="v\\(b\\) = inf at t = 0.5 s") as caught:
        check_finite(signals, time)
    assert caught.value.last == 1.0
    check_finite({"v(a)": signals["v(a)"]}, time)  # finite: no error


@requires_ngspice
def test_progress_and_size_reported_while_ngspice_runs():
    lines: list[str] = []
    limits = RunLimits(progress=lines.append, report_every=0.05)
    waves = run_ngspice(ladder(20, ".tran 1u 0.2"), limits=limits)
    assert len(waves.time) > 2e5  # 0.2 s in steps of at most 1 us
    assert lines[0].startswith("ngspice run size: at least 2e+05 time steps")
    running = [line for line in lines if line.startswith("ngspice: running for")]
    assert running, lines  # ngspice takes seconds for this
    assert waves.stats["peak_memory_bytes"] > 0


def test_watch_reports_and_stops_past_the_budget():
    import os

    from circuitsim.interop.ngspice_limits import RunWatch, process_memory
    from circuitsim.solver.errors import MemoryBudgetError

    lines: list[str] = []
    resident = process_memory(os.getpid())
    watch = RunWatch(None, 1.0, lines.append, report_every=10.0)
    watch(os.getpid(), 5.0)
    watch(os.getpid(), 10.5)
    assert lines == [lines[0]] and lines[0].startswith("ngspice: running for 10 s")
    assert watch.peak >= resident / 2
    tight = RunWatch(resident / 4, 1.0, None)
    tight.cap = 0  # no address-space cap on this test's own process
    with pytest.raises(MemoryBudgetError, match="ngspice's resident memory reached"):
        tight(os.getpid(), 1.0)
