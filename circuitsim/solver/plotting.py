"""A quick figure of simulation results: one panel for voltages, one for currents."""

from __future__ import annotations

import os

from circuitsim.atomic import write_figure_atomic
from circuitsim.solver.waveforms import Waveforms


def plot_waveforms(waves: Waveforms, path: str | os.PathLike, title: str = "") -> None:
    """Save a PNG/PDF/SVG (by ``path``'s suffix) of every signal in ``waves`` against time.

    Voltages (``v(...)``) share the top panel, currents (``i(...)``) the bottom one; a panel
    with no signals is left out. Signals inside subcircuit instances (names with a dot, such
    as ``v(xu1a.mid)``) are left out when top-level ones exist: a macromodel's internals would
    bury the circuit's own traces. Legends go beside the panels.
    """
    from matplotlib.figure import Figure  # here: a run without --plot does not load it

    names = [n for n in waves.names if "." not in n] or waves.names
    groups = [
        ("voltage (V)", [n for n in names if n.startswith("v(")]),
        ("current (A)", [n for n in names if not n.startswith("v(")]),
    ]
    groups = [g for g in groups if g[1]]
    fig = Figure(figsize=(10, 3.5 * max(len(groups), 1)))
    axes = fig.subplots(len(groups) or 1, 1, sharex=True, squeeze=False)
    for ax, (label, names) in zip(axes[:, 0], groups, strict=False):
        for name in names:
            ax.plot(
                waves.time, waves[name], label=name, marker="." if len(waves.time) < 3 else None
            )
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        ax.legend(
            fontsize="x-small",
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            ncol=1 + len(names) // 14,
            frameon=False,
        )
    axes[-1, 0].set_xlabel("time (s)")
    if title:
        axes[0, 0].set_title(title)
    write_figure_atomic(fig, path, bbox_inches="tight")
