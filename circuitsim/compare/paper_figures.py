"""The paper's remaining figures: free response (Fig. 3) and stability against speed.
Written atomically in the house style (:mod:`circuitsim.figure_style`).

Fig. 4 (displacement, velocity, phase portrait) is :func:`circuitsim.compare.figures.
plot_response`; the circuit-over-ODE overlay is :func:`circuitsim.compare.plots.plot_overlay`.
"""

from __future__ import annotations

import os

import numpy as np

from circuitsim.compare.mapping import Trace
from circuitsim.figure_style import (
    DOUBLE_COLUMN,
    MARK,
    house_style,
    legend_outside,
    new_figure,
    save_figure,
    series_style,
)


@house_style
def plot_free_response(
    path: str | os.PathLike,
    responses: dict[float, Trace],
    state: str = "y",
    unit: str = "m",
    scale: float = 1000.0,
    scaled_unit: str = "mm",
    dpi: float | None = None,
) -> None:
    """Free responses at several speeds, one panel each (the paper's Fig. 3).

    Parameters
    ----------
    path : path-like
        PNG to write.
    responses : dict of float to (ndarray, ndarray)
        Speed (m/s) -> ``(t, values)`` of ``state``, model seconds and SI units.
    state, unit : str
        For the axis label.
    scale, scaled_unit : float, str
        Display factor and its unit (metres shown as millimetres).
    dpi : float, optional
        Resolution of a PNG, dots per inch (default the house style's).
    """
    figure = new_figure(DOUBLE_COLUMN, 2.6)
    axes = figure.subplots(1, len(responses))
    axes = np.atleast_1d(axes)
    for axis, (speed, (t, values)) in zip(axes, responses.items(), strict=True):
        axis.plot(t, values * scale, **series_style(0))
        peak = np.max(np.abs(values[t >= t[-1] - 1.0])) * scale
        axis.set(
            xlabel="time (s)",
            ylabel=f"{state} ({scaled_unit})",
            title=f"V = {speed:g} m/s\nmax |{state}| over the last second {peak:.4g} {scaled_unit}",
        )
    save_figure(figure, path, dpi)


@house_style
def plot_growth_rate(
    path: str | os.PathLike,
    speeds: np.ndarray,
    rates: np.ndarray,
    critical: float,
    realized: dict[str, list[float]] | None = None,
    dpi: float | None = None,
) -> None:
    """Largest real part of the eigenvalues against speed, with the critical speed(s).

    Parameters
    ----------
    path : path-like
        PNG to write.
    speeds : ndarray, shape (p,)
        m/s.
    rates : ndarray, shape (p,)
        Largest real part at each speed, 1/s.
    critical : float
        The model's critical speed, m/s.
    realized : dict of str to list of float, optional
        Label -> critical speeds of realized circuits (from their netlists' mapping checks);
        several values are drawn as the band they span.
    dpi : float, optional
        Resolution of a PNG, dots per inch (default the house style's).
    """
    figure = new_figure(DOUBLE_COLUMN, 3.0)
    axes = figure.subplots(1, 2)
    for axis, zoom in zip(axes, (False, True), strict=True):
        mask = np.abs(speeds - critical) <= 2.0 if zoom else np.ones(speeds.size, bool)
        axis.plot(speeds[mask], rates[mask], **series_style(0))
        axis.axhline(0.0, color="0.4", linewidth=0.6)
        axis.axvline(critical, **MARK, label=f"model V_c = {critical:.4f} m/s")
        bands = sorted((realized or {}).items())
        for index, (label, values) in enumerate(bands, start=2):
            style = series_style(index)
            values = [v for v in values if v is not None]
            if not zoom or not values:  # a band of 0.01 m/s is a line over 40-70 m/s
                continue
            lo, hi = min(values), max(values)
            if hi - lo > 1e-3:
                axis.axvspan(lo, hi, color=style["color"], alpha=0.25, hatch="//" * (index % 2),
                             label=f"{label}: {lo:.3f}-{hi:.3f} m/s")  # fmt: skip
            else:
                axis.axvline(lo, **style, label=f"{label}: {lo:.4f} m/s")
        axis.set(
            xlabel="forward speed V (m/s)",
            ylabel="largest Re(eigenvalue) (1/s)",
            title="near the critical speed" if zoom else "linear stability",
        )
    legend_outside(figure, axes[1], ncols=2)
    save_figure(figure, path, dpi)
