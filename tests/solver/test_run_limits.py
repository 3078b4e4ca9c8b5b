"""Step-count and wall-time limits of a transient run: a named error saying where it stopped."""

import subprocess
import sys
import time
from pathlib import Path

import pytest

from circuitsim.netlist.reader import parse_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.errors import CircuitInputError, RunLimitError

ROOT = Path(__file__).resolve().parents[2]
KERNELS = ["python", "ports", "compiled"]

# a diode rectifier: every loop runs it (the compiled kernels need a junction or a charge)
RECTIFIER = """* limits
V1 in 0 SIN(0 1 1k)
R1 in a 1k
D1 a b DX
C1 b 0 1u
.model DX D(is=1e-14)
.tran 10u 10m
.end
"""
# the same with TMAX = 0.2 ms: 50 steps at least (a limit below is refused before the start,
# tests/solver/test_run_guards.py), about 65 attempted
STEPPED = RECTIFIER.replace(".tran 10u 10m", ".tran 1m 10m")


@pytest.mark.parametrize("kernel", KERNELS)
def test_step_limit_stops_with_where_and_what_to_try(kernel):
    circuit = parse_netlist(STEPPED)
    with pytest.raises(RunLimitError, match="more than 50 time steps") as caught:
        simulate(circuit, SimulationOptions(kernel=kernel, max_steps=50))
    error = caught.value
    assert error.limit == "max_steps" and error.tstop == 10e-3
    assert 0 < error.time < 10e-3  # where it stopped
    assert "of 0.01 s" in str(error) and "--max-steps" in str(error)


@pytest.mark.parametrize("kernel", KERNELS)
def test_wall_time_limit_stops_the_run(kernel):
    circuit = parse_netlist(RECTIFIER)
    simulate(circuit, SimulationOptions(kernel=kernel))  # kernels loaded: time the run only
    with pytest.raises(RunLimitError, match="longer than 1e-09 s of wall time") as caught:
        simulate(circuit, SimulationOptions(kernel=kernel, max_wall_time=1e-9))
    assert caught.value.limit == "max_wall_time"
    assert 0 <= caught.value.time < 10e-3
    assert "--max-wall-time" in str(caught.value)


def test_limits_are_validated_and_not_read_from_the_netlist():
    with pytest.raises(CircuitInputError, match="max_wall_time"):
        SimulationOptions(max_wall_time=0)
    with pytest.raises(CircuitInputError, match="max_steps"):
        SimulationOptions(max_steps=0)
    circuit = parse_netlist(RECTIFIER.replace(".end", ".options max_steps=5\n.end"))
    assert SimulationOptions.from_circuit(circuit).max_steps == 2_000_000


def test_cli_limit_option_names_the_file_and_where_it_stopped(tmp_path):
    netlist = tmp_path / "rect.cir"
    netlist.write_text(STEPPED)
    result = subprocess.run(
        [sys.executable, "-m", "circuitsim", "simulate", str(netlist), "--max-steps", "55"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert result.returncode == 3  # the run failed (cli/__init__.py's exit codes)
    assert "rect.cir: more than 55 time steps attempted: stopped at t = " in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize("kernel", ["ports", "compiled"])
def test_the_kernel_compile_does_not_count_against_the_wall_time_limit(kernel, monkeypatch):
    """A first run on a cold cache compiles for minutes on a loaded machine: the compile's
    time (here a stand-in: the first call of the loop made 0.5 s longer, announced as a
    compile) extends the deadline, so a 0.3 s limit stops only the run's own work."""
    from circuitsim.solver.compiled import runner

    circuit = parse_netlist(RECTIFIER)
    simulate(circuit, SimulationOptions(kernel=kernel))  # kernels loaded
    real_loop_state = runner._loop_state

    class SlowFirstCall:
        def __init__(self, loop):
            self._loop, self._calls = loop, 0

        def __getattr__(self, name):
            return getattr(self._loop, name)

        def run(self, *args):
            self._calls += 1
            if self._calls == 1:
                time.sleep(0.5)
            return self._loop.run(*args)

    def loop_state(*args, **kwargs):
        loop, st, mid = real_loop_state(*args, **kwargs)
        return SlowFirstCall(loop), st, mid

    monkeypatch.setattr(runner, "_loop_state", loop_state)
    monkeypatch.setattr(runner, "_announce_compile", lambda kind, dispatcher, helpers=0: True)
    monkeypatch.setattr(runner, "record_compile_seconds", lambda kind, seconds: None)
    result = simulate(circuit, SimulationOptions(kernel=kernel, max_wall_time=0.3))
    assert result.time[-1] == pytest.approx(10e-3)
