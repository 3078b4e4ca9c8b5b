"""Figures of a direct ODE solution: displacement, velocity and phase portrait (paper Fig. 4),
and every state of any model against time (``ode --plot``).

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


LEGEND_ENTRIES = 12  # states named in one panel's legend; more would hide the traces


def plot_states(
    path: str | os.PathLike,
    result: OdeResult,
    title: str = "",
    time_unit: str = "s",
    samples: int = 20001,
    dpi: int = 90,
    state: str | None = None,
) -> Figure:
    """Draw every state against time, one panel per unit, and save to ``path``.

    States sharing a unit share a panel (the wheelset: m, rad, m/s, rad/s), so a model of
    any size gives a figure of a few panels. When ``state`` (default: the first) is a
    coordinate with a rate ``<q>_dot`` (a second-order model; a rate's own coordinate is
    taken for a rate) a phase portrait of that pair ends the figure, with the kinks marked.

    Parameters
    ----------
    path : path-like
        Figure file to write, in the format of its suffix (PNG, PDF, SVG ...).
    result : OdeResult
        From :func:`circuitsim.mechanics.solve`.
    title : str
        Figure title (e.g. the parameters of the run).
    time_unit : str
        The model's time unit (``"s"``; ``""`` for a dimensionless time).
    samples : int
        Dense-output samples over the span.
    dpi : int
        Resolution.
    state : str, optional
        The phase portrait's coordinate (or its rate).

    Returns
    -------
    Figure
        The figure written (its axes carry the labels).
    """
    state = result.states[0] if state is None else state
    if state.endswith("_dot") and state[: -len("_dot")] in result.states:
        state = state[: -len("_dot")]
    t = np.linspace(result.t[0], result.t[-1], samples)
    x = result.sol(t)
    groups: dict[str, list[int]] = {}
    for index, unit in enumerate(result.units):
        groups.setdefault(unit, []).append(index)
    first, rate = state, f"{state}_dot"
    phase = first in result.states and rate in result.states
    panels = len(groups) + phase
    figure = Figure(figsize=(9, 1.2 + 2.2 * panels))
    axes = np.atleast_1d(figure.subplots(panels, 1))
    time_label = f"time ({time_unit})" if time_unit else "time (dimensionless)"
    for axis, (unit, members) in zip(axes, groups.items(), strict=False):
        for index in members:
            label = result.states[index] if members.index(index) < LEGEND_ENTRIES else None
            axis.plot(t, x[index], linewidth=0.8, label=label)
        names = ", ".join(result.states[i] for i in members[:3])
        more = f" (+{len(members) - 3})" if len(members) > 3 else ""
        axis.set(xlabel=time_label, ylabel=f"{names}{more} ({unit or '1'})")
        if len(members) > 1:
            axis.legend(loc="upper right", fontsize=7, ncol=min(4, len(members)))
    if phase:
        axis = axes[-1]
        d, v = result.states.index(first), result.states.index(rate)
        axis.plot(x[d], x[v], color="tab:green", linewidth=0.6)
        if len(result.kinks):
            k = result.sol(result.kinks)
            axis.plot(k[d], k[v], ".", color="black", markersize=2, label="kinks")
            axis.legend(loc="upper right", fontsize=7)
        axis.set(
            xlabel=f"{first} ({result.units[d] or '1'})",
            ylabel=f"{rate} ({result.units[v] or '1'})",
            title="phase portrait",
        )
    for axis in axes:
        axis.grid(True, linewidth=0.3)
    if title:
        figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    save_figure(figure, path, dpi)
    return figure
