"""The stability and ode verbs, called through circuitsim.cli.main."""

import json
import textwrap

import numpy as np
import pytest

from circuitsim.cli import main


def test_stability_json(capsys):
    assert main(["stability", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["critical_speed"] == pytest.approx(55.6455, abs=0.01)
    assert report["hunting_frequency"] == pytest.approx(8.477, abs=1e-3)
    assert report["speed"] == 55.0
    assert len(report["eigenvalues"]) == 4
    # at 55 m/s, just below critical: every eigenvalue in the left half-plane
    assert all(re < 0 for re, _ in report["eigenvalues"])


def test_stability_text_with_coefficient_set_and_speed(capsys):
    assert main(["stability", "--coeffs", "derived", "--speed", "57"]) == 0
    out = capsys.readouterr().out
    assert "55.626" in out and "8.47" in out and "V = 57" in out


def test_ode_csv_reproduces_model_md_row(tmp_path, capsys):
    out = tmp_path / "out.csv"
    assert main(["ode", "--freq", "3", "--flange", "--csv", str(out)]) == 0
    with open(out) as handle:
        assert handle.readline().strip() == "time,y,psi,y_dot,psi_dot"
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert data[0, 0] == 0.0 and data[-1, 0] == pytest.approx(5.0)
    # reference: f = 3 Hz, flange on: max |y| 14.265 mm, y(5 s) +0.8557 mm, max |y'| 0.4772 m/s
    assert np.max(np.abs(data[:, 1])) * 1e3 == pytest.approx(14.265, rel=1e-3)
    assert data[-1, 1] * 1e3 == pytest.approx(0.8557, rel=1e-3)
    assert np.max(np.abs(data[:, 3])) == pytest.approx(0.4772, rel=1e-3)
    summary = capsys.readouterr().out
    assert "0.01426" in summary and "flange" in summary


def test_ode_free_response_and_plot(tmp_path, capsys):
    png = tmp_path / "fig.png"
    argv = ["ode", "--speed", "57", "--amplitude", "0", "--y0", "0.005", "--no-flange"]
    assert main(argv + ["--tstop", "10", "--plot", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    out = capsys.readouterr().out
    assert "nonlinear: none" in out
    # reference: V = 57 grows to 1.223 m (max |y| over 9-10 s, which is the max over 0-10 s)
    line = next(row for row in out.splitlines() if row.strip().startswith("y "))
    assert float(line.split()[3]) == pytest.approx(1.223, rel=1e-2)


def test_help_explains_units_and_defaults(capsys):
    for verb in ("ode", "stability"):
        with pytest.raises(SystemExit):
            main([verb, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert "m/s" in text and "default" in text
    with pytest.raises(SystemExit):
        main(["ode", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for words in ("Hz", "0.040", "ON", "time,y,psi,y_dot,psi_dot"):
        assert words in text


def test_bad_parameter_and_bad_model_file(tmp_path, capsys):
    assert main(["ode", "--param", "zeta=1", "--tstop", "0.1"]) == 2
    assert "parameters.zeta: unknown parameter" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text('[model]\nname = "x"\nkind = "first_order"\n[states]\nnames = ["x"]\n')
    assert main(["stability", "--model", str(bad)]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "matrices: missing table" in err
    with pytest.raises(SystemExit):
        main(["ode", "--param", "novalue"])
    assert "NAME=VALUE" in capsys.readouterr().err


GAP = """
[model]
name = "gap"
kind = "second_order"
[coordinates]
names = ["x"]
units = ["m"]
[parameters]
m = 2.0
k = 50.0
g = 0.1
v0 = 0.5
[matrices]
M = [["m"]]
K = [[0]]
[nonlinear.gap]
enters = { x = 1 }
linear = { x = "k" }
abs = [{ gain = "-k/2", row = [1], offset = "g" }, { gain = "k/2", row = [1], offset = "-g" }]
[initial]
x_dot = "v0"
"""


def test_user_model_through_the_cli(tmp_path, capsys):
    path = tmp_path / "gap.toml"
    path.write_text(textwrap.dedent(GAP))
    csv = tmp_path / "gap.csv"
    argv = ["ode", "--model", str(path), "--tstop", "1", "--dt", "0.01", "--csv", str(csv)]
    assert main(argv + ["--param", "v0=0.2"]) == 0
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    # free flight at 0.2 m/s until the wall at g = 0.1 (t = 0.5 s), then the spring
    assert np.allclose(data[data[:, 0] <= 0.5, 1], 0.2 * data[data[:, 0] <= 0.5, 0])
    contact = data[data[:, 0] > 0.5]
    spring = 0.1 + (0.2 / 5) * np.sin(5 * (contact[:, 0] - 0.5))
    assert np.allclose(contact[:, 1], spring, rtol=0, atol=1e-9)
    capsys.readouterr()
    assert main(["ode", "--model", str(path), "--speed", "3"]) == 2
    assert "no parameter for --speed" in capsys.readouterr().err
    # no [options] y0 in this file: --y0 sets the first state
    argv = ["ode", "--model", str(path), "--y0", "0.05", "--param", "v0=0", "--tstop", "1"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "+0.05" in out and "0 kink crossings" in out


def test_stability_of_a_user_model_in_another_parameter(tmp_path, capsys):
    # x'' + (c - mu) x' + k x = 0: critical mu = c = 0.3, frequency sqrt(k) / (2 pi) Hz
    path = tmp_path / "osc.toml"
    path.write_text(
        '[model]\nname = "osc"\nkind = "second_order"\n[coordinates]\nnames = ["x"]\n'
        "[parameters]\nmu = 0.0\nc = 0.3\nk = 16.0\n"
        '[matrices]\nM = [[1]]\nC = [["c - mu"]]\nK = [["k"]]\n'
    )
    argv = ["stability", "--model", str(path), "--parameter", "mu", "--bracket", "0.01", "10"]
    assert main(argv + ["--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["critical_speed"] == pytest.approx(0.3, rel=1e-9)
    assert report["hunting_frequency"] == pytest.approx(4 / (2 * np.pi), rel=1e-9)
    assert main(["stability", "--model", str(path)]) == 2
    assert "no parameter for --speed" in capsys.readouterr().err
