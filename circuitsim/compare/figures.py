"""Figures of a direct ODE solution: displacement, velocity and phase portrait (paper Fig. 4).

Written atomically as PNG; small enough on disk to commit.
"""

from __future__ import annotations

import os

import numpy as np
from matplotlib.figure import Figure

from circuitsim.compare.plots import save_figure
from circuitsim.mechanics.solve import OdeResult


def default_pair(result: OdeResult) -> tuple[str, str]:
    """The displacement and velocity states to draw: ``q`` and ``q_dot`` if the model has them
    (second order: the first coordinate), else the first two states."""
    first = result.states[0]
    rate = f"{first}_dot"
    if rate in result.states:
        return first, rate
    return first, result.states[min(1, len(result.states) - 1)]


def plot_response(
    path: str | os.PathLike,
    result: OdeResult,
    displacement: str | None = None,
    velocity: str | None = None,
    title: str = "",
    samples: int = 20001,
    dpi: int = 90,
) -> None:
    """Draw displacement(t), velocity(t) and velocity against displacement, save to ``path``.

    Parameters
    ----------
    path : path-like
        Figure file to write, in the format of its suffix (PNG, PDF, SVG ...).
    result : OdeResult
        From :func:`circuitsim.mechanics.solve`.
    displacement, velocity : str, optional
        State names (default: :func:`default_pair`).
    title : str
        Figure title (e.g. the parameters of the run).
    samples : int
        Dense-output samples over the span.
    dpi : int
        Resolution.
    """
    first, second = default_pair(result)
    displacement = displacement or first
    velocity = velocity or second
    for name in (displacement, velocity):
        if name not in result.states:
            raise KeyError(f"unknown state {name!r} (states: {', '.join(result.states)})")
    t = np.linspace(result.t[0], result.t[-1], samples)
    x = result.sol(t)
    d = x[result.states.index(displacement)]
    v = x[result.states.index(velocity)]
    d_unit = result.units[result.states.index(displacement)]
    v_unit = result.units[result.states.index(velocity)]

    figure = Figure(figsize=(12, 3.6))
    axes = figure.subplots(1, 3)
    axes[0].plot(t, d, color="tab:blue", linewidth=0.9)
    axes[0].set(xlabel="time (s)", ylabel=f"{displacement} ({d_unit})", title="displacement")
    axes[1].plot(t, v, color="tab:red", linewidth=0.9)
    axes[1].set(xlabel="time (s)", ylabel=f"{velocity} ({v_unit})", title="velocity")
    axes[2].plot(d, v, color="tab:green", linewidth=0.6)
    axes[2].set(
        xlabel=f"{displacement} ({d_unit})", ylabel=f"{velocity} ({v_unit})", title="phase portrait"
    )
    if len(result.kinks):
        # where the piecewise-linear terms switch branch (the wheelset: flange contact)
        k = result.sol(result.kinks)
        axes[2].plot(
            k[result.states.index(displacement)],
            k[result.states.index(velocity)],
            ".",
            color="black",
            markersize=2,
            label="kinks",
        )
        axes[2].legend(loc="upper right", fontsize=7)
    for axis in axes:
        axis.grid(True, linewidth=0.3)
    if title:
        figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    save_figure(figure, path, dpi)
