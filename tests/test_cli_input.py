"""``--input NAME=FILE.csv``: a forcing group's input given as a time series on the command line.

The lag x' = -a x + u(t) with the model file's own step (3 at 0.3 s) has the closed form
x = (3/a)(1 - exp(-a (t - 0.3))) after the step; the same step written as a CSV profile
(two points at 0.3 s make the jump) and given with --input must give that solution too.
"""

import csv

import numpy as np
import pytest

from circuitsim.cli import main
from tests.mechanics.test_forcing_inputs import FIRST_ORDER

# x' = -a x + u(t) (a = 3 /s), with a step of 3 at 0.3 s as the model file's own input
LAG = (
    FIRST_ORDER
    + """
[forcing.push]
kind = "step"
amplitude = 3.0
start = 0.3
enters = { x = 1 }
"""
)

# the model's step as a time series: two points at 0.3 s, the jump
STEP_CSV = "time_s,force_N\n0, 0\n0.3, 0\n0.3, 3\n5, 3\n"


def closed_form(t):
    return np.where(t > 0.3, 3.0 / 3.0 * (1 - np.exp(-3.0 * (t - 0.3))), 0.0)


def ode_x(argv, out):
    assert main(["ode", *argv, "--tstop", "2", "--dt", "0.0025", "--csv", str(out)]) == 0
    with open(out, newline="") as handle:
        rows = list(csv.reader(handle))
    header, data = rows[0], np.array(rows[1:], dtype=float)
    return data[:, 0], data[:, header.index(next(h for h in header if h.startswith("x")))]


@pytest.fixture
def model(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # --input names are relative to the working directory
    path = tmp_path / "lag.toml"
    path.write_text(LAG)
    return path


def test_a_csv_step_equals_the_model_files_step(model, tmp_path):
    (tmp_path / "step.csv").write_text(STEP_CSV)
    t, own = ode_x(["--model", str(model)], tmp_path / "own.csv")
    t_csv, given = ode_x(["--model", str(model), "--input", "push=step.csv"], tmp_path / "g.csv")
    np.testing.assert_array_equal(t, t_csv)
    assert np.max(np.abs(own - closed_form(t))) < 1e-8
    assert np.max(np.abs(given - closed_form(t))) < 1e-8


def test_a_csv_input_replaces_the_step(model, tmp_path):
    # twice the force from the file: the solution doubles (the file, not the model's step)
    (tmp_path / "double.csv").write_text("0,0\n0.3,0\n0.3,6\n5,6\n")
    t, x = ode_x(["--model", str(model), "--input", "push=double.csv"], tmp_path / "d.csv")
    assert np.max(np.abs(x - 2 * closed_form(t))) < 1e-8


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("0,0\n0.3,0,1\n1,1\n", "bad.csv line 2: expected two columns (time, value), got 3"),
        ("0,0\n0.5,x\n", "bad.csv line 2: expected a number, got 'x'"),
        ("0,0\n0.5,1\n0.4,1\n", "bad.csv line 3: time 0.4 is before the previous 0.5"),
    ],
)
def test_a_bad_file_is_one_line_naming_it(model, tmp_path, capsys, text, message):
    (tmp_path / "bad.csv").write_text(text)
    assert main(["ode", "--model", str(model), "--input", "push=bad.csv"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err
    assert err.endswith(f"--input push=bad.csv: {message}"), err


def test_a_missing_file_or_group_is_named(model, tmp_path, capsys):
    assert main(["ode", "--model", str(model), "--input", "push=none.csv"]) == 2
    err = capsys.readouterr().err
    assert "error: --input push=none.csv: " in err
    assert f"{tmp_path / 'none.csv'}: file not found" in err
    assert main(["ode", "--model", str(model), "--input", "road=none.csv"]) == 2
    assert "--input road: model lag has no forcing group 'road' (known: push)" in (
        capsys.readouterr().err
    )
    with pytest.raises(SystemExit) as stopped:  # argparse's usage error
        main(["ode", "--model", str(model), "--input", "push"])
    assert stopped.value.code == 2
    assert "expected NAME=FILE.csv, got 'push'" in capsys.readouterr().err
