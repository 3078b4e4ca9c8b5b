"""Figures of a direct ODE solution: displacement, velocity and phase portrait (paper Fig. 4),
and every state of any model against time (``ode --plot``).

Written atomically in the house style (:mod:`circuitsim.figure_style`): lengths in mm.
"""

from __future__ import annotations

import os

import numpy as np
from matplotlib.figure import Figure

from circuitsim.figure_style import (
    DOUBLE_COLUMN,
    display_unit,
    house_style,
    legend_outside,
    new_figure,
    save_figure,
    series_style,
)
from circuitsim.mechanics.solve import OdeResult


def default_pair(result: OdeResult) -> tuple[str, str]:
    """The displacement and velocity states to draw: ``q`` and ``q_dot`` if the model has them
    (second order: the first coordinate), else the first two states."""
    first = result.states[0]
    rate = f"{first}_dot"
    if rate in result.states:
        return first, rate
    return first, result.states[min(1, len(result.states) - 1)]


@house_style
def plot_response(
    path: str | os.PathLike,
    result: OdeResult,
    displacement: str | None = None,
    velocity: str | None = None,
    title: str = "",
    samples: int = 20001,
    dpi: float | None = None,
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
    dpi : float, optional
        Resolution of a PNG, dots per inch (default the house style's).
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
    d_unit, d_factor = display_unit(result.units[result.states.index(displacement)])
    v_unit, v_factor = display_unit(result.units[result.states.index(velocity)])
    d, v = d * d_factor, v * v_factor

    figure = new_figure(DOUBLE_COLUMN, 2.6)
    axes = figure.subplots(1, 3)
    line = series_style(0)
    axes[0].plot(t, d, **line)
    axes[0].set(xlabel="time (s)", ylabel=f"{displacement} ({d_unit})", title="displacement")
    axes[1].plot(t, v, **line)
    axes[1].set(xlabel="time (s)", ylabel=f"{velocity} ({v_unit})", title="velocity")
    axes[2].plot(d, v, **{**line, "linewidth": 0.6})
    axes[2].set(
        xlabel=f"{displacement} ({d_unit})", ylabel=f"{velocity} ({v_unit})", title="phase portrait"
    )
    if len(result.kinks):
        # where the piecewise-linear terms switch branch (the wheelset: flange contact)
        k = result.sol(result.kinks)
        axes[2].plot(
            k[result.states.index(displacement)] * d_factor,
            k[result.states.index(velocity)] * v_factor,
            "o",
            color=series_style(1)["color"],
            markersize=2.5,
            label="kinks (a piecewise-linear term switches branch)",
        )
        legend_outside(figure, axes[2])
    if title:
        figure.suptitle(title)
    save_figure(figure, path, dpi)


LEGEND_ENTRIES = 12  # states named in one panel's legend; more would hide the traces


@house_style
def plot_states(
    path: str | os.PathLike,
    result: OdeResult,
    title: str = "",
    time_unit: str = "s",
    samples: int = 20001,
    dpi: float | None = None,
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
    dpi : float, optional
        Resolution of a PNG, dots per inch (default the house style's).
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
    figure = new_figure(DOUBLE_COLUMN, 0.9 + 2.0 * panels)
    axes = np.atleast_1d(figure.subplots(panels, 1))
    time_label = f"time ({time_unit})" if time_unit else "time (dimensionless)"
    shown_units = [display_unit(unit) for unit in result.units]
    x = x * np.array([factor for _, factor in shown_units])[:, None]
    for axis, (unit, members) in zip(axes, groups.items(), strict=False):
        for order, index in enumerate(members):
            label = result.states[index] if order < LEGEND_ENTRIES else None
            axis.plot(t, x[index], label=label, **series_style(order))
        names = ", ".join(result.states[i] for i in members[:3])
        more = f" (+{len(members) - 3})" if len(members) > 3 else ""
        axis.set(xlabel=time_label, ylabel=f"{names}{more} ({display_unit(unit)[0] or '1'})")
        if len(members) > 1:
            axis.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))
    if phase:
        axis = axes[-1]
        d, v = result.states.index(first), result.states.index(rate)
        axis.plot(x[d], x[v], **{**series_style(0), "linewidth": 0.6})
        if len(result.kinks):
            k = result.sol(result.kinks) * np.array([f for _, f in shown_units])[:, None]
            axis.plot(k[d], k[v], "o", color=series_style(1)["color"], markersize=2.5,
                      label="kinks")  # fmt: skip
            axis.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))
        axis.set(
            xlabel=f"{first} ({shown_units[d][0] or '1'})",
            ylabel=f"{rate} ({shown_units[v][0] or '1'})",
            title="phase portrait",
        )
    if title:
        figure.suptitle(title)
    save_figure(figure, path, dpi)
    return figure
