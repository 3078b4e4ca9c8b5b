"""``--max-step`` on the verbs that solve the ODE directly: ode, compare, tolerance, hunting.

Each verb refuses a step that is not positive and finite (exit 2, naming the option) and
hands the value to the direct solver. ``ode`` and ``hunting`` run for real (the ODE only);
``compare`` and ``tolerance`` simulate circuits first, so there the call into the library
is caught and checked instead.
"""

import sys

import numpy as np
import pytest

import circuitsim.compare.case
import circuitsim.studies.tolerance
from circuitsim.cli import main
from circuitsim.mechanics import load_model
from circuitsim.mechanics.errors import IntegrationError

VERBS = ["ode", "compare", "tolerance", "hunting"]


@pytest.mark.parametrize("verb", VERBS)
@pytest.mark.parametrize("value", ["0", "-1e-3", "nan", "inf"])
def test_a_step_that_is_not_positive_and_finite_is_refused(verb, value, tmp_path, capsys):
    argv = [verb, f"--max-step={value}"]
    if verb in ("tolerance", "hunting"):
        argv += ["--out", str(tmp_path / "out")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--max-step must be a positive finite number" in err
    assert "Traceback" not in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("verb", VERBS)
def test_help_gives_the_unit(verb, capsys):
    with pytest.raises(SystemExit):
        main([verb, "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "--max-step SECONDS" in out
    assert "largest step of the direct ODE solution, in the model's time unit" in out


def _steps(out: str) -> int:
    line = next(line for line in out.splitlines() if " steps, " in line)
    return int(line.split(" steps, ")[0].split()[-1])


def test_ode_max_step_bounds_the_steps(tmp_path, capsys):
    loose, tight = tmp_path / "loose.csv", tmp_path / "tight.csv"
    assert main(["ode", "--tstop", "1", "--csv", str(loose)]) == 0
    free = _steps(capsys.readouterr().out)
    assert main(["ode", "--tstop", "1", "--max-step", "0.001", "--csv", str(tight)]) == 0
    out = capsys.readouterr().out
    # at most 1 ms a step: at least 1000 solver points over 1 s, far more than the default's
    assert _steps(out) >= 1000 > 2 * free
    # the same trajectory to the tolerance (the CSV's 10 digits)
    a = np.loadtxt(loose, delimiter=",", skiprows=1)
    b = np.loadtxt(tight, delimiter=",", skiprows=1)
    assert np.max(np.abs(a - b) / np.ptp(a, axis=0)) < 1e-7


class _Caught(IntegrationError):
    """Raised by a stand-in after it recorded its call (the CLI exits 3)."""


def test_compare_passes_max_step_to_the_direct_solution(monkeypatch, capsys):
    calls = []

    def run_case(system, *args, **kwargs):
        calls.append(kwargs)
        raise _Caught("stand-in for run_case")

    monkeypatch.setattr(circuitsim.compare.case, "run_case", run_case)
    assert main(["compare", "--max-step", "0.0005"]) == 3
    assert calls[0]["max_step"] == 0.0005
    assert "stand-in for run_case" in capsys.readouterr().err


def test_reference_traces_solves_with_max_step(monkeypatch):
    import circuitsim.mechanics as mechanics

    real, steps = mechanics.solve, []

    def solve(system, **kwargs):
        steps.append(kwargs.get("max_step"))
        return real(system, **kwargs)

    monkeypatch.setattr(mechanics, "solve", solve)
    system = load_model("wheelset").system(parameters={"f": 3.0})
    result, traces = circuitsim.compare.case.reference_traces(system, 0.2, max_step=0.001)
    assert steps == [0.001]
    assert np.max(np.diff(result.t)) <= 0.001 * (1 + 1e-12)
    assert set(traces) == set(system.states)


def test_tolerance_passes_max_step_to_the_study(monkeypatch, tmp_path, capsys):
    calls = []

    def run_tolerance(*args, **kwargs):
        calls.append(kwargs)
        raise _Caught("stand-in for run_tolerance")

    monkeypatch.setattr(circuitsim.studies.tolerance, "run_tolerance", run_tolerance)
    argv = ["tolerance", "-n", "1", "--max-step", "0.001", "--out", str(tmp_path / "t")]
    assert main(argv) == 3
    assert calls[0]["max_step"] == 0.001


def test_hunting_solves_every_step_with_max_step(monkeypatch, tmp_path, capsys):
    module = sys.modules["circuitsim.mechanics.solve"]  # the name is also the function's
    real, steps = module.solve, []

    def solve(system, span, **kwargs):
        steps.append(kwargs.get("max_step"))
        return real(system, span, **kwargs)

    monkeypatch.setattr(module, "solve", solve)
    argv = ["hunting", "--speeds", "50,51", "--settle", "0.2", "--record", "0.1", "--flange",
            "--no-circuit", "--max-step", "0.003", "--out", str(tmp_path)]  # fmt: skip
    assert main(argv) == 0, capsys.readouterr().err
    assert steps and set(steps) == {0.003}


def test_a_max_step_needing_more_steps_than_the_limit_is_refused_at_once(capsys):
    # 1 ns over 5 s is 5e9 steps: refused before the start (exit 3), not after 500,000
    assert main(["ode", "--max-step", "1e-9"]) == 3
    err = capsys.readouterr().err
    assert "not started: max_step 1e-09 s needs at least 5e+09 steps" in err
    assert main(["ode", "--max-step", "1e-320"]) == 3
    assert "needs at least 1e300 steps" in capsys.readouterr().err
