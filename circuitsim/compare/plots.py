"""Circuit traces drawn over the reference's (the paper's Fig. 6 style), written atomically.

Kept small on disk (PNG, ~100 dpi) so that the validation figures can be committed.
"""

from __future__ import annotations

import os

import numpy as np
from matplotlib.figure import Figure

from circuitsim.atomic import write_figure_atomic
from circuitsim.compare.mapping import Trace, resample

# Solid thin lines in distinct colours over a wide grey reference: dashes over dense oscillations
# look like noise and triple the PNG size.
_STYLES = [
    {"color": "tab:red", "linewidth": 0.7},
    {"color": "tab:blue", "linewidth": 0.7},
    {"color": "tab:green", "linewidth": 0.7},
    {"color": "tab:purple", "linewidth": 0.7},
]


def save_figure(figure, path: str | os.PathLike, dpi: int = 90) -> None:
    """Render ``figure`` in the format of ``path``'s suffix (PNG without one) and write it
    atomically to ``path``."""
    write_figure_atomic(figure, path, dpi=dpi)


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
    dpi: int = 72,
) -> None:
    """Each state's circuit trace(s) over the reference trace, one panel per state.

    With ``errors``, a second panel per state shows circuit minus reference: traces that agree
    to a line width differ where the comparison lives.

    Parameters
    ----------
    path : path
        Figure to write, in the format of its suffix (PNG, PDF, SVG ...).
    reference : dict of str to (ndarray, ndarray)
        Per state ``(t, values)``, model seconds and physical units.
    circuits : dict of str to dict of str to (ndarray, ndarray)
        Per curve label (``"builtin, ideal"`` ...) the circuit's state traces, already mapped.
    states : list of str, optional
        Panels to draw (default: the reference's states).
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
    dpi : int
        Resolution.
    """
    states = states or list(reference)
    units = units or {}
    scales = scales or {}
    rows = 2 * len(states) if errors else len(states)
    figure = Figure(figsize=(6.4, 1.5 * rows + 0.6))
    axes = figure.subplots(rows, 1, sharex=True, squeeze=False)
    panels = axes[::2, 0] if errors else axes[:, 0]
    for axis, state in zip(panels, states, strict=True):
        factor = scales.get(state, 1.0)
        grid = _grid(reference[state], n_points)
        t, values = grid, resample(reference[state], grid)
        axis.plot(t, values * factor, color="0.55", linewidth=2.4, label=reference_label)
        for style, (label, traces) in zip(_STYLES * 4, circuits.items(), strict=False):
            if state in traces:
                tc = _grid(traces[state], n_points)
                vc = resample(traces[state], tc)
                axis.plot(tc, vc * factor, label=f"circuit ({label})", **style)
        unit = units.get(state, "")
        axis.set_ylabel(f"{state} ({unit})" if unit else state, fontsize=8)
        axis.grid(True, alpha=0.3)
        if errors:
            _error_panel(
                axes[2 * states.index(state) + 1, 0], state, reference, circuits, factor, n_points
            )
            axes[2 * states.index(state) + 1, 0].set_ylabel(
                f"error ({unit})" if unit else "error", fontsize=8
            )
    axes[0, 0].legend(loc="upper right", fontsize=7, ncol=2)
    axes[-1, 0].set_xlabel("model time (s)")
    if title:
        figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    save_figure(figure, path, dpi)


def _grid(trace: Trace, n_points: int) -> np.ndarray:
    t = trace[0]
    return np.linspace(t[0], t[-1], n_points)


def _error_panel(axis, state, reference, circuits, factor, n_points: int) -> None:
    grid = _grid(reference[state], n_points)
    base = resample(reference[state], grid)
    for style, (label, traces) in zip(_STYLES * 4, circuits.items(), strict=False):
        if state in traces:
            t_c = traces[state][0]
            inside = (grid >= t_c[0]) & (grid <= t_c[-1])
            difference = resample(traces[state], grid[inside]) - base[inside]
            axis.plot(grid[inside], difference * factor, label=label, **style)
    axis.grid(True, alpha=0.3)
