"""Waveforms to a binary rawfile in ngspice's layout (``simulate --raw FILE.raw``).

The layout is the one ngspice 39 writes with ``ngspice -b -r FILE.raw`` (read from its own
output): text lines ``Title:``, ``Date:``, ``Plotname:``, ``Flags: real``, ``No. Variables:``,
``No. Points:``, then ``Variables:`` with one ``\\tindex\\tname\\ttype`` line per vector (``time``
first, of type ``time``; ``v(node)`` of type ``voltage``, ``i(vname)`` of type ``current``),
then ``Binary:`` and, point after point, every vector's value as a little-endian float64
(ngspice says ``Flags: real`` for these doubles). The values are written as they are: a
file read back (by ngspice's ``load``, spicelib's ``RawRead``, our
:func:`~circuitsim.interop.rawfile.read_rawfile`) gives the same doubles, bit for bit.

No ``Command:`` line, although ngspice 44 and later write one (``Command: ngspice-44 ...``)
and spicelib (1.6.4) takes a rawfile's dialect from it: ngspice 39's ``load`` runs the rest of
a ``Command:`` line as a front-end command (tested: ``Command: circuitsim ...`` printed
"Error: misplaced Command: line" and "circuitsim: no such command available in ngspice"), so
the file would be a program for the ngspice it is meant for. spicelib reads the file as it
reads ngspice 39's own, with ``RawRead(path, dialect='ngspice')``.
"""

from __future__ import annotations

import os
import time as clock

import numpy as np

from circuitsim.atomic import write_atomic
from circuitsim.solver.waveforms import Waveforms

__all__ = ["rawfile_bytes", "write_rawfile", "vector_type"]


def vector_type(name: str) -> str:
    """ngspice's type word for the vector ``name``: ``voltage`` for ``v(...)``, ``current``
    for ``i(...)``.

    Raises
    ------
    ValueError
        ``name`` is neither (a physical state, say): a rawfile has no type for it.
    """
    lowered = name.lower()
    if lowered.startswith("v(") and lowered.endswith(")"):
        return "voltage"
    if lowered.startswith("i(") and lowered.endswith(")"):
        return "current"
    raise ValueError(
        f"the signal {name!r} is neither a voltage v(...) nor a current i(...); "
        "a rawfile gives every vector one of ngspice's types"
    )


def rawfile_bytes(
    waves: Waveforms,
    title: str = "circuitsim",
    operating_point: bool = False,
    date: str | None = None,
) -> bytes:
    """The binary rawfile of ``waves``: header text, then the points as float64.

    Parameters
    ----------
    waves : Waveforms
        ``time`` (s) and ``v(...)`` (V) / ``i(...)`` (A) signals, all of one length.
    title : str
        The ``Title:`` line (the netlist's title; line breaks become spaces).
    operating_point : bool
        Write an ``Operating Point`` plot (ngspice's ``.op`` layout: one point and no time
        vector) instead of a ``Transient Analysis``.
    date : str, optional
        The ``Date:`` line; by default now, in ngspice's ``ctime`` form.

    Returns
    -------
    bytes

    Raises
    ------
    ValueError
        A signal that is not ``v(...)`` or ``i(...)``, signals of differing lengths, an
        operating point with more than one point, or a non-finite time.
    """
    time = np.asarray(waves.time, dtype=float)
    names = list(waves.signals)
    columns = [np.asarray(waves.signals[name], dtype=float) for name in names]
    for name, column in zip(names, columns, strict=True):
        if column.shape != time.shape:
            raise ValueError(
                f"the signal {name!r} has {column.size} values for {time.size} time points"
            )
    if not np.all(np.isfinite(time)):
        raise ValueError("the time axis holds a value that is not a finite number")
    variables = [(name, vector_type(name)) for name in names]
    if operating_point:
        if time.size != 1:
            raise ValueError(f"an operating point has one point, not {time.size}")
        plotname = "Operating Point"
    else:
        variables.insert(0, ("time", "time"))
        columns.insert(0, time)
        plotname = "Transient Analysis"
    header = [
        f"Title: {' '.join(title.splitlines()).strip()}",
        f"Date: {clock.ctime() if date is None else date}",
        f"Plotname: {plotname}",
        "Flags: real",
        f"No. Variables: {len(variables)}",
        f"No. Points: {time.size}",
        "Variables:",
        *(f"\t{index}\t{name}\t{kind}" for index, (name, kind) in enumerate(variables)),
        "Binary:",
    ]
    table = np.empty((time.size, len(columns)), dtype="<f8")
    for index, column in enumerate(columns):
        table[:, index] = column
    return ("\n".join(header) + "\n").encode() + table.tobytes()


def write_rawfile(
    path: str | os.PathLike,
    waves: Waveforms,
    title: str = "circuitsim",
    operating_point: bool = False,
) -> None:
    """Write :func:`rawfile_bytes` of ``waves`` to ``path``, atomically (temporary file, then
    rename: an existing file is replaced whole or not at all).

    Raises
    ------
    ValueError
        See :func:`rawfile_bytes` (nothing is written).
    OSError
        A :class:`~circuitsim.atomic.WriteError` naming ``path``.
    """
    data = rawfile_bytes(waves, title, operating_point)
    write_atomic(path, lambda handle: handle.write(data), binary=True)
