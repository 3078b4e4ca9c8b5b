"""The house style of the figures (circuitsim/figure_style.py) and the --format/--dpi options
of the verbs that draw: the format follows the option or the suffix, a PNG's resolution is
measured from its pixel size, histograms keep their bins when one value is far out, a ratio
axis reads plain numbers, and the hunting figure labels its bound and rings re-pushed steps."""

import math
import struct

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from circuitsim.cli import main
from circuitsim.figure_style import DEFAULT_DPI, DOUBLE_COLUMN, MIN_FONT_PT, robust_range
from tests.conftest import requires_ngspice

MAGIC = {"png": b"\x89PNG\r\n\x1a\n", "pdf": b"%PDF", "svg": b"<?xml"}


def png_size(path) -> tuple[int, int]:
    """Width and height in pixels, read from the PNG's IHDR chunk."""
    data = path.read_bytes()
    assert data[:8] == MAGIC["png"] and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def texts(figure) -> list:
    """Every text artist of ``figure`` that shows something (titles, labels, ticks,
    legends)."""
    FigureCanvasAgg(figure).draw()
    return [t for t in figure.findobj(lambda a: hasattr(a, "get_fontsize")) if t.get_text()]


# --- the style module ---------------------------------------------------------------------


def test_robust_range_leaves_one_far_outlier_outside_and_counts_it():
    rng = np.random.default_rng(3)
    values = np.append(rng.normal(0.10, 0.01, 39), 156.0)  # one circuit at 156 % NRMSD
    low, high, below, above = robust_range(values)
    assert (below, above) == (0, 1)
    assert high < 0.2  # the bins span the 39 others, not 0-156
    inside = values[(values >= low) & (values <= high)]
    assert inside.size == 39 and inside.min() == values[:39].min()


def test_robust_range_of_values_without_outliers_is_theirs():
    values = np.linspace(1.0, 2.0, 11)
    assert robust_range(values) == (1.0, 2.0, 0, 0)
    low, high, below, above = robust_range(np.full(5, 0.5))  # all equal: a range around them
    assert low < 0.5 < high and (below, above) == (0, 0)


# --- ode --plot: format by suffix or option, resolution -----------------------------------


@pytest.mark.parametrize(
    ("plot", "options", "written", "fmt"),
    [
        ("a.svg", [], "a.svg", "svg"),
        ("b", ["--format", "pdf"], "b.pdf", "pdf"),
        ("c.png", ["--format", "png"], "c.png", "png"),
    ],
)
def test_ode_plot_format_follows_the_suffix_or_the_option(tmp_path, plot, options, written, fmt):
    args = ["ode", "--tstop", "0.2", "--plot", str(tmp_path / plot), *options]
    assert main(args) == 0
    assert [p.name for p in tmp_path.iterdir()] == [written]
    assert (tmp_path / written).read_bytes().startswith(MAGIC[fmt])


def test_ode_plot_suffix_and_format_that_disagree_are_refused(tmp_path, capsys):
    args = ["ode", "--tstop", "0.2", "--plot", str(tmp_path / "a.pdf"), "--format", "svg"]
    assert main(args) == 2
    assert "the suffix .pdf and --format svg disagree" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("dpi", [None, 100.0])
def test_png_resolution_is_the_dpi_asked_for(tmp_path, dpi):
    """The figure is laid out at print size (DOUBLE_COLUMN inches wide), so its width in
    pixels over that width is the resolution."""
    path = tmp_path / "ode.png"
    args = ["ode", "--tstop", "0.2", "--plot", str(path)]
    assert main(args + ([] if dpi is None else ["--dpi", str(dpi)])) == 0
    width, _ = png_size(path)
    assert width / DOUBLE_COLUMN == pytest.approx(dpi or DEFAULT_DPI, abs=0.5)


@pytest.mark.parametrize("dpi", ["0", "5000", "nan"])
def test_dpi_out_of_range_is_refused(tmp_path, capsys, dpi):
    args = ["ode", "--tstop", "0.2", "--plot", str(tmp_path / "a.png"), "--dpi", dpi]
    assert main(args) == 2
    assert "--dpi must be between 30 and 1200" in capsys.readouterr().err


def test_the_response_figure_is_in_millimetres_with_print_sized_fonts(tmp_path):
    from circuitsim.compare.figures import plot_states
    from circuitsim.mechanics import load_model, solve

    system = load_model().system()
    result = solve(system, t_span=(0.0, 0.2))
    figure = plot_states(tmp_path / "s.png", result)
    labels = [a.get_ylabel() for a in figure.axes]
    assert "y (mm)" in labels and not any(label.endswith("(m)") for label in labels)
    assert figure.get_size_inches()[0] == pytest.approx(DOUBLE_COLUMN)
    assert min(t.get_fontsize() for t in texts(figure)) >= MIN_FONT_PT


# --- tolerance histograms -----------------------------------------------------------------


def tolerance_result(nrmsd: np.ndarray, frequency_ratio: np.ndarray):
    from circuitsim.compare.comparison import Thresholds
    from circuitsim.studies.tolerance import ToleranceResult, Tolerances

    n = nrmsd.size
    metrics = {"y": {"nrmsd_percent": nrmsd, "peak_ratio": np.full(n, 1.001),
                     "frequency_ratio": frequency_ratio}}  # fmt: skip
    return ToleranceResult(Tolerances(), 1, n, None, np.full(n, np.nan), np.zeros((n, 4, 4)),
                           metrics, thresholds=Thresholds())  # fmt: skip


def test_tolerance_histogram_keeps_its_bins_with_an_outlier_and_counts_it(tmp_path):
    from circuitsim.studies.tolerance import plot_tolerance

    rng = np.random.default_rng(7)
    nrmsd = np.append(rng.uniform(0.05, 0.15, 39), 156.0)
    ratio = 1.0 + rng.uniform(-2e-6, 2e-6, 40)
    figure = plot_tolerance(tolerance_result(nrmsd, ratio), tmp_path / "t.png", "y")
    panel = next(a for a in figure.axes if a.get_title().startswith("y: NRMSD"))
    bars = [p for p in panel.patches if p.get_height() > 0]
    edges = [p.get_x() + p.get_width() for p in bars]
    assert max(edges) < 1.0  # not one bin from 0 to 156 %
    assert sum(p.get_height() for p in bars) == 39
    assert "off scale: 1 above (max 156)" in panel.get_title()


def test_frequency_ratio_axis_reads_plain_numbers(tmp_path):
    from circuitsim.studies.tolerance import plot_tolerance

    ratio = 1.0 + np.linspace(-2e-6, 2e-6, 20)
    figure = plot_tolerance(tolerance_result(np.full(20, 0.1), ratio), tmp_path / "t.png", "y")
    FigureCanvasAgg(figure).draw()
    panel = next(a for a in figure.axes if a.get_title().startswith("y: frequency ratio"))
    assert panel.xaxis.get_major_formatter().get_offset() == ""
    ticks = [t.get_text() for t in panel.get_xticklabels() if t.get_text()]
    assert ticks and all("e" not in t and "+" not in t for t in ticks)
    assert all(abs(float(t.replace("\N{MINUS SIGN}", "-")) - 1.0) < 1e-4 for t in ticks)


# --- the hunting figure -------------------------------------------------------------------


def test_hunting_figure_labels_its_bound_and_rings_repushed_steps(tmp_path):
    from circuitsim.studies.hunting_plot import plot_hunting
    from circuitsim.studies.hunting_result import HuntingBranch, HuntingResult, HuntingSettings

    speeds = np.array([53.0, 54.0, 55.0, 56.0])
    # flange off: dies out at 53, re-pushed at 54, grows past the 20 mm bound at 56
    up = HuntingBranch("ode", "up", False, speeds, np.array([1e-5, 4e-3, 8e-3, math.inf]),
                       ["decaying", "decaying", "growing", "unbounded"],
                       np.array([True, True, False, False]))  # fmt: skip
    settings = HuntingSettings(settle=1.0, record=1.0, bound=0.02)
    result = HuntingResult("V", "m/s", "y", "m", 0.005, settings, 55.6, [up])
    figure = plot_hunting(result, tmp_path / "h.png")
    assert (tmp_path / "h.png").read_bytes().startswith(MAGIC["png"])
    (axis,) = figure.axes
    labels = [t.get_text() for t in axis.get_legend().get_texts()]
    assert "bound 20 mm (arrow: grew past it)" in labels
    bound = [line for line in axis.get_lines() if line.get_label().startswith("bound")]
    assert list(bound[0].get_ydata()) == [20.0, 20.0]
    ringed = [line for line in axis.get_lines() if line.get_marker() == "o"
              and line.get_markerfacecolor() == "none" and len(line.get_xdata())]  # fmt: skip
    assert [list(r.get_xdata()) for r in ringed] == [[54.0]]  # not the first step
    drawn = next(line for line in axis.get_lines() if line.get_label() == "ode, up")
    assert np.isnan(drawn.get_ydata()[-1])  # the unbounded step is not drawn at a value
    assert any(line.get_marker() == r"$\uparrow$" for line in axis.get_lines())


# --- reproduce ----------------------------------------------------------------------------


def test_reproduce_refuses_a_bad_dpi_before_any_work(tmp_path, capsys):
    out = tmp_path / "rep"
    assert main(["reproduce", "--out", str(out), "--dpi", "10"]) == 2
    assert "--dpi must be between 30 and 1200" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.slow
@requires_ngspice
def test_reproduce_writes_every_figure_in_the_format_asked_and_embeds_fig4(tmp_path):
    from circuitsim.studies.reproduce import reproduce
    from circuitsim.studies.reproduce_cases import Scenario

    result = reproduce(
        tmp_path, scenarios=(Scenario(10.0, True, t_stop=0.5),), opamps=("ideal",),
        series=("exact",), engines=("ngspice",), free_speeds=(54.0,), workers=1,
        hunting_speeds=(), tolerance_samples=0, frequency_response=False, figure_format="svg",
    )  # fmt: skip
    drawn = {k: v for k, v in result.figures.items() if k != "schematic"}  # always SVG + PNG
    assert {"fig3", "fig4-f10-flange-on", "fig6-f10-flange-on", "critical-speed"} <= set(drawn)
    for relative in drawn.values():
        assert relative.endswith(".svg")
        assert (tmp_path / relative).read_bytes().startswith(MAGIC["svg"])
    assert not list((tmp_path / "figures").glob("fig*.png"))
    report = (tmp_path / "report.md").read_text()
    assert "![ODE: displacement, velocity and phase portrait, V = 55 m/s, f = 10 Hz, flange on]" \
        "(figures/fig4-f10-flange-on.svg)" in report  # fmt: skip
    assert "freq of error y (Hz)" in report and "error freq" not in report
