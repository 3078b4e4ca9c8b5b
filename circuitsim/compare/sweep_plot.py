"""The sweep's files: its CSV and its bifurcation-style figure, peak |state| against the
swept parameter (linear or log axis), the critical value marked."""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from circuitsim.atomic import write_text_atomic
from circuitsim.figure_style import (
    MARK,
    REFERENCE,
    SINGLE_COLUMN,
    house_style,
    legend_outside,
    new_figure,
    save_figure,
    series_style,
)

if TYPE_CHECKING:
    from circuitsim.compare.sweep import SweepResult


class SweepPlotWarning(UserWarning):
    """Something the sweep's figure cannot show (the CSV has every value)."""


def save_sweep(
    result: SweepResult,
    folder: str | os.PathLike,
    stem: str = "sweep",
    log: bool = False,
    fmt: str = "png",
    dpi: float | None = None,
) -> list[Path]:
    """Write ``<stem>.csv`` and the figure ``<stem>.<fmt>`` (bifurcation-style plot)
    atomically.

    ``log`` draws the figure's peak axis on a log scale (see :func:`plot_sweep`); ``dpi``
    is a PNG's resolution (default the house style's).

    Returns
    -------
    list of Path
        The files written.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    csv_path, figure_path = folder / f"{stem}.csv", folder / f"{stem}.{fmt}"
    write_text_atomic(csv_path, result.csv_text())
    plot_sweep(result, figure_path, log=log, dpi=dpi)
    return [csv_path, figure_path]


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


@house_style
def plot_sweep(
    result: SweepResult, path: str | os.PathLike, log: bool = False, dpi: float | None = None
) -> None:
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
    dpi : float, optional
        Resolution of a PNG, dots per inch (default the house style's).
    """
    fig = new_figure(1.4 * SINGLE_COLUMN, 3.6)
    ax = fig.subplots()
    scale, unit = (1e3, "mm") if result.state_unit == "m" else (1.0, result.state_unit)
    peak_all, peak_late, log = _log_drawable(result, log)
    whole = {**REFERENCE, "linewidth": 1.6}
    ax.plot(result.values, peak_all * scale, marker="s", ms=3, label="whole run", **whole)
    ax.plot(
        result.values,
        peak_late * scale,
        ms=3,
        label=f"last {result.window:g} s",
        **series_style(0, marker=True),
    )
    if log:
        ax.set_yscale("log")
    if result.critical is not None:
        ax.axvline(
            result.critical,
            **MARK,
            label=f"critical {result.parameter} = {result.critical:.4g} {result.unit}",
        )
    ax.set_xlabel(f"{result.parameter} ({result.unit})" if result.unit else result.parameter)
    ax.set_ylabel(f"max |{result.state}| ({unit})")
    ax.set_title(f"peak |{result.state}| against {result.parameter} ({result.engine} engine)")
    legend_outside(fig, ax, ncols=2)
    save_figure(fig, path, dpi)
