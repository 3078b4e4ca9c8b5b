"""The house style of every figure circuitsim draws: print sizes, fonts, line styles, units,
and the one way a figure is written (format and resolution).

A figure is laid out at the size it is printed (:data:`SINGLE_COLUMN` or :data:`DOUBLE_COLUMN`
wide, inches), so that the point sizes of :data:`RC` are the sizes on paper (>= 8 pt). The
series styles pair colours of distinct lightness with distinct line styles and markers, so
that a figure printed in grey still tells its curves apart. Legends go outside the axes
(:func:`legend_outside`). Lateral displacements are drawn in millimetres everywhere
(:func:`display_unit`). Matplotlib's settings are applied only inside :func:`house_style`'s
context (``matplotlib.rc_context``), never to the global state.

This module sits at the package top level (like :mod:`circuitsim.atomic`) so that every room
that plots may import it.
"""

from __future__ import annotations

import contextlib
import functools
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

from circuitsim.atomic import write_figure_atomic

SINGLE_COLUMN = 3.5
"""Width of a one-column figure, inches (a two-column journal page)."""

DOUBLE_COLUMN = 7.2
"""Width of a full-page-width figure, inches."""

FORMATS = ("png", "svg", "pdf")
"""Formats the ``--format`` option offers."""

DEFAULT_FORMAT = "png"

DEFAULT_DPI = 200
"""Resolution of PNG figures, dots per inch (vector formats ignore it for their lines)."""

MIN_FONT_PT = 8.0
"""Smallest text size on paper, points."""

RC: dict[str, Any] = {
    "font.size": 9.0,
    "axes.titlesize": 9.0,
    "axes.labelsize": 9.0,
    "xtick.labelsize": 8.0,
    "ytick.labelsize": 8.0,
    "legend.fontsize": 8.0,
    "figure.titlesize": 10.0,
    "axes.formatter.useoffset": False,  # a ratio axis reads 0.999999, never 1e-6+1
    "axes.formatter.limits": (-5, 6),  # 0.0002 rather than a 1e-4 multiplier
    "axes.grid": True,
    "grid.alpha": 0.3,
    "grid.linewidth": 0.5,
    "lines.linewidth": 1.0,
    "lines.markersize": 4.0,
    "legend.frameon": False,
    "savefig.dpi": DEFAULT_DPI,
    "svg.fonttype": "none",  # text stays text in SVG
    "pdf.fonttype": 42,  # TrueType in PDF (journals refuse Type 3)
}

REFERENCE = {"color": "0.72", "linewidth": 2.6, "linestyle": "-"}
"""The reference (ODE, model) curve: a wide light-grey band the others are drawn over."""

SERIES: tuple[dict[str, Any], ...] = (
    {"color": "#000000", "linestyle": "-", "marker": "o"},
    {"color": "#d55e00", "linestyle": "--", "marker": "s"},
    {"color": "#0072b2", "linestyle": "-.", "marker": "^"},
    {"color": "#e69f00", "linestyle": ":", "marker": "v"},
    {"color": "#009e73", "linestyle": (0, (5, 1, 1, 1, 1, 1)), "marker": "D"},
    {"color": "#cc79a7", "linestyle": (0, (1, 1)), "marker": "x"},
)
"""Series styles in order: colours of distinct lightness (black, vermilion, blue, orange,
green, pink: the Okabe-Ito set) each with its own line style and marker."""

MARK = {"color": "#d55e00", "linestyle": "--", "linewidth": 1.0}
"""A vertical or horizontal mark (critical speed, threshold, bound)."""


def series_style(index: int, marker: bool = False) -> dict[str, Any]:
    """The style of the ``index``-th series (cycling), with or without its marker."""
    style = dict(SERIES[index % len(SERIES)])
    if not marker:
        style.pop("marker")
    return style


_DISPLAY = {"m": ("mm", 1e3)}


def display_unit(unit: str) -> tuple[str, float]:
    """The unit a quantity in ``unit`` is drawn in, and the factor from ``unit`` to it.

    Lengths in metres are drawn in millimetres (the wheelset's lateral displacement and
    clearance are millimetres); every other unit is drawn as it is.

    Returns
    -------
    tuple of (str, float)
        ``("mm", 1000.0)`` for ``"m"``, else ``(unit, 1.0)``.
    """
    return _DISPLAY.get(unit, (unit, 1.0))


@contextlib.contextmanager
def style_context() -> Iterator[None]:
    """Matplotlib's settings of the house style, inside this context only."""
    import matplotlib

    with matplotlib.rc_context(RC):
        yield


F = TypeVar("F", bound=Callable[..., Any])


def house_style(function: F) -> F:
    """Decorator: run a plotting function inside :func:`style_context`."""

    @functools.wraps(function)
    def styled(*args, **kwargs):
        with style_context():
            return function(*args, **kwargs)

    return styled  # type: ignore[return-value]


def new_figure(width: float = DOUBLE_COLUMN, height: float = 3.0):
    """A Figure of print size ``width`` x ``height`` inches with constrained layout (room is
    made for legends placed outside the axes)."""
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), layout="constrained")


def legend_outside(figure, axis=None, ncols: int | None = None, **kwargs) -> None:
    """The legend of ``axis`` (default: the first axes), below the axes of ``figure``, outside
    the data (below rather than above: the suptitle keeps the top). Does nothing when nothing
    is labelled."""
    axis = axis if axis is not None else figure.axes[0]
    handles, labels = axis.get_legend_handles_labels()
    if not handles:
        return
    figure.legend(
        handles,
        labels,
        loc="outside lower center",
        ncols=ncols or min(len(handles), 4),
        **kwargs,
    )


def figure_path(path: str | os.PathLike, fmt: str | None) -> Path:
    """``path`` with the suffix of ``fmt`` (``png``, ``svg``, ``pdf``), or as it is."""
    path = Path(path)
    return path if fmt is None else path.with_suffix(f".{fmt}")


def save_figure(figure, path: str | os.PathLike, dpi: float | None = None) -> None:
    """Write ``figure`` atomically in the format of ``path``'s suffix (PNG without one) at
    ``dpi`` dots per inch (default :data:`DEFAULT_DPI`)."""
    write_figure_atomic(figure, path, dpi=DEFAULT_DPI if dpi is None else dpi)


def robust_range(values, spread: float = 3.0) -> tuple[float, float, int, int]:
    """The range a histogram of ``values`` is drawn over, and the values left outside it.

    The range is the quartiles widened by ``spread`` inter-quartile ranges, cut to the data:
    one circuit at 156 % among thousands near 0.1 % does not squash the rest into one bin.
    When the quartiles coincide (all values within a few equal ones) the range is the data's.

    Parameters
    ----------
    values : array_like
        Finite values (others are ignored).
    spread : float
        Inter-quartile ranges beyond each quartile kept inside.

    Returns
    -------
    tuple of (float, float, int, int)
        ``(low, high, below, above)``: the range and the counts of values under and over it.
    """
    import numpy as np

    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return 0.0, 1.0, 0, 0
    q1, q3 = np.percentile(finite, [25.0, 75.0])
    iqr = q3 - q1
    low, high = float(finite.min()), float(finite.max())
    if iqr > 0:
        low, high = max(low, q1 - spread * iqr), min(high, q3 + spread * iqr)
    if high <= low:  # one value: a range around it
        pad = abs(low) * 1e-9 or 1e-12
        low, high = low - pad, high + pad
    return low, high, int(np.sum(finite < low)), int(np.sum(finite > high))
