"""The bench's clock (BenchRunner) on a library session: held at a model time asked for
(``until``), however fast it may run, and the refused values."""

import threading
import time

import pytest

from circuitsim.bench.api import state_of
from circuitsim.bench.errors import BenchError
from circuitsim.bench.runner import BenchRunner
from circuitsim.bench.session import BenchSession
from circuitsim.solver.errors import ConvergenceError
from tests.bench.test_session import wheelset_setup


def wait_until_held(runner: BenchRunner, patience: float = 240.0) -> None:
    deadline = time.monotonic() + patience
    while runner.running:
        assert runner.error is None, runner.error
        assert time.monotonic() < deadline, "the clock was not held"
        time.sleep(0.05)


def test_an_unthrottled_clock_is_held_at_the_chunk_boundary_asked_for():
    session = BenchSession(wheelset_setup(), chunk=0.1)
    runner = BenchRunner(session, rate=float("inf"), running=False).start()
    try:
        time.sleep(0.3)
        assert session.t == 0.0 and session.steps == 0  # started held: nothing ran
        runner.set_until(0.45)  # not a boundary: held at the first one past it
        runner.resume()
        wait_until_held(runner)
        assert session.steps == 5 and session.t == pytest.approx(0.5, abs=1e-12)
        time.sleep(0.3)  # unthrottled, yet it stays there
        assert session.steps == 5 and not runner.running and runner.until is None
        runner.set_until(0.7)
        runner.resume()
        wait_until_held(runner)
        assert session.steps == 7
        runner.set_until(0.2)  # already past: held where it is
        runner.resume()
        wait_until_held(runner)
        assert session.steps == 7
    finally:
        runner.stop()


@pytest.fixture(scope="module")
def held_runner():
    return BenchRunner(BenchSession(wheelset_setup(), chunk=0.1), running=False)


@pytest.mark.parametrize("until", ["1", True, float("nan"), float("inf")])
def test_until_must_be_a_finite_number(held_runner, until):
    runner = held_runner
    with pytest.raises(BenchError, match="until must be a finite number"):
        runner.set_until(until)
    assert runner.until is None


def test_the_state_is_read_while_a_chunk_is_computed(held_runner):
    """/api/state answers from the state before the chunk instead of waiting for it (a first
    chunk that compiles the kernels took longer than the API test's 60 s request timeout)."""
    session = held_runner.session
    computing, release = threading.Event(), threading.Event()
    run = session.circuit.run

    def slow_run(*args):
        computing.set()
        release.wait(60)
        return run(*args)

    session.circuit.run = slow_run
    chunk = threading.Thread(target=session.step)
    chunk.start()
    try:
        assert computing.wait(60)
        answers = []
        reader = threading.Thread(target=lambda: answers.append(state_of(held_runner)))
        reader.start()
        reader.join(10)
        assert answers and answers[0]["t"] == 0.0 and answers[0]["state"]["y"] == 0.0
    finally:
        release.set()
        chunk.join(60)
        session.circuit.run = run
    assert session.t == pytest.approx(0.1, abs=1e-12)
    assert state_of(held_runner)["t"] == session.t


def test_a_failed_chunk_says_its_model_time(held_runner):
    """The engine's t counts from the chunk's start; the CI failure's t = 0.0670958 s was read
    as the first chunk's, where it was chunk 537's (model time 53.7 s)."""
    session = held_runner.session
    run = session.circuit.run

    def failing_run(*args):
        raise ConvergenceError("time step too small", time=0.0670958, step=2.18e-15)

    session.circuit.run = failing_run
    runner = BenchRunner(session, rate=float("inf"))
    runner.set_until(session.t + 1.0)
    t0 = session.t
    runner.start()
    try:
        deadline = time.monotonic() + 60
        while runner.error is None:
            assert time.monotonic() < deadline
            time.sleep(0.05)
    finally:
        runner.stop()
        session.circuit.run = run
    assert runner.error.startswith(
        f"ConvergenceError in the chunk from model time {t0:.6g} s to {t0 + 0.1:.6g} s"
    )
    assert "at t = 0.0670958 s" in runner.error and not runner.running
    assert session.t == t0  # the session keeps the state before the chunk


def test_an_overload_stops_the_clock_and_resume_goes_on_after_a_push():
    session = BenchSession(wheelset_setup(57.0), chunk=0.1)
    session.set_state({"y": 12.0 / session.scale_map.states["y"].volts_per_unit})
    runner = BenchRunner(session, rate=float("inf")).start()
    try:
        deadline = time.monotonic() + 240.0
        while runner.error is None:
            assert time.monotonic() < deadline, "no overload"
            time.sleep(0.05)
        assert "Overload" in runner.error and "swing" in runner.error
        assert not runner.running
        t = session.t
        session.set_state({"y": 0.005, "psi": 0.0, "y_dot": 0.0, "psi_dot": 0.0})
        runner.set_until(t + 0.3)
        runner.resume()  # the error is cleared: the refused chunk runs from the push
        wait_until_held(runner)
        assert session.t == pytest.approx(t + 0.3, abs=1e-9)
    finally:
        runner.stop()
