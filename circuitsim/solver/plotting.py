"""Quick figures of simulation results: traces against time, or a Bode plot of an .ac sweep."""

from __future__ import annotations

import os

from circuitsim.figure_style import DOUBLE_COLUMN, house_style, new_figure, save_figure
from circuitsim.solver.waveforms import Waveforms


@house_style
def plot_waveforms(
    waves: Waveforms, path: str | os.PathLike, title: str = "", dpi: float | None = None
) -> None:
    """Save a PNG/PDF/SVG (by ``path``'s suffix) of every signal in ``waves`` against time.

    Voltages (``v(...)``) share the top panel, currents (``i(...)``) the bottom one; a panel
    with no signals is left out. Signals inside subcircuit instances (names with a dot, such
    as ``v(xu1a.mid)``) are left out when top-level ones exist: a macromodel's internals would
    bury the circuit's own traces. Legends go beside the panels. House style
    (:mod:`circuitsim.figure_style`); ``dpi`` of a PNG (default the house style's).
    """

    names = [n for n in waves.names if "." not in n] or waves.names
    groups = [
        ("voltage (V)", [n for n in names if n.startswith("v(")]),
        ("current (A)", [n for n in names if not n.startswith("v(")]),
    ]
    groups = [g for g in groups if g[1]]
    fig = new_figure(DOUBLE_COLUMN, 2.8 * max(len(groups), 1) + 0.4)
    axes = fig.subplots(len(groups) or 1, 1, sharex=True, squeeze=False)
    for ax, (label, names) in zip(axes[:, 0], groups, strict=False):
        for name in names:
            ax.plot(
                waves.time, waves[name], label=name, marker="." if len(waves.time) < 3 else None
            )
        ax.set_ylabel(label)
        ax.legend(
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            ncol=1 + len(names) // 14,
            frameon=False,
        )
    axes[-1, 0].set_xlabel("time (s)")
    if title:
        axes[0, 0].set_title(title)
    save_figure(fig, path, dpi)


@house_style
def plot_bode(
    waves: Waveforms, path: str | os.PathLike, title: str = "", dpi: float | None = None
) -> None:
    """Save a Bode plot of an ``.ac`` sweep: magnitude (dB) above, phase (degrees) below,
    against frequency (Hz, logarithmic), one line per signal.

    ``waves`` holds ``vm(...)``/``vp(...)`` and ``im(...)``/``ip(...)`` pairs (as both
    engines return them). Signals inside subcircuit instances are left out when top-level
    ones exist, as in :func:`plot_waveforms`; so is a signal that is zero at every frequency
    (no path from the excitation), which has no level in dB. House style; ``dpi`` of a PNG
    (default the house style's).
    """
    import numpy as np

    pairs = [n for n in waves.names if n[1:2] == "m" and n[0] in "vi"]
    pairs = [n for n in pairs if "." not in n] or pairs
    pairs = [n for n in pairs if np.any(waves[n] > 0)]
    fig = new_figure(DOUBLE_COLUMN, 5.2)
    magnitude, phase = fig.subplots(2, 1, sharex=True)
    for name in pairs:
        label = name[0] + name[2:]
        with np.errstate(divide="ignore"):
            magnitude.semilogx(waves.time, 20 * np.log10(waves[name]), label=label)
        phase.semilogx(waves.time, waves[name[0] + "p" + name[2:]], label=label)
    magnitude.set_ylabel("magnitude (dB re 1 V or 1 A)")
    phase.set_ylabel("phase (degrees)")
    phase.set_xlabel("frequency (Hz)")
    for ax in (magnitude, phase):
        ax.grid(True, which="both")
    if pairs:
        magnitude.legend(
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            ncol=1 + len(pairs) // 14,
            frameon=False,
        )
    if title:
        magnitude.set_title(title)
    save_figure(fig, path, dpi)
