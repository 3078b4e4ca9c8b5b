"""Figures are written atomically, in the format their suffix names, without touching the
caller's matplotlib backend (a notebook that imports circuitsim keeps its own)."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure

from circuitsim.atomic import write_figure_atomic
from circuitsim.solver.plotting import plot_waveforms
from circuitsim.solver.waveforms import Waveforms

ROOT = Path(__file__).resolve().parents[1]
MAGIC = {".png": b"\x89PNG", ".pdf": b"%PDF", ".svg": b"<?xml"}


def _waves() -> Waveforms:
    t = np.linspace(0.0, 1e-3, 50)
    return Waveforms(
        time=t, signals={"v(a)": np.sin(2e4 * t), "i(v1)": 1e-3 * np.cos(2e4 * t)}, engine="x"
    )


@pytest.mark.parametrize("suffix", [".png", ".pdf", ".svg"])
def test_plot_waveforms_writes_the_format_of_its_suffix(tmp_path, suffix):
    path = tmp_path / f"w{suffix}"
    plot_waveforms(_waves(), path, title="t")
    assert path.read_bytes().startswith(MAGIC[suffix])
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left


def test_a_failing_figure_leaves_an_existing_file_untouched(tmp_path):
    path = tmp_path / "old.png"
    path.write_bytes(b"keep me")
    figure = Figure()
    figure.subplots().plot([0, 1], [0, 1])
    with pytest.raises(ValueError):
        write_figure_atomic(figure, path, format="no-such-format")
    assert path.read_bytes() == b"keep me"
    assert [p.name for p in tmp_path.iterdir()] == ["old.png"]


def test_plotting_keeps_the_callers_backend(tmp_path):
    # in a fresh interpreter: pyplot's backend is process-wide state
    script = f"""
import matplotlib
matplotlib.use("pdf")
import circuitsim.compare, circuitsim.compare.plots, circuitsim.compare.figures
import circuitsim.compare.paper_figures, circuitsim.compare.sweep, circuitsim.cli
import circuitsim.compare.sweep_plot
from tests.test_figures_io import _waves
from circuitsim.solver.plotting import plot_waveforms
plot_waveforms(_waves(), {str(tmp_path / "w.png")!r})
import sys
sys.stdout.write(matplotlib.get_backend())
"""
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert out.stdout.lower() == "pdf"
    assert (tmp_path / "w.png").read_bytes().startswith(MAGIC[".png"])
