"""The sweep's files: its CSV and its bifurcation-style figure, peak |state| against the
swept parameter (linear or log axis), the critical value marked."""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from circuitsim.atomic import write_figure_atomic, write_text_atomic

if TYPE_CHECKING:
    from circuitsim.compare.sweep import SweepResult


class SweepPlotWarning(UserWarning):
    """Something the sweep's figure cannot show (the CSV has every value)."""


def save_sweep(
    result: SweepResult, folder: str | os.PathLike, stem: str = "sweep", log: bool = False
) -> list[Path]:
    """Write ``<stem>.csv`` and ``<stem>.png`` (bifurcation-style plot) atomically.

    ``log`` draws the figure's peak axis on a log scale (see :func:`plot_sweep`).

    Returns
    -------
    list of Path
        The files written.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    csv_path, png_path = folder / f"{stem}.csv", folder / f"{stem}.png"
    write_text_atomic(csv_path, result.csv_text())
    plot_sweep(result, png_path, log=log)
    return [csv_path, png_path]


def _log_drawable(result: SweepResult, log: bool) -> tuple[np.ndarray, np.ndarray, bool]:
    """The peaks (whole run, late window) to draw and whether the axis is logarithmic: on a
    log axis a peak of 0 (a state that stayed at rest) cannot be drawn, and is left out (NaN,
    a gap) with a SweepPlotWarning naming the values; the CSV keeps it. A sweep whose every
    peak is 0 keeps a linear axis (with the warning saying so)."""
    peak_all, peak_late = result.peak_all.astype(float), result.peak_late.astype(float)
    if not log:
        return peak_all, peak_late, False
    zero = (peak_all <= 0) | (peak_late <= 0)
    if not zero.any():
        return peak_all, peak_late, True
    if zero.all():
        warnings.warn(
            f"log axis: peak |{result.state}| is 0 at every {result.parameter}; the figure "
            "keeps a linear axis",
            SweepPlotWarning,
            stacklevel=3,
        )
        return peak_all, peak_late, False
    where = ", ".join(f"{v:g}" for v in result.values[zero][:10])
    more = f" and {int(zero.sum()) - 10} more" if zero.sum() > 10 else ""
    warnings.warn(
        f"log axis: peak |{result.state}| is 0 at {result.parameter} = {where}{more} "
        f"{result.unit}; left out of the figure (the CSV has it)",
        SweepPlotWarning,
        stacklevel=3,
    )
    gap = np.where(zero, np.nan, 1.0)
    return peak_all * gap, peak_late * gap, True


def plot_sweep(result: SweepResult, path: str | os.PathLike, log: bool = False) -> None:
    """Peak |state| (late window and whole run) against the parameter, critical value marked.

    Parameters
    ----------
    result : SweepResult
    path : str or path-like
        PNG file, written atomically.
    log : bool
        Peak axis on a log scale: a growing or decaying free response shows as a straight
        line. Peaks of 0 cannot be drawn there: those values are left out of the figure with
        a :class:`SweepPlotWarning` (all of them 0: the axis stays linear, with the warning).
    """
    from matplotlib.figure import Figure  # here: a sweep's CSV alone does not load it

    fig = Figure(figsize=(7, 4.2))
    ax = fig.subplots()
    scale, unit = (1e3, "mm") if result.state_unit == "m" else (1.0, result.state_unit)
    peak_all, peak_late, log = _log_drawable(result, log)
    ax.plot(result.values, peak_all * scale, "o-", ms=3, color="0.6", label="whole run")
    ax.plot(
        result.values,
        peak_late * scale,
        "o-",
        ms=3,
        color="C0",
        label=f"last {result.window:g} s",
    )
    if log:
        ax.set_yscale("log")
    if result.critical is not None:
        ax.axvline(result.critical, color="C3", ls="--", lw=1)
        ax.annotate(
            f"critical {result.parameter} = {result.critical:.4g} {result.unit}",
            (result.critical, 0.97),
            xycoords=("data", "axes fraction"),
            ha="right",
            va="top",
            rotation=90,
            color="C3",
            fontsize=8,
            bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none", "alpha": 0.85},
        )
    ax.set_xlabel(f"{result.parameter} ({result.unit})" if result.unit else result.parameter)
    ax.set_ylabel(f"max |{result.state}| ({unit})")
    ax.set_title(f"peak |{result.state}| against {result.parameter} ({result.engine} engine)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    write_figure_atomic(fig, path, format="png", dpi=120)
