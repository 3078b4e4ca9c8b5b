"""The hunting study's files: its CSV and its bifurcation diagram (PNG)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from circuitsim.atomic import write_figure_atomic, write_text_atomic
from circuitsim.studies.hunting_result import PATHS, HuntingResult

_STYLE = {  # (path, direction): line style, marker, colour
    ("ode", "up"): ("-", "^", "C0"),
    ("ode", "down"): ("-", "v", "C1"),
    ("circuit", "up"): ("none", "o", "C0"),
    ("circuit", "down"): ("none", "s", "C1"),
}


def save_hunting(result: HuntingResult, folder: str | os.PathLike, stem: str = "hunting"):
    """Write ``<stem>.csv`` and ``<stem>.png`` atomically; returns the paths written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    csv_path, png_path = folder / f"{stem}.csv", folder / f"{stem}.png"
    write_text_atomic(csv_path, result.csv_text())
    plot_hunting(result, png_path)
    return [csv_path, png_path]


def _label(value: float | None, unit: str) -> str:
    return "none" if value is None else f"{value:g} {unit}".strip()


def plot_hunting(result: HuntingResult, path: str | os.PathLike) -> None:
    """Amplitude against speed: one panel per flange setting, both paths and directions,
    the linear critical speed and each path's nonlinear critical speeds marked.

    The flange-on panel has a linear axis (the cycle's branch); the flange-off panel a log
    axis (decay and growth of the linear wheelset), unbounded steps drawn at the bound.
    """
    from matplotlib.figure import Figure  # here: the CSV alone does not load it

    flanges = sorted({b.flange for b in result.branches}, reverse=True)
    fig = Figure(figsize=(7.5, 3.6 * len(flanges)))
    axes = np.atleast_1d(fig.subplots(len(flanges), 1, squeeze=False)[:, 0])
    scale, unit = (1e3, "mm") if result.state_unit == "m" else (1.0, result.state_unit)
    bound = result.settings.bound * scale
    for ax, flange in zip(axes, flanges, strict=True):
        for b in (b for b in result.branches if b.flange == flange):
            style, marker, colour = _STYLE[(b.path, b.direction)]
            amplitude = np.where(
                [s == "unbounded" for s in b.status], bound, np.asarray(b.amplitude) * scale
            )
            ax.plot(
                b.speeds, amplitude, ls=style, marker=marker, ms=4 if b.path == "ode" else 6,
                color=colour, mfc=colour if b.path == "ode" else "none", lw=1,
                label=f"{b.path}, {b.direction}",
            )  # fmt: skip
        if result.linear_critical is not None:
            ax.axvline(result.linear_critical, color="C3", ls="--", lw=1)
        notes = [f"linear critical {_label(result.linear_critical, result.unit)}"]
        for path_name, ls in zip(PATHS, (":", "-."), strict=True):
            up, down = result.critical(path_name, flange)
            for value, colour in ((up, "C0"), (down, "C1")):
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
        ax.text(
            0.01, 0.97, "\n".join(notes), transform=ax.transAxes, va="top", fontsize=7,
            bbox={"boxstyle": "round,pad=0.3", "fc": "white", "ec": "0.8", "alpha": 0.9},
        )  # fmt: skip
        if not flange:
            ax.set_yscale("log")
            ax.axhline(bound, color="0.5", lw=0.8, ls=":")
        ax.set_ylabel(f"amplitude max |{result.state}| ({unit})")
        ax.set_title(
            f"flange {'on' if flange else 'off'}: last {result.settings.record:g} s after "
            f"{result.settings.settle:g} s settling per step",
            fontsize=9,
        )
        ax.grid(True, alpha=0.3)
        ax.legend(loc="lower right", fontsize=7, ncol=2)
    axes[-1].set_xlabel(f"{result.parameter} ({result.unit})" if result.unit else result.parameter)
    fig.suptitle("hunting: limit-cycle amplitude, speed swept up then down", fontsize=10)
    fig.tight_layout()
    write_figure_atomic(fig, path, format="png", dpi=120)
