"""Circuit traces drawn over the reference's (the paper's Fig. 6 style), written atomically
in the house style (:mod:`circuitsim.figure_style`)."""

from __future__ import annotations

import os

import numpy as np
from matplotlib.figure import Figure

from circuitsim.compare.mapping import Trace, resample
from circuitsim.figure_style import (
    DOUBLE_COLUMN,
    REFERENCE,
    house_style,
    legend_outside,
    new_figure,
    save_figure,
    series_style,
)

__all__ = ["plot_overlay", "save_figure"]


#: States per column of an overlay: more states are drawn in side-by-side columns.
STATES_PER_COLUMN = 6

#: Columns of an overlay at most (a 30-state model: 5 columns of 6).
MAX_COLUMNS = 6


@house_style
def plot_overlay(
    path: str | os.PathLike,
    reference: dict[str, Trace],
    circuits: dict[str, dict[str, Trace]],
    states: list[str] | None = None,
    units: dict[str, str] | None = None,
    title: str = "",
    reference_label: str = "ODE",
    scales: dict[str, float] | None = None,
    errors: bool = False,
    n_points: int = 1500,
    dpi: float | None = None,
    time_unit: str = "s",
) -> Figure:
    """Each state's circuit trace(s) over the reference trace, one panel per state.

    With ``errors``, a second panel per state shows circuit minus reference: traces that agree
    to a line width differ where the comparison lives. Past :data:`STATES_PER_COLUMN` states
    the panels fill side-by-side columns (at most :data:`MAX_COLUMNS`), so that a model of
    many states gives a grid rather than one tall column.

    Parameters
    ----------
    path : path
        Figure to write, in the format of its suffix (PNG, PDF, SVG ...).
    reference : dict of str to (ndarray, ndarray)
        Per state ``(t, values)``, model time and physical units.
    circuits : dict of str to dict of str to (ndarray, ndarray)
        Per curve label (``"builtin, ideal"`` ...) the circuit's state traces, already mapped.
    states : list of str, optional
        Panels to draw, in order (default: the reference's states).
    units : dict of str to str, optional
        Axis units per state.
    title : str
        Figure title.
    reference_label : str
        Legend entry of the reference.
    scales : dict of str to float, optional
        Display factor per state with its unit name folded into ``units`` by the caller
        (e.g. 1000 for metres shown as mm).
    errors : bool
        Add a circuit-minus-reference panel below each state's panel.
    n_points : int
        Every curve is drawn from this many resampled points (keeps the PNG small; 50 points
        per period at 10 Hz over 5 s).
    dpi : float, optional
        Resolution of a PNG, dots per inch (default the house style's).
    time_unit : str
        The model's time unit (``"s"``; ``""`` for a dimensionless time).

    Returns
    -------
    Figure
        The figure written.

    Raises
    ------
    KeyError
        A state of ``states`` that the reference does not have (the CLI checks names first).
    """
    states = states or list(reference)
    units = units or {}
    scales = scales or {}
    columns = min(MAX_COLUMNS, -(-len(states) // STATES_PER_COLUMN))
    per_column = -(-len(states) // columns)
    rows = 2 * per_column if errors else per_column
    if columns == 1:
        size = (DOUBLE_COLUMN, (1.45 if rows <= 4 else 1.1) * rows + 0.9)  # <= a page
    else:  # lower panels in a grid: 5 columns of 6 states with errors stay on one screen
        size = (max(DOUBLE_COLUMN, 3.4 * columns), 1.2 * rows + 0.9)
    figure = new_figure(*size)
    axes = figure.subplots(rows, columns, sharex=True, squeeze=False)
    step = 2 if errors else 1
    for k, state in enumerate(states):
        column, row = divmod(k, per_column)
        axis = axes[step * row, column]
        factor = scales.get(state, 1.0)
        grid = _grid(reference[state], n_points)
        t, values = grid, resample(reference[state], grid)
        axis.plot(t, values * factor, label=reference_label, **REFERENCE)
        for index, (label, traces) in enumerate(circuits.items()):
            style = series_style(index)
            if state in traces:
                tc = _grid(traces[state], n_points)
                vc = resample(traces[state], tc)
                axis.plot(tc, vc * factor, label=f"circuit ({label})", **style)
        unit = units.get(state, "")
        axis.set_ylabel(f"{state} ({unit})" if unit else state)
        if errors:
            below = axes[step * row + 1, column]
            _error_panel(below, state, reference, circuits, factor, n_points)
            below.set_ylabel(f"error ({unit})" if unit else "error")
    for k in range(len(states), per_column * columns):  # the last column's empty slots
        column, row = divmod(k, per_column)
        for extra in range(step):
            axes[step * row + extra, column].set_visible(False)
    legend_outside(figure, axes[0, 0], ncols=min(3, len(circuits) + 1))
    label = f"model time ({time_unit})" if time_unit else "model time (dimensionless)"
    for column in range(columns):
        filled = min(per_column, len(states) - column * per_column)
        axes[step * filled - 1, column].set_xlabel(label)
        axes[step * filled - 1, column].xaxis.set_tick_params(labelbottom=True)
    if title:
        figure.suptitle(title)
    save_figure(figure, path, dpi)
    return figure


def _grid(trace: Trace, n_points: int) -> np.ndarray:
    t = trace[0]
    return np.linspace(t[0], t[-1], n_points)


def _error_panel(axis, state, reference, circuits, factor, n_points: int) -> None:
    grid = _grid(reference[state], n_points)
    base = resample(reference[state], grid)
    for index, (label, traces) in enumerate(circuits.items()):
        style = series_style(index)
        if state in traces:
            t_c = traces[state][0]
            inside = (grid >= t_c[0]) & (grid <= t_c[-1])
            difference = resample(traces[state], grid[inside]) - base[inside]
            axis.plot(grid[inside], difference * factor, label=label, **style)
