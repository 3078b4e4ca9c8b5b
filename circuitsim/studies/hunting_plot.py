"""The hunting study's files: its CSV and its bifurcation diagram (house style:
:mod:`circuitsim.figure_style`)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from circuitsim.atomic import write_text_atomic
from circuitsim.figure_style import (
    DOUBLE_COLUMN,
    MARK,
    SERIES,
    house_style,
    new_figure,
    save_figure,
)
from circuitsim.studies.hunting_result import PATHS, HuntingResult

_UP, _DOWN = SERIES[0]["color"], SERIES[1]["color"]
_STYLE = {  # (path, direction): line style, marker, colour
    ("ode", "up"): ("-", "^", _UP),
    ("ode", "down"): ("--", "v", _DOWN),
    ("circuit", "up"): ("none", "o", _UP),
    ("circuit", "down"): ("none", "s", _DOWN),
}


def save_hunting(
    result: HuntingResult,
    folder: str | os.PathLike,
    stem: str = "hunting",
    fmt: str = "png",
    dpi: float | None = None,
):
    """Write ``<stem>.csv`` and the figure ``<stem>.<fmt>`` atomically; returns the paths
    written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    csv_path, figure_path = folder / f"{stem}.csv", folder / f"{stem}.{fmt}"
    write_text_atomic(csv_path, result.csv_text())
    plot_hunting(result, figure_path, dpi)
    return [csv_path, figure_path]


def _label(value: float | None, unit: str) -> str:
    return "none" if value is None else f"{value:g} {unit}".strip()


@house_style
def plot_hunting(result: HuntingResult, path: str | os.PathLike, dpi: float | None = None):
    """Amplitude against speed: one panel per flange setting, both paths and directions,
    the linear critical speed and each path's nonlinear critical speeds marked.

    The flange-on panel has a linear axis (the cycle's branch); the flange-off panel a log
    axis (decay and growth of the linear wheelset). A step that grew past the bound is drawn
    as an open upward triangle on the labelled bound line (its amplitude is not known), and
    a step that was pushed again (the one before it died out or grew past the bound) is
    ringed: its amplitude is the push's, not the previous cycle's. Returns the Figure.
    """
    flanges = sorted({b.flange for b in result.branches}, reverse=True)
    fig = new_figure(DOUBLE_COLUMN, 0.6 + 3.9 * len(flanges))
    axes = np.atleast_1d(fig.subplots(len(flanges), 1, squeeze=False)[:, 0])
    scale, unit = (1e3, "mm") if result.state_unit == "m" else (1.0, result.state_unit)
    bound = result.settings.bound * scale
    for ax, flange in zip(axes, flanges, strict=True):
        past_bound = repushed = False
        for b in (b for b in result.branches if b.flange == flange):
            style, marker, colour = _STYLE[(b.path, b.direction)]
            speeds = np.asarray(b.speeds, dtype=float)
            unbounded = np.array([s == "unbounded" for s in b.status], dtype=bool)
            amplitude = np.where(unbounded, np.nan, np.asarray(b.amplitude, dtype=float) * scale)
            ax.plot(
                speeds, amplitude, ls=style, marker=marker, ms=4 if b.path == "ode" else 6,
                color=colour, mfc=colour if b.path == "ode" else "none", lw=1,
                label=f"{b.path}, {b.direction}",
            )  # fmt: skip
            if unbounded.any():
                past_bound = True
                ax.plot(speeds[unbounded], np.full(unbounded.sum(), bound), ls="none",
                        marker=r"$\uparrow$", ms=9, color=colour)  # fmt: skip
            again = np.asarray(b.pushed, dtype=bool).copy()
            again[:1] = False  # the first step of every branch starts from the push
            again &= ~unbounded
            if again.any():
                repushed = True
                ax.plot(speeds[again], amplitude[again], ls="none", marker="o", ms=10,
                        mfc="none", mec="0.35", mew=0.8)  # fmt: skip
        if np.isfinite(bound) and (past_bound or not flange):
            ax.axhline(bound, color="0.45", lw=0.8, ls=":",
                       label=f"bound {bound:g} {unit} (arrow: grew past it)")  # fmt: skip
        if repushed:
            again_label = "pushed again (the step before died out or grew past the bound)"
            ax.plot([], [], ls="none", marker="o", ms=10, mfc="none", mec="0.35", mew=0.8,
                    label=again_label)  # fmt: skip
        if result.linear_critical is not None:
            ax.axvline(result.linear_critical, **MARK)
        notes = [f"linear critical {_label(result.linear_critical, result.unit)}"]
        for path_name, ls in zip(PATHS, (":", "-."), strict=True):
            up, down = result.critical(path_name, flange)
            for value, colour in ((up, _UP), (down, _DOWN)):
                if value is not None:
                    ax.axvline(value, color=colour, ls=ls, lw=1)
            if result.branch(path_name, "up", flange) is not None:
                if up is None and down is None:
                    grows, _ = result.onset(path_name, flange)
                    notes.append(
                        f"{path_name}: no limit cycle; grows from {_label(grows, result.unit)}"
                    )
                else:
                    notes.append(
                        f"{path_name}: cycle appears {_label(up, result.unit)} (up), "
                        f"vanishes {_label(down, result.unit)} (down)"
                    )
        if not flange:
            ax.set_yscale("log")
        ax.set_ylabel(f"amplitude max |{result.state}| ({unit})")
        ax.set_title(
            f"flange {'on' if flange else 'off'}: last {result.settings.record:g} s after "
            f"{result.settings.settle:g} s settling per step"
        )
        for note in notes:  # in the legend, beside the data rather than over it
            ax.plot([], [], ls="none", label=note)
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncols=2)
    for ax in axes:  # every panel: its legend sits below it
        ax.set_xlabel(f"{result.parameter} ({result.unit})" if result.unit else result.parameter)
    fig.suptitle("hunting: limit-cycle amplitude, speed swept up then down")
    save_figure(fig, path, dpi)
    return fig
