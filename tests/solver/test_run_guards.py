"""Run guards of the builtin engine: diverged results fail (NonFiniteError), the memory budget
refuses or stops a run (RunSizeError, MemoryBudgetError), the run's size is said before it."""

import math

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.netlist.reader import parse_netlist
from circuitsim.netlist.run_size import RunSize, default_memory_budget, physical_memory
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.errors import (
    CircuitInputError,
    MemoryBudgetError,
    NonFiniteError,
    RunSizeError,
)
from circuitsim.solver.recording import first_non_finite

KERNELS = ["python", "ports", "compiled"]

# dv/dt = +v / tau: G1 drives gm * v(a) into node a (SPICE: from n+ = 0 through G1 to n- = a)
GROWTH = """* diverging capacitor
C1 a 0 1u IC=1
G1 0 a a 0 1m
.tran 1m 1 uic
.end
"""


def overflow_time(tau: float, h: float) -> float:
    """When v' = v / tau from v(0) = 1, stepped by h (one backward Euler step, then the
    trapezoidal rule, as a fixed-step run with maxord 2 does), first overflows, s."""
    v = 1.0 / (1.0 - h / tau)
    growth = (1.0 + h / (2 * tau)) / (1.0 - h / (2 * tau))
    steps = 1
    with np.errstate(over="ignore"):
        while math.isfinite(v):
            v = float(np.float64(v) * growth)
            steps += 1
    return steps * h


@pytest.mark.parametrize("kernel", KERNELS)
def test_diverging_circuit_stops_naming_the_signal_and_time(kernel):
    h = 1e-4
    options = SimulationOptions(kernel=kernel, fixed_step=h)
    with pytest.raises(NonFiniteError) as caught:
        simulate(parse_netlist(GROWTH), options)
    error = caught.value
    assert error.signal == "v(a)"
    assert not math.isfinite(error.value)
    assert abs(error.time - overflow_time(1e-3, h)) <= 1.5 * h  # 0.7092 s
    assert "v(a)" in str(error) and "diverged" in str(error)


def test_diverging_circuit_fails_through_the_cli(tmp_path, capsys):
    netlist = tmp_path / "grow.cir"
    netlist.write_text(GROWTH)
    out = tmp_path / "grow.csv"
    assert main(["simulate", str(netlist), "--csv", str(out)]) == 3
    assert not out.exists()  # no file of inf/NaN rows


def test_first_non_finite_finds_the_first_bad_row():
    table = np.ones((1000, 7))
    assert first_non_finite(table) is None
    table[613, 4] = np.nan
    table[900, 0] = np.inf
    assert first_non_finite(table) == 613
    assert first_non_finite(table, 614) == 900
    big = np.full((10, 3), 1e308)  # finite values whose sum overflows: not a failure
    assert first_non_finite(big) is None


def ladder(nodes: int, tran: str) -> str:
    """An RC ladder of ``nodes`` nodes driven by a 1 kHz sine: its steps are set by the
    truncation error, far below TMAX for a long tstep."""
    lines = ["* ladder", "V1 n0 0 SIN(0 1 1k)"]
    for i in range(nodes):
        lines += [f"R{i + 1} n{i} n{i + 1} 1k", f"C{i + 1} n{i + 1} 0 10n"]
    return "\n".join([*lines, tran, ".end"]) + "\n"


def test_run_past_the_memory_budget_is_refused_before_it_starts():
    circuit = parse_netlist(ladder(20, ".tran 1u 1"))
    signals = 20 + 1  # the 20 ladder nodes and n0 (n0 is a node too)
    signals += 1  # i(v1)
    points = 1e6 + 1  # tstop / TMAX and t = 0
    needed = points * (signals + 1) * 8
    with pytest.raises(RunSizeError) as caught:
        simulate(circuit, SimulationOptions(max_memory=needed / 2))
    error = caught.value
    assert error.limit == "max_memory"
    assert f"{needed / 1e6:.3g} MB" in str(error)
    assert "--probe" in str(error) and "--max-memory" in str(error)
    # recording one signal fits: the same budget lets the run start (refused only by size)
    size = RunSize.of(1e-6, 1.0, signals=1)
    assert size.recorded_bytes < needed / 2


def test_run_past_the_step_limit_is_refused_before_it_starts():
    circuit = parse_netlist(ladder(2, ".tran 1m 1"))  # 1000 steps at least
    with pytest.raises(RunSizeError, match="at least 1e\\+03 time steps") as caught:
        simulate(circuit, SimulationOptions(max_steps=999))
    assert caught.value.limit == "max_steps"
    with pytest.raises(RunSizeError, match="1e\\+12 time steps"):
        simulate(parse_netlist(ladder(2, ".tran 1u 1e6")))
    with pytest.raises(CircuitInputError, match="resolution of time"):
        simulate(parse_netlist(ladder(2, ".tran 1e-30 1e-6")))


@pytest.mark.parametrize("kernel", KERNELS)
def test_recorder_stops_at_the_memory_budget(kernel):
    # at least 21 points by TMAX; about 1,800 by the truncation error
    circuit = parse_netlist(ladder(20, ".tran 10m 0.2"))
    full = simulate(circuit, SimulationOptions(kernel="ports"))
    columns = len(full.signals)  # every signal is an unknown here
    budget = 300 * (columns + 1) * 8  # 300 points' worth
    assert len(full.time) > 1000
    with pytest.raises(MemoryBudgetError) as caught:
        simulate(circuit, SimulationOptions(kernel=kernel, max_memory=budget))
    error = caught.value
    assert error.limit == "max_memory" and 0 < error.time < 0.2
    assert error.held <= budget
    assert error.steps * (columns + 1) * 8 <= budget
    assert "--max-memory" in str(error)


def test_default_budget_is_half_the_physical_memory():
    total = physical_memory()
    assert total is not None and total > 0
    assert default_memory_budget() == total // 2
    assert SimulationOptions().max_memory == default_memory_budget()
    with pytest.raises(CircuitInputError, match="max_memory"):
        SimulationOptions(max_memory=0)


def test_cli_prints_the_size_before_the_run(tmp_path, capsys):
    netlist = tmp_path / "l.cir"
    netlist.write_text(ladder(3, ".tran 1m 10m"))
    assert main(["simulate", str(netlist), "--max-memory", "2G"]) == 0
    err = capsys.readouterr().err
    # TMAX = min(tstep, tstop / 50) = 0.2 ms: 50 steps; 5 signals (n0..n3, i(v1)) and the
    # time, 8 bytes each
    assert "run size: at least 50 time steps" in err
    assert "51 points x 48 bytes" in err and "budget 2 GB" in err


def test_cli_max_memory_refuses_and_is_validated(tmp_path, capsys):
    netlist = tmp_path / "l.cir"
    netlist.write_text(ladder(3, ".tran 1u 1"))
    assert main(["simulate", str(netlist), "--max-memory", "10M"]) == 3
    assert "above the memory budget of 10 MB" in capsys.readouterr().err
    assert main(["simulate", str(netlist), "--max-memory", "lots"]) == 2
    assert "--max-memory" in capsys.readouterr().err


def test_guard_errors_survive_a_trip_between_processes():
    import pickle

    errors = [
        RunSizeError("max_memory", 1e9, 20.0, "the recorded results need at least 39.5 GB"),
        MemoryBudgetError(3e7, 3.6, 20.0, 32800, 2.7e7, "record fewer signals"),
        NonFiniteError("v(a)", 0.7092, float("inf"), 1.65e308),
    ]
    for error in errors:
        again = pickle.loads(pickle.dumps(error))
        assert type(again) is type(error) and str(again) == str(error)
