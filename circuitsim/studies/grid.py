"""Parameter grids: the full product of a few parameters' values, or sets read from a CSV file.

A grid is a table of variants, one row each, one column per parameter (the model's names and
SI units). A full grid lists the product of its axes with the last parameter varying fastest
(``--param V --values 50,60 --param lambda --values 0.1,0.2``: (50, 0.1), (50, 0.2), (60, 0.1),
(60, 0.2)), and keeps the axes for a map plot.

The CSV file of parameter sets::

    # comments and blank lines are skipped
    V (m/s), lambda
    50, 0.1
    55.5, 0.25

A header of parameter names (a model parameter or one of its options, such as ``speed``; an
optional unit in parentheses must be the parameter's), then one row of numbers per variant.
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import os
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from circuitsim.inputfile import GRID_BYTES, InputTooLargeError, read_text
from circuitsim.studies.errors import GridFileError, StudyError

MAX_VARIANTS = 10_000
"""Most variants a grid may have: each is a circuit simulation of its own."""

Resolve = Callable[[str], tuple[str, str]]
"""Maps a name as written (``speed``, ``V``) to (model parameter name, its unit); raises
KeyError with the reason when the model has no such parameter."""

_HEADER = re.compile(r"^\s*([^()]*?)\s*(?:\(([^()]*)\))?\s*$")


@dataclass(frozen=True)
class ParameterGrid:
    """The variants of a study: parameter values, one row per variant.

    Attributes
    ----------
    names : tuple of str
        Model parameter names (``("V", "lambda")``).
    units : tuple of str
        Their SI units (``""`` for none).
    points : ndarray, shape (variants, parameters)
        The values, SI units.
    axes : tuple of ndarray or None
        A full grid's values of each parameter (``points`` is their product, the last
        varying fastest); None for sets read from a file.
    source : str or None
        The CSV file the sets were read from.
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    points: np.ndarray
    axes: tuple[np.ndarray, ...] | None = None
    source: str | None = None

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @property
    def shape(self) -> tuple[int, ...] | None:
        """A full grid's shape (one length per axis), None for sets from a file."""
        return None if self.axes is None else tuple(len(a) for a in self.axes)

    def assignments(self, index: int) -> list[tuple[str, float]]:
        """Variant ``index``'s (parameter, value) pairs."""
        return [(n, float(v)) for n, v in zip(self.names, self.points[index], strict=True)]

    def describe(self, first: int, last: int | None = None) -> str:
        """Names variant ``first`` (``"V 50 m/s, lambda 0.2"``) or those from ``first`` to
        ``last`` (``"variants 3 (...) to 17 (...)"``) in messages."""

        def one(k: int) -> str:
            parts = (
                f"{n} {float(v):g} {u}".rstrip()
                for n, v, u in zip(self.names, self.points[k], self.units, strict=True)
            )
            return ", ".join(parts)

        if last is None:
            return one(first)
        return f"variants {first} ({one(first)}) to {last} ({one(last)})"


def full_grid(
    names: Sequence[str], units: Sequence[str], axes: Sequence[np.ndarray]
) -> ParameterGrid:
    """The product of ``axes`` (the last varying fastest).

    Raises
    ------
    StudyError
        A parameter named twice, an empty axis, or more than :data:`MAX_VARIANTS` variants.
    """
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if list(names).count(n) > 1})
        raise StudyError(f"parameter {', '.join(twice)} is named twice in the grid")
    count = math.prod(len(a) for a in axes)
    if count == 0:
        raise StudyError("the grid has no variants (an axis without values)")
    if count > MAX_VARIANTS:
        sizes = " x ".join(str(len(a)) for a in axes)
        raise StudyError(f"the grid has {sizes} = {count:,} variants, more than {MAX_VARIANTS:,}")
    axes = tuple(np.asarray(a, dtype=float) for a in axes)
    points = np.array(list(itertools.product(*axes)), dtype=float).reshape(count, len(axes))
    return ParameterGrid(tuple(names), tuple(units), points, axes)


def read_grid_csv(
    path: str | os.PathLike, resolve: Resolve, limit: int = MAX_VARIANTS
) -> ParameterGrid:
    """Parameter sets from a CSV file (see the module's docstring for the format).

    Parameters
    ----------
    path : str or path-like
    resolve : callable(name) -> (parameter, unit)
        The model's lookup of a column's name; raises KeyError with the reason.
    limit : int
        Most rows accepted.

    Raises
    ------
    GridFileError
        An unreadable file, no header or no rows, an unknown or repeated parameter, a unit
        that is not the parameter's, a row of another length, or a value that is not a finite
        number (the message names the file, the line and the column).
    """
    path = Path(path)
    try:
        text = read_text(path, GRID_BYTES, "a grid file", encoding="utf-8-sig")
    except InputTooLargeError as exc:  # /dev/zero too: at most the limit is read
        raise GridFileError(str(exc)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise GridFileError(f"{path}: cannot read the grid file: {exc}") from None
    rows = [
        (number, row)
        for number, row in enumerate(csv.reader(io.StringIO(text)), start=1)
        if row and any(cell.strip() for cell in row) and not row[0].lstrip().startswith("#")
    ]
    if not rows:
        raise GridFileError(f"{path}: no header line (expected parameter names, e.g. 'V,lambda')")
    line, header = rows[0]
    names, units = _header(path, line, header, resolve)
    if len(rows) == 1:
        raise GridFileError(f"{path}: no parameter sets after the header (line {line})")
    if len(rows) - 1 > limit:
        raise GridFileError(f"{path}: {len(rows) - 1:,} parameter sets, more than {limit:,}")
    points = np.empty((len(rows) - 1, len(names)))
    for k, (line, row) in enumerate(rows[1:]):
        if len(row) != len(names):
            raise GridFileError(
                f"{path}: line {line}: {len(row)} values, expected {len(names)} "
                f"({', '.join(names)})"
            )
        for column, cell in enumerate(row):
            try:
                value = float(cell)
            except ValueError:
                value = math.nan
                problem = f"{cell.strip()!r} is not a number"
            else:
                problem = f"{cell.strip()} is not a finite number"
            if not math.isfinite(value):
                raise GridFileError(
                    f"{path}: line {line}, column {column + 1} ({names[column]}): {problem}"
                )
            points[k, column] = value
    return ParameterGrid(tuple(names), tuple(units), points, None, str(path))


def _header(path: Path, line: int, header: list[str], resolve: Resolve):
    """The header's parameter names and units (``"V (m/s)"``, ``"speed"``, ``"lambda"``)."""
    names: list[str] = []
    units: list[str] = []
    for column, cell in enumerate(header, start=1):
        where = f"{path}: line {line}, column {column}"
        found = _HEADER.match(cell)
        label = found.group(1) if found else ""
        if not label:
            raise GridFileError(f"{where}: expected a parameter name, got {cell.strip()!r}")
        try:
            name, unit = resolve(label)
        except KeyError as exc:
            reason = exc.args[0] if exc.args else f"no parameter {label!r}"
            raise GridFileError(f"{where}: {reason}") from None
        given = found.group(2)
        if given is not None and given.strip() != unit:
            raise GridFileError(
                f"{where} ({label}): unit {given.strip()!r}, but {name} is in {unit or 'no unit'}"
                " (the grid's values are SI, as the model's)"
            )
        if name in names:
            raise GridFileError(f"{where} ({label}): parameter {name} is already column "
                                f"{names.index(name) + 1}")  # fmt: skip
        names.append(name)
        units.append(unit)
    return names, units
