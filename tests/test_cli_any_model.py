"""Nothing of the wheelset where a model is not one (issue 16, item 5): help texts, plot labels
and units come from the model, `ode` honours [circuit] t_stop, [circuit] time_scale and
`compare --time-scale`, `compare` prints generate's warnings, `stability --eigenvalues` works
for any model. Each checked with a model that is not the wheelset."""

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.mechanics import load_model, solve

MODELS = Path(__file__).resolve().parent / "synthesis" / "models"
GAP = str(MODELS / "gap_oscillator.toml")  # m = 1, c = 0.6, k = 40; [circuit] t_stop = 5
TWO_MASS = str(MODELS / "two_mass_stop.toml")

DECAY = """
[model]
name = "decay"
kind = "first_order"
time_unit = "{time_unit}"

[states]
names = ["u"]
units = ["V"]

[parameters]
tau = {{ value = 0.5, unit = "{time_unit}" }}

[matrices]
A = [["-1 / tau"]]

[initial]
u = 1.0

[circuit]
t_stop = 2.0
{extra}
"""


def decay(tmp_path, time_unit="s", extra=""):
    path = tmp_path / "decay.toml"
    path.write_text(DECAY.format(time_unit=time_unit, extra=extra))
    return str(path)


def test_ode_runs_to_the_model_files_t_stop(tmp_path, capsys):
    csv = tmp_path / "u.csv"
    assert main(["ode", "--model", decay(tmp_path), "--csv", str(csv), "--dt", "0.01"]) == 0
    out = capsys.readouterr().out
    assert "0 to 2 s," in out
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    assert data[-1, 0] == 2.0
    # u' = -u / tau: u(2) = exp(-4)
    assert data[-1, 1] == pytest.approx(math.exp(-4.0), rel=1e-8)
    assert main(["ode", "--model", decay(tmp_path), "--tstop", "1"]) == 0  # the option wins
    assert "0 to 1 s," in capsys.readouterr().out


def test_a_dimensionless_time(tmp_path, capsys):
    path = decay(tmp_path, time_unit="")
    model = load_model(path)
    assert model.time_unit == ""
    plot = tmp_path / "u.png"
    assert main(["ode", "--model", path, "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    assert "0 to 2," in out and "at 2:" in out
    from circuitsim.compare.figures import plot_states

    figure = plot_states(tmp_path / "again.png", solve(model.system(), (0.0, 2.0)), time_unit="")
    assert figure.axes[0].get_xlabel() == "time (dimensionless)"


def test_rates_of_a_dimensionless_second_order_model_keep_the_coordinates_unit(tmp_path):
    text = Path(GAP).read_text().replace(
        'kind = "second_order"', 'kind = "second_order"\ntime_unit = "1"'
    )
    path = tmp_path / "gap.toml"
    path.write_text(text)
    assert load_model(path).units == ("m", "m")
    assert load_model(GAP).units == ("m", "m/s")


def test_every_state_is_plotted_in_its_unit(tmp_path):
    model = load_model(TWO_MASS)
    result = solve(model.system(), (0.0, 1.0))
    from circuitsim.compare.figures import plot_states

    figure = plot_states(tmp_path / "two.png", result, time_unit=model.time_unit)
    # units m and m/s: two panels of two traces each, then the phase portrait of x1 (with
    # the kinks marked when the stop was reached)
    assert len(result.kinks) > 0
    assert [len(axis.lines) for axis in figure.axes] == [2, 2, 2]
    # lengths are drawn in mm (the house style, circuitsim/figure_style.py)
    assert figure.axes[0].get_ylabel() == "x1, x2 (mm)"
    assert figure.axes[1].get_ylabel() == "x1_dot, x2_dot (m/s)"
    assert figure.axes[0].get_xlabel() == "time (s)"
    assert figure.axes[2].get_xlabel() == "x1 (mm)"
    drawn = np.vstack([line.get_ydata() for axis in figure.axes[:2] for line in axis.lines])
    t = figure.axes[0].lines[0].get_xdata()
    in_mm = np.array([1e3 if unit == "m" else 1.0 for unit in result.units])[:, None]
    assert np.allclose(drawn, result.sol(t) * in_mm)
    assert (tmp_path / "two.png").stat().st_size > 1000


def test_help_texts_come_from_the_model(capsys):
    with pytest.raises(SystemExit):
        main(["ode", "--model", GAP, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    # the description and --model name the built-in default (and other options may give it
    # as an example); the scenario options' texts do not
    options = text[text.index("--coeffs SET coefficient set") :]
    for words in ("lateral", "flange force", "eta=", "psi", "paper"):
        assert words not in options
    scenario = text[text.index("--speed V not used") : text.index("gap (on)")]
    assert "wheelset" not in scenario
    assert "--speed V not used by gap_oscillator" in text
    assert "switch all the piecewise-linear terms of gap_oscillator on or off" in text
    assert "gap (on)" in text
    assert "header time,x,x_dot; units s, m, m/s" in text
    assert "k (N/m)" in text  # --param lists the model's parameters with units
    with pytest.raises(SystemExit):
        main(["generate", "--model", GAP, "--help"])
    assert "not used by gap_oscillator" in capsys.readouterr().out


def test_help_of_a_mapped_option_names_the_parameter(tmp_path, capsys):
    path = Path(decay(tmp_path))
    path.write_text(path.read_text().replace("[matrices]", '[options]\nfreq = "tau"\n[matrices]'))
    with pytest.raises(SystemExit):
        main(["ode", "--model", str(path), "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--freq F sets tau of decay (s; default 0.5)" in text


def test_help_without_a_model_is_for_any_model(capsys):
    with pytest.raises(SystemExit):
        main(["ode", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "sets the parameter the model's [options] table maps 'amplitude' to" in text
    assert "switch all the model's piecewise-linear terms on or off" in text


def test_stability_eigenvalues_of_a_model_without_a_speed(capsys):
    # m x'' + c x' + k x = 0 with m = 1, c = 0.6, k = 100: lambda = -0.3 +- i sqrt(100 - 0.09)
    argv = ["stability", "--model", GAP, "--eigenvalues", "--param", "k=100"]
    assert main([*argv, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["parameters"]["k"] == 100.0
    first, second = report["modes"]
    assert first["eigenvalue"] == pytest.approx([-0.3, math.sqrt(100 - 0.09)], rel=1e-12)
    assert second["eigenvalue"] == pytest.approx([-0.3, -math.sqrt(100 - 0.09)], rel=1e-12)
    assert first["damping_ratio"] == pytest.approx(0.6 / (2 * math.sqrt(100)), rel=1e-12)
    assert first["natural_frequency"] == pytest.approx(10 / (2 * math.pi), rel=1e-12)
    assert first["damped_frequency"] == pytest.approx(math.sqrt(99.91) / (2 * math.pi), rel=1e-12)
    assert main(argv) == 0
    table = capsys.readouterr().out
    assert "at k=100" in table and "-0.3 +9.9955j" in table and "unstable" not in table


def test_stability_eigenvalues_of_a_first_order_model(tmp_path, capsys):
    assert main(["stability", "--model", decay(tmp_path), "--eigenvalues", "--json"]) == 0
    (mode,) = json.loads(capsys.readouterr().out)["modes"]
    assert mode["eigenvalue"] == [-2.0, 0.0]  # -1 / tau
    assert mode["damping_ratio"] == 1.0 and mode["damped_frequency"] == 0.0


def test_time_scale_from_the_model_file_and_the_option(tmp_path, capsys):
    path = decay(tmp_path, extra="time_scale = 50.0")
    out = tmp_path / "d.cir"
    assert main(["generate", "--model", path, "-o", str(out)]) == 0
    scale = json.loads((tmp_path / "d.scale.json").read_text())
    assert scale["time_scale"] == 50.0
    assert re.search(r"^\.tran \S+ 40m ", out.read_text(), re.M)  # 2 model seconds / 50
    assert main(["generate", "--model", path, "--time-scale", "4", "-o", str(out)]) == 0
    assert json.loads((tmp_path / "d.scale.json").read_text())["time_scale"] == 4.0
    capsys.readouterr()


def test_compare_with_a_time_scale_matches_the_ode(capsys):
    argv = ["compare", "--model", GAP, "--time-scale", "100", "--json", "--tstop", "2"]
    assert main(argv) == 0
    data = json.loads(capsys.readouterr().out)
    for state in ("x", "x_dot"):
        assert data["states"][state]["nrmsd_percent"] < 0.5


def test_compare_prints_the_warnings_generate_prints(tmp_path, capsys):
    # c = 0.01 next to k = 40: no capacitor keeps every resistor in range, a warning (c = 1e-4
    # would need R C = 1e4 s, 1 Gohm on the largest capacitor: refused, synthesis/bounds.py)
    scenario = ["--model", GAP, "--param", "c=0.01", "--tstop", "1"]
    assert main(["generate", *scenario, "-o", str(tmp_path / "g.cir")]) in (0, 1)
    generated = [line for line in capsys.readouterr().err.splitlines() if "warning:" in line]
    assert generated and any("is outside" in line for line in generated)
    main(["compare", *scenario, "--series", "E96"])
    compared = [line for line in capsys.readouterr().err.splitlines() if "warning:" in line]
    assert compared == generated


def test_stability_of_a_model_without_a_speed_points_to_eigenvalues(tmp_path, capsys):
    assert main(["stability", "--model", decay(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "no parameter for --speed" in err and "--eigenvalues" in err and "--parameter" in err
