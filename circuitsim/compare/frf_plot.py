"""Bode figures of frequency response functions: the model's and its circuits', per state."""

from __future__ import annotations

import os

import numpy as np

from circuitsim.figure_style import (
    DOUBLE_COLUMN,
    SERIES,
    house_style,
    legend_outside,
    new_figure,
    save_figure,
)
from circuitsim.mechanics.frf import FrequencyResponse

# distinct in grey too: the model solid black, each engine dashed or dash-dotted
_STYLES = {
    "model": (SERIES[0]["color"], "-"),
    "builtin": (SERIES[1]["color"], "--"),
    "ngspice": (SERIES[2]["color"], "-."),
}


@house_style
def plot_frf(
    responses: dict[str, FrequencyResponse],
    input_name: str,
    path: str | os.PathLike,
    title: str = "",
    dpi: float | None = None,
) -> None:
    """One row per state: magnitude (dB re 1 state unit per input unit) and phase (degrees)
    against model frequency (Hz, logarithmic), one line per source (``"model"``, engines).

    Parameters
    ----------
    responses : dict of str to FrequencyResponse
        On one frequency grid; keys name the lines.
    input_name : str
        Which forcing input's transfer functions.
    path : path
        PNG/PDF/SVG by suffix.
    title : str
        Figure title (default: names the input).
    dpi : float, optional
        Resolution of a PNG, dots per inch (default the house style's).
    """

    first = next(iter(responses.values()))
    states = first.states
    unit_in = first.input_units[first.inputs.index(input_name)] or "input unit"
    fig = new_figure(DOUBLE_COLUMN, 1.9 * len(states) + 1.0)
    axes = fig.subplots(len(states), 2, sharex=True, squeeze=False)
    for row, state in enumerate(states):
        magnitude, phase = axes[row]
        for source, response in responses.items():
            color, style = _STYLES.get(source, (SERIES[3]["color"], ":"))
            h = response.of(input_name, state)
            with np.errstate(divide="ignore"):
                magnitude.semilogx(response.frequencies, 20 * np.log10(np.abs(h)), style,
                                   color=color, label=source)  # fmt: skip
            phase.semilogx(response.frequencies, np.degrees(np.angle(h)), style, color=color)
        unit = first.units[row] or "unit"
        magnitude.set_ylabel(f"{state}\n(dB re 1 {unit}/{unit_in})")
        phase.set_ylabel("phase (degrees)")
        phase.set_ylim(-190, 190)
        phase.set_yticks([-180, -90, 0, 90, 180])
        for ax in (magnitude, phase):
            ax.grid(True, which="both")
    for ax in axes[-1]:
        ax.set_xlabel("frequency (Hz, model time)")
    fig.suptitle(title or f"frequency response from {input_name}")
    legend_outside(fig, axes[0, 0])
    save_figure(fig, path, dpi)
