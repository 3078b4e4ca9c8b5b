"""Every verb on the state the user names: a 2-DOF model whose first coordinate is a plain
stable oscillator and whose second, y, loses its damping with the speed (c_y = c0 (1 - V/50)).
``hunting --state y`` (or ``[options] state``, or ``[options] y0`` with ``[initial]``) pushes
and measures y; the amplitudes are checked against the equations typed again here and solved
with scipy step by step with the same continuation."""

import csv
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from circuitsim.cli import main

M_Y, K_Y, C0 = 2.0, 2.0 * (2 * math.pi * 1.5) ** 2, 0.8  # kg, N/m, N s/m
MODEL = """
[model]
name = "second_state"
kind = "second_order"
[coordinates]
names = ["x", "y"]
units = ["m", "m"]
[parameters]
V = {{ value = 40.0, unit = "m/s" }}
m_x = 1.0
k_x = 400.0
c_x = 4.0
m_y = {m}
k_y = {k}
c_y = {{ value = "{c0}*(1 - V/50)" }}
y0 = {{ value = 0.0, unit = "m" }}
[options]
speed = "V"
{options}
[matrices]
M = [["m_x", 0], [0, "m_y"]]
C = [["c_x", 0], [0, "c_y"]]
K = [["k_x", 0], [0, "k_y"]]
{initial}
"""


def write_model(tmp_path, options="", initial="", name="m.toml"):
    path = tmp_path / name
    path.write_text(MODEL.format(m=M_Y, k=K_Y, c0=C0, options=options, initial=initial))
    return str(path)


def reference_amplitudes(speeds, push, settle=1.0, record=1.0):
    """max |y| over each step's record window, each step from the last one's end (strict
    continuation: --repush 0), up then down, from the typed equation of y alone."""
    out, x = {}, np.array([push, 0.0])
    for direction, order in (("up", speeds), ("down", speeds[::-1])):
        for V in order:
            c = C0 * (1 - V / 50)

            def f(_, s, c=c):
                return [s[1], -(c * s[1] + K_Y * s[0]) / M_Y]

            t = np.linspace(settle, settle + record, 4001)
            sol = solve_ivp(f, (0, settle + record), x, rtol=1e-11, atol=1e-14,
                            dense_output=True, method="DOP853")  # fmt: skip
            out[(direction, float(V))] = float(np.max(np.abs(sol.sol(t)[0])))
            x = sol.y[:, -1]
    return out


def run_hunting(tmp_path, model, *extra):
    out = tmp_path / "out"
    args = ["hunting", "--model", model, "--speeds", "40,50,60", "--settle", "1", "--record",
            "1", "--repush", "0", "--no-circuit", "--out", str(out), *extra]  # fmt: skip
    assert main(args) == 0
    with open(out / "hunting.csv") as handle:
        return list(csv.DictReader(handle))


@pytest.mark.parametrize(
    "options, initial, extra",
    [
        ("", "", ("--state", "y", "--y0", "0.005")),  # --state names it
        ('state = "y"', "", ("--y0", "0.005")),  # the model's [options] state
        ('y0 = "y0"', '[initial]\ny = "y0"', ("--y0", "0.005")),  # [options] y0, [initial]
        ('y0 = "y0"\nstate = "y"', '[initial]\ny = "y0"', ("--y0", "0.005")),
    ],
)
def test_hunting_pushes_and_measures_the_named_state(tmp_path, options, initial, extra):
    rows = run_hunting(tmp_path, write_model(tmp_path, options, initial), *extra)
    assert "amplitude_y (m)" in rows[0]
    expected = reference_amplitudes(np.array([40.0, 50.0, 60.0]), 0.005)
    for row in rows:
        key = (row["direction"], float(row["V (m/s)"]))
        assert float(row["amplitude_y (m)"]) == pytest.approx(expected[key], rel=1e-5)
    statuses = {(r["direction"], float(r["V (m/s)"])): r["status"] for r in rows}
    assert statuses[("up", 40.0)] == "decaying" and statuses[("up", 60.0)] == "growing"


def test_the_push_of_the_first_state_is_refused_for_the_second(tmp_path, capsys):
    """[options] y0 puts the push into x ([initial] x = y0), --state y measures y: y starts
    at rest, which is refused with the start named."""
    model = write_model(tmp_path, 'y0 = "y0"', '[initial]\nx = "y0"')
    args = ["hunting", "--model", model, "--speeds", "40,50", "--state", "y", "--y0", "0.005",
            "--no-circuit", "--out", str(tmp_path / "o")]  # fmt: skip
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "the push is 0: start y away from rest" in err and "x = 0.005" in err


def test_an_unknown_state_is_refused(tmp_path, capsys):
    model = write_model(tmp_path)
    args = ["hunting", "--model", model, "--speeds", "40,50", "--state", "q", "--no-circuit",
            "--out", str(tmp_path / "o")]  # fmt: skip
    assert main(args) == 2
    assert "unknown state 'q' (states: x, y, x_dot, y_dot)" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text(open(model).read().replace('speed = "V"', 'speed = "V"\nstate = "z"'))
    assert main(["stability", "--model", str(bad)]) == 2
    assert "options.state: unknown state 'z'" in capsys.readouterr().err


def test_ode_pushes_the_named_state_and_draws_its_phase_portrait(tmp_path, capsys):
    model = write_model(tmp_path, 'state = "y"')
    plot, table = tmp_path / "ode.png", tmp_path / "ode.csv"
    args = ["ode", "--model", model, "--y0", "0.005", "--tstop", "1", "--plot", str(plot),
            "--csv", str(table)]  # fmt: skip
    assert main(args) == 0
    with open(table) as handle:
        first = next(csv.DictReader(handle))
    y = next(v for k, v in first.items() if k.startswith("y") and "dot" not in k)
    x = next(v for k, v in first.items() if k.startswith("x") and "dot" not in k)
    assert float(y) == 0.005 and float(x) == 0.0
    from circuitsim.compare.figures import plot_states
    from circuitsim.mechanics import load_model
    from circuitsim.mechanics.solve import solve

    loaded = load_model(model)
    result = solve(loaded.system(None, {}, x0={"y": 0.005}), (0.0, 0.5))
    figure = plot_states(tmp_path / "p.png", result, state=loaded.default_state)
    phase = figure.axes[-1]
    assert phase.get_title() == "phase portrait"
    # lengths drawn in mm (the house style, circuitsim/figure_style.py)
    assert phase.get_xlabel() == "y (mm)" and phase.get_ylabel() == "y_dot (m/s)"


def free_peak(V: float, push: float, t_stop: float, window: float) -> float:
    """max |y| over the last ``window`` seconds of y's free response from ``push``."""
    c = C0 * (1 - V / 50)
    sol = solve_ivp(lambda _, s: [s[1], -(c * s[1] + K_Y * s[0]) / M_Y], (0, t_stop),
                    [push, 0.0], rtol=1e-11, atol=1e-14, dense_output=True)  # fmt: skip
    return float(np.max(np.abs(sol.sol(np.linspace(t_stop - window, t_stop, 8001))[0])))


def test_sweep_measures_the_named_state_and_names_its_kernel(tmp_path, capsys):
    model = write_model(tmp_path, 'state = "y"')
    out = tmp_path / "sweep"
    args = ["sweep", "--model", model, "--param", "V", "--values", "40:60:10", "--y0", "0.005",
            "--tstop", "2", "--window", "1", "--jobs", "1", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    assert "(builtin, ports kernel; changed:" in capsys.readouterr().out
    with open(out / "sweep.csv") as handle:
        rows = list(csv.DictReader(handle))
    for row in rows:
        V = float(row["V (m/s)"])
        assert float(row["max_abs_y_last_1s (m)"]) == pytest.approx(
            free_peak(V, 0.005, 2.0, 1.0), rel=1e-3
        )


def test_tolerance_draws_the_named_state_and_no_speed_panel_without_a_speed(tmp_path, capsys):
    """The model without [options] speed: no critical-speed panel; the metrics of --state."""
    import json

    model = write_model(tmp_path, 'state = "y"')
    text = open(model).read().replace('speed = "V"\n', "")
    path = tmp_path / "nospeed.toml"
    path.write_text(text)
    out = tmp_path / "tol"
    args = ["tolerance", "--model", str(path), "--y0", "0.005", "-n", "2", "--tstop", "1",
            "--jobs", "1", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    assert "times (builtin, ports kernel):" in capsys.readouterr().out
    data = json.loads((out / "tolerance.json").read_text())
    assert data["kernel"] == "ports"
    from circuitsim.studies.tolerance import ToleranceResult, Tolerances, plot_tolerance

    metrics = {s: {m: np.array(data["metrics"][s][m], dtype=float) for m in data["metrics"][s]}
               for s in data["metrics"]}  # fmt: skip
    result = ToleranceResult(Tolerances(), 1, 2, None, np.full(2, np.nan), np.zeros((2, 4, 4)),
                             metrics)  # fmt: skip
    figure = plot_tolerance(result, tmp_path / "t.png", "y")
    titles = [a.get_title() for a in figure.axes if a.get_visible()]
    assert titles == ["y: NRMSD", "y: peak ratio", "y: frequency ratio"]


def test_hunting_circuit_path_measures_the_named_state(tmp_path):
    """The circuit path too: its amplitudes of y (the second coordinate) follow the typed
    equation's, to the circuit's accuracy."""
    model = write_model(tmp_path, 'state = "y"')
    out = tmp_path / "out"
    args = ["hunting", "--model", model, "--speeds", "40,50,60", "--settle", "1", "--record",
            "1", "--repush", "0", "--y0", "0.005", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    with open(out / "hunting.csv") as handle:
        rows = [r for r in csv.DictReader(handle) if r["path"] == "circuit"]
    assert len(rows) == 6
    expected = reference_amplitudes(np.array([40.0, 50.0, 60.0]), 0.005)
    for row in rows:
        key = (row["direction"], float(row["V (m/s)"]))
        assert float(row["amplitude_y (m)"]) == pytest.approx(expected[key], rel=1e-3)
