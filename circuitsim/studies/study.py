"""A grid study: every variant's circuit run, its peaks in a tidy CSV and, for two parameters,
a map.

The variants are made and run as a sweep's (:func:`circuitsim.compare.sweep.run_sweep`: one
translation, exact resistors, one amplitude scaling; variants that differ only in resistors run
from the base circuit's shared start), by the executor given (in-process threads, or a Dask
cluster: :mod:`circuitsim.studies.execution`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from circuitsim.atomic import write_text_atomic
from circuitsim.compare.sweep import SweepResult, run_sweep
from circuitsim.compare.sweep_measure import Executor
from circuitsim.figure_style import (
    MARK,
    SINGLE_COLUMN,
    house_style,
    legend_outside,
    new_figure,
    save_figure,
)
from circuitsim.mechanics.system import System
from circuitsim.studies.grid import ParameterGrid
from circuitsim.synthesis.options import SynthesisOptions


@dataclass
class GridResult:
    """Peak |state| of every variant of a grid.

    Attributes
    ----------
    grid : ParameterGrid
    sweep : SweepResult
        The run (its ``values`` are the variants' indices; peaks, timings, statistics and
        clipping warnings as for a one-parameter sweep).
    critical : (str, ndarray, ndarray) or None
        A curve to draw on the map: the name of the axis it is a value of, the other axis's
        values and the linear critical value at each (the critical speed against conicity).
    """

    grid: ParameterGrid
    sweep: SweepResult
    critical: tuple[str, np.ndarray, np.ndarray] | None = None

    def metrics(self) -> list[tuple[str, np.ndarray, str]]:
        """(metric name, value per variant, unit) of each metric in the CSV."""
        s = self.sweep
        return [
            (f"max_abs_{s.state}_last_{s.window:g}s", s.peak_late, s.state_unit),
            (f"max_abs_{s.state}_all", s.peak_all, s.state_unit),
        ]

    def csv_text(self) -> str:
        """Tidy table: ``variant,<parameter> (<unit>)...,metric,value,unit``, one row per
        variant and metric, full precision (repr: reads back as the same double)."""
        g = self.grid
        columns = [f"{n} ({u})" if u else n for n, u in zip(g.names, g.units, strict=True)]
        lines = [",".join(["variant", *columns, "metric", "value", "unit"])]
        metrics = self.metrics()
        for k in range(len(g)):
            point = ",".join(repr(float(v)) for v in g.points[k])
            for name, values, unit in metrics:
                lines.append(f"{k},{point},{name},{float(values[k])!r},{unit}")
        return "\n".join(lines) + "\n"


def run_grid(
    systems: Sequence[System],
    grid: ParameterGrid,
    engine: str = "builtin",
    options: SynthesisOptions | None = None,
    state: str | None = None,
    window: float = 1.0,
    workers: int | None = None,
    progress=None,
    ngspice_timeout: float | None = None,
    executor: Executor | None = None,
) -> GridResult:
    """Run the circuit of every variant of ``grid`` (``systems[k]`` is variant k's).

    Parameters as :func:`circuitsim.compare.sweep.run_sweep`; ``executor`` runs the builtin
    engine's variants (default: in-process, ``workers`` threads).

    Raises
    ------
    ComparisonError, SynthesisError, SolverError, NgspiceError, ClusterError
    """
    sweep = run_sweep(
        systems,
        np.arange(len(grid), dtype=float),
        "variant",
        "",
        engine,
        options,
        state=state,
        window=window,
        workers=workers,
        progress=progress,
        ngspice_timeout=ngspice_timeout,
        executor=executor,
        describe=grid.describe,
    )
    return GridResult(grid, sweep)


def save_grid(
    result: GridResult,
    folder: str | os.PathLike,
    stem: str = "sweep",
    log: bool = False,
    fmt: str = "png",
    dpi: float | None = None,
) -> list[Path]:
    """Write ``<stem>.csv`` (tidy) and, for two parameters, ``<stem>.<fmt>`` (the map;
    ``dpi``: a PNG's resolution, default the house style's).

    Returns
    -------
    list of Path
        The files written.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = [folder / f"{stem}.csv"]
    write_text_atomic(written[0], result.csv_text())
    if len(result.grid.names) == 2:
        written.append(folder / f"{stem}.{fmt}")
        plot_map(result, written[1], log=log, dpi=dpi)
    return written


@house_style
def plot_map(
    result: GridResult, path: str | os.PathLike, log: bool = False, dpi: float | None = None
) -> None:
    """The late-window peak over two parameters: a colour map for a full grid, coloured
    points for sets from a file; the linear critical curve drawn when known.

    Parameters
    ----------
    result : GridResult
        Of two parameters.
    path : str or path-like
        PNG file, written atomically.
    log : bool
        Logarithmic colour scale (peaks of 0 shown in the lowest colour).
    dpi : float, optional
        Resolution of a PNG, dots per inch (default the house style's).
    """
    from matplotlib.colors import LogNorm

    g, s = result.grid, result.sweep
    scale, unit = (1e3, "mm") if s.state_unit == "m" else (1.0, s.state_unit)
    peaks = s.peak_late * scale
    norm = None
    if log and np.any(peaks > 0):
        low = float(np.min(peaks[peaks > 0]))
        norm = LogNorm(vmin=low, vmax=max(float(np.max(peaks)), low * 10))
        peaks = np.maximum(peaks, low)
    fig = new_figure(1.4 * SINGLE_COLUMN, 4.0)
    ax = fig.subplots()
    x_name, y_name = g.names
    if g.axes is not None:
        x, y = g.axes
        image = ax.pcolormesh(x, y, peaks.reshape(len(x), len(y)).T, shading="nearest",
                              norm=norm, cmap="viridis")  # fmt: skip
    else:
        image = ax.scatter(g.points[:, 0], g.points[:, 1], c=peaks, s=30, norm=norm,
                           cmap="viridis")  # fmt: skip
    fig.colorbar(image, ax=ax, label=f"max |{s.state}| over the last {s.window:g} s ({unit})")
    if result.critical is not None:
        limits = ax.get_xlim(), ax.get_ylim()  # the grid's range, not the curve's
        along, other, critical = result.critical
        curve = (critical, other) if along == x_name else (other, critical)
        ax.plot(*curve, **MARK, label=f"linear critical {along}")
        ax.set_xlim(*limits[0])
        ax.set_ylim(*limits[1])
        legend_outside(fig, ax)
    x_unit, y_unit = g.units
    ax.set_xlabel(f"{x_name} ({x_unit})" if x_unit else x_name)
    ax.set_ylabel(f"{y_name} ({y_unit})" if y_unit else y_name)
    ax.set_title(f"peak |{s.state}| over {x_name} x {y_name} ({len(g)} variants, {s.engine})")
    save_figure(fig, path, dpi)
