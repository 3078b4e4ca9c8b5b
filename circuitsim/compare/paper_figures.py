"""The paper's remaining figures: free response (Fig. 3) and stability against speed.
Written atomically as small PNGs.

Fig. 4 (displacement, velocity, phase portrait) is :func:`circuitsim.compare.figures.
plot_response`; the circuit-over-ODE overlay is :func:`circuitsim.compare.plots.plot_overlay`.
"""

from __future__ import annotations

import os

import numpy as np
from matplotlib.figure import Figure

from circuitsim.compare.mapping import Trace
from circuitsim.compare.plots import save_figure


def plot_free_response(
    path: str | os.PathLike,
    responses: dict[float, Trace],
    state: str = "y",
    unit: str = "m",
    scale: float = 1000.0,
    scaled_unit: str = "mm",
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
    """
    figure = Figure(figsize=(5.2 * len(responses), 3.2))
    axes = figure.subplots(1, len(responses))
    axes = np.atleast_1d(axes)
    for axis, (speed, (t, values)) in zip(axes, responses.items(), strict=True):
        axis.plot(t, values * scale, color="tab:blue", linewidth=0.8)
        peak = np.max(np.abs(values[t >= t[-1] - 1.0]))
        axis.set(
            xlabel="time (s)",
            ylabel=f"{state} ({scaled_unit})",
            title=f"V = {speed:g} m/s: max |{state}| over the last second {peak:.3g} {unit}",
        )
        axis.title.set_fontsize(9)
        axis.grid(True, linewidth=0.3)
    figure.tight_layout()
    save_figure(figure, path, dpi=72)


def plot_growth_rate(
    path: str | os.PathLike,
    speeds: np.ndarray,
    rates: np.ndarray,
    critical: float,
    realized: dict[str, list[float]] | None = None,
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
    """
    figure = Figure(figsize=(10.5, 3.4))
    axes = figure.subplots(1, 2)
    colours = ["tab:orange", "tab:green", "tab:purple", "tab:brown"]
    for axis, zoom in zip(axes, (False, True), strict=True):
        mask = np.abs(speeds - critical) <= 2.0 if zoom else np.ones(speeds.size, bool)
        axis.plot(speeds[mask], rates[mask], color="tab:blue", linewidth=1.2)
        axis.axhline(0.0, color="black", linewidth=0.6)
        axis.axvline(critical, color="tab:red", linewidth=1.0, label=f"model V_c = {critical:.4f}")
        bands = sorted((realized or {}).items())
        for colour, (label, values) in zip(colours * 4, bands, strict=False):
            values = [v for v in values if v is not None]
            if not zoom or not values:
                continue
            lo, hi = min(values), max(values)
            if hi - lo > 1e-3:
                axis.axvspan(lo, hi, color=colour, alpha=0.25, label=f"{label}: {lo:.3f}-{hi:.3f}")
            else:
                axis.axvline(
                    lo, color=colour, linestyle="--", linewidth=1.0, label=f"{label}: {lo:.4f}"
                )
        axis.set(
            xlabel="forward speed V (m/s)",
            ylabel="largest Re(eigenvalue) (1/s)",
            title="near the critical speed" if zoom else "linear stability",
        )
        axis.grid(True, linewidth=0.3)
        axis.legend(fontsize=6.5, loc="upper left")
    figure.tight_layout()
    save_figure(figure, path, dpi=72)
