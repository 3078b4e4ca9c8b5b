"""The sweep verb takes generate's scenario options (--y0: the free response from a push), a log
peak axis, and --jobs under one name (--workers: its deprecated alias) like the other verbs."""

import csv

import numpy as np
import pytest

from circuitsim.cli import build_parser, main
from circuitsim.compare.sweep import SweepResult
from circuitsim.compare.sweep_plot import SweepPlotWarning, plot_sweep
from circuitsim.mechanics import load_model, solve

SPEEDS = (54.0, 57.0)  # m/s, either side of the wheelset's linear critical speed 55.6455 m/s
Y0 = 0.005  # m, the push
T_STOP = 1.0  # model seconds
WINDOW = 0.5  # model seconds


def _read_sweep(path):
    with open(path) as handle:
        rows = list(csv.reader(handle))
    return rows[0], [[float(x) for x in row] for row in rows[1:]]


def test_sweep_free_response_from_y0_grows_above_the_critical_speed(tmp_path, capsys):
    """--amplitude 0 --y0 0.005: below the critical speed the push decays, above it grows;
    each variant's peaks (whole run and late window) against the direct ODE solution of the
    same scenario (flange on, the default)."""
    out = tmp_path / "free"
    argv = ["sweep", "--param", "speed", "--values", ",".join(f"{v:g}" for v in SPEEDS),
            "--amplitude", "0", "--y0", str(Y0), "--tstop", str(T_STOP),
            "--window", str(WINDOW), "--log", "--jobs", "2", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    assert "critical V (linear) 55.6455" in capsys.readouterr().out
    assert (out / "sweep.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    header, rows = _read_sweep(out / "sweep.csv")
    assert header[0] == "V (m/s)" and [r[0] for r in rows] == list(SPEEDS)
    assert header[3:] == ["R33 (ohm)", "R44 (ohm)"]  # the resistors the speed turns
    model = load_model()
    reference = {}
    for speed, late, whole, *_ in rows:
        system = model.system(parameters={"V": speed, "a": 0.0, "y0": Y0})
        exact = solve(system, t_span=(0.0, T_STOP))
        reference[speed] = exact.max_abs("y"), exact.max_abs("y", t_from=T_STOP - WINDOW)
        assert whole == pytest.approx(reference[speed][0], rel=0.02)
        assert late == pytest.approx(reference[speed][1], rel=0.02)
    (_, late_below, all_below, *_), (_, late_above, all_above, *_) = rows
    # the ODE says: growth above, decay below (the whole-run peak below is the push itself)
    assert reference[57.0][0] > reference[54.0][0] and reference[57.0][1] > reference[54.0][1]
    assert all_above > all_below and late_above > late_below
    assert late_below < Y0 < late_above


def test_sweep_refuses_y0_that_fixes_the_swept_parameter(tmp_path, capsys):
    argv = ["sweep", "--param", "y0", "--values", "0.001,0.002", "--y0", "0.003",
            "--out", str(tmp_path)]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--y0 0.003 fixes y0" in err and "--param y0 sweeps" in err


@pytest.mark.parametrize("verb", ["generate", "compare", "ode", "sweep"])
def test_every_scenario_verb_takes_the_same_scenario_options(verb):
    """One set of scenario options (scenario_options.add_scenario_options) for every verb that
    builds the model's System: --y0 is no longer ode's alone."""
    scenario = {"--speed", "--freq", "--amplitude", "--y0", "--flange", "--no-flange",
                "--forcing", "--param"}  # fmt: skip
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices[verb]
    options = {s for a in sub._actions for s in a.option_strings}
    assert scenario <= options


@pytest.mark.parametrize("verb", ["sweep", "reproduce"])
def test_jobs_is_the_one_name_and_workers_its_deprecated_alias(verb, capsys):
    parser = build_parser()
    base = ["sweep", "--param", "speed", "--values", "50"] if verb == "sweep" else [verb]
    assert parser.parse_args([*base, "--jobs", "3"]).jobs == 3
    assert "deprecated" not in capsys.readouterr().err
    assert parser.parse_args([*base, "--workers", "3"]).jobs == 3
    assert "warning: --workers is deprecated, use --jobs" in capsys.readouterr().err


def test_workers_alias_runs_a_sweep_and_a_bad_count_names_it(tmp_path, capsys):
    argv = ["sweep", "--param", "speed", "--values", "50", "--tstop", "0.05",
            "--out", str(tmp_path)]  # fmt: skip
    assert main([*argv, "--workers", "1"]) == 0
    assert "warning: --workers is deprecated" in capsys.readouterr().err
    assert (tmp_path / "sweep.csv").exists()
    assert main(["reproduce", "--workers", "0", "--out", str(tmp_path / "r")]) == 2
    assert "reproduce: error: --workers must be at least 1, got 0" in capsys.readouterr().err
    assert main([*argv, "--jobs", "0"]) == 2
    assert "sweep: error: --jobs must be at least 1, got 0" in capsys.readouterr().err


def _result(peaks):
    peaks = np.asarray(peaks, dtype=float)
    return SweepResult("V", "m/s", np.array([50.0, 55.0, 60.0]), "y", "m", peaks, peaks,
                       "builtin", 1.0)  # fmt: skip


def _y_scale(monkeypatch, result, path):
    """Draw ``result`` with log=True; return the y axis's scale and the drawn peaks."""
    from matplotlib.axes import Axes

    drawn = {}
    set_yscale = Axes.set_yscale

    def spy(self, value, **kwargs):
        drawn["scale"] = value
        return set_yscale(self, value, **kwargs)

    monkeypatch.setattr(Axes, "set_yscale", spy)
    plot = Axes.plot

    def record(self, x, y, *args, **kwargs):
        drawn.setdefault("y", []).append(np.asarray(y))
        return plot(self, x, y, *args, **kwargs)

    monkeypatch.setattr(Axes, "plot", record)
    plot_sweep(result, path, log=True)
    assert path.stat().st_size > 1000
    return drawn.get("scale", "linear"), drawn["y"]


def test_log_axis_leaves_out_zero_peaks_with_a_warning(tmp_path, monkeypatch):
    """A peak of 0 (a state at rest) has no place on a log axis: left out, the value named."""
    result = _result([0.0, 1e-3, 2e-2])
    with pytest.warns(SweepPlotWarning, match=r"peak \|y\| is 0 at V = 50 m/s"):
        scale, drawn = _y_scale(monkeypatch, result, tmp_path / "zero.png")
    assert scale == "log"
    for y in drawn:  # mm: the positive peaks drawn as they are, the zero one a gap
        assert np.isnan(y[0]) and list(y[1:]) == pytest.approx([1.0, 20.0])
    assert result.peak_all[0] == 0.0  # the result (and so the CSV) keeps it


def test_log_axis_of_only_zero_peaks_stays_linear_with_a_warning(tmp_path, monkeypatch):
    with pytest.warns(SweepPlotWarning, match="0 at every V; the figure keeps a linear axis"):
        scale, _ = _y_scale(monkeypatch, _result([0.0, 0.0, 0.0]), tmp_path / "zeros.png")
    assert scale == "linear"


def test_log_axis_of_positive_peaks_warns_nothing(tmp_path, monkeypatch, recwarn):
    scale, _ = _y_scale(monkeypatch, _result([1e-4, 1e-3, 2e-2]), tmp_path / "log.png")
    assert scale == "log"
    assert not [w for w in recwarn if issubclass(w.category, SweepPlotWarning)]
