"""The direct solution ends: a step-count and a wall-time limit, each a named error saying at
what model time it stopped and what to try (issue 21: `ode --freq 1e9 --tstop 1` ran for ever)."""

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.mechanics import IntegrationError, load_model, solve
from circuitsim.mechanics.errors import IntegrationLimitError
from circuitsim.mechanics.limits import MAX_STEPS, MAX_WALL_TIME


@pytest.fixture(scope="module")
def wheelset():
    return load_model()


def test_a_forcing_that_needs_more_steps_than_allowed_is_refused_before_the_start(wheelset):
    system = wheelset.system(parameters={"f": 1e9})
    with pytest.raises(IntegrationLimitError) as caught:
        solve(system, (0.0, 1.0))
    error = caught.value
    assert (error.time, error.steps, error.limit) == (0.0, 0, "steps")
    assert "1e+09 Hz needs at least 1e+09 steps" in str(error)
    assert "--max-steps" in str(error)


def test_the_step_limit_stops_the_run_and_says_where(wheelset):
    # 50 Hz over 1 s passes the one-step-per-period bound (50 <= 300) but needs ~8 steps per
    # period at rtol 1e-10: the limit stops it part way
    system = wheelset.system(parameters={"f": 50.0})
    with pytest.raises(IntegrationLimitError) as caught:
        solve(system, (0.0, 1.0), max_steps=300)
    error = caught.value
    assert error.limit == "steps" and error.steps == 301
    assert 0.0 < error.time < 1.0
    assert f"stopped at t = {error.time:.6g} s of 1 s after 300 steps" in str(error)
    assert isinstance(error, IntegrationError)  # callers handling IntegrationError still do


def test_the_wall_time_limit_stops_the_run(wheelset):
    system = wheelset.system(parameters={"f": 1e4})
    with pytest.raises(IntegrationLimitError) as caught:
        solve(system, (0.0, 1.0), max_wall_time=0.2)
    error = caught.value
    assert error.limit == "time" and 0.0 < error.time < 1.0
    assert "of wall time (the limit: 0.2 s" in str(error) and "--max-wall-time" in str(error)


def test_no_limit_changes_a_run_within_them(wheelset):
    system = wheelset.system()
    limited = solve(system, (0.0, 1.0))
    free = solve(system, (0.0, 1.0), max_steps=None, max_wall_time=None)
    assert limited.t.tolist() == free.t.tolist()
    assert (limited.x == free.x).all()


@pytest.mark.parametrize("bad", [{"max_steps": 0}, {"max_wall_time": -1.0}, {"method": "Euler"}])
def test_bad_limits_and_methods_are_refused(wheelset, bad):
    with pytest.raises(IntegrationError):
        solve(wheelset.system(), (0.0, 0.1), **bad)


def test_the_cli_stops_with_exit_code_3_and_one_line(capsys):
    assert main(["ode", "--freq", "1e9", "--tstop", "1"]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("circuitsim ode: error: not started: the forcing")
    assert main(["ode", "--freq", "100", "--tstop", "1", "--max-steps", "300"]) == 3
    assert "after 300 steps (the step limit" in capsys.readouterr().err
    assert main(["ode", "--freq", "1e4", "--tstop", "1", "--max-wall-time", "0.2"]) == 3
    assert "(the limit: 0.2 s" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv", [["--max-steps", "0"], ["--max-wall-time", "0"], ["--max-wall-time", "nan"]]
)
def test_bad_limit_options_are_usage_errors(argv, capsys):
    assert main(["ode", "--tstop", "0.1", *argv]) == 2
    assert argv[0] in capsys.readouterr().err


def test_the_help_states_the_library_defaults(capsys):
    with pytest.raises(SystemExit):
        main(["ode", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"(default {MAX_STEPS:,})" in text and f"(default {MAX_WALL_TIME:g} s)" in text


def test_states_that_overflow_end_in_a_named_error(tmp_path):
    # x' = 700 x from 1: exp(700 t) passes the float range near t = 1 s; a NaN derivative once
    # made scipy step on for ever with a NaN step size
    path = tmp_path / "up.toml"
    path.write_text(
        '[model]\nname = "up"\nkind = "first_order"\n[states]\nnames = ["x"]\n'
        "[matrices]\nA = [[700]]\n[initial]\nx = 1\n"
    )
    with pytest.raises(IntegrationError, match="the derivative is not finite at t = ") as caught:
        with np.errstate(all="ignore"):
            solve(load_model(path).system(), (0.0, 2.0))
    assert "the model overflows" in str(caught.value)
