"""Reading a user's file with a size limit: at most LIMIT + 1 bytes, whatever the file is.

A leaf module (imports nothing of ours), beside :mod:`circuitsim.atomic` (which writes), so
that every room and the CLI read their input files the same way.

A file's reported size is not trusted: a device (``/dev/zero``, ``/dev/urandom``) reports 0
bytes and never ends, a FIFO or a pipe (``<(command)``) has no size at all, and a regular file
can grow while it is read. :func:`read_bytes` therefore reads at most ``limit + 1`` bytes and
refuses the file if it got more than ``limit``; a regular file whose reported size is already
past the limit is refused before any byte is read. The error is :class:`InputTooLargeError`,
an ``OSError`` (``EFBIG``) whose message names the file, the limit and what the limit is for.

The limits of each kind of file are named here (``*_BYTES``), each with the reason for its
size, so that one table (docs/robustness.md) lists them all.
"""

from __future__ import annotations

import errno
import io
import os
import stat

MiB = 2**20

MODEL_FILE_BYTES = 16 * MiB
"""Model file (TOML): a dense 1,000-state model (a million linear coefficients) is about
10 MiB."""

NETLIST_BYTES = 64 * MiB
"""Netlist, or one file it includes (a vendor ``.lib``): the generated 64-mass TL074 chain's
netlist is 0.17 MiB, so 64 MiB leaves room for vendors' libraries of many parts."""

DECK_BYTES = 256 * MiB
"""All files of one netlist together (the netlist and everything it includes)."""

SCALE_FILE_BYTES = 16 * MiB
"""Scale file (JSON): the 64-mass chain's (128 states) is 12 KiB, about 100 bytes per state, so
16 MiB holds far more states than :data:`MAX_SCALE_STATES`."""

MAX_SCALE_STATES = 2_000
"""Most states of a scale file: twice the 1,000-state model the model-file limit is sized for
(the largest generated here, the 64-mass chain, has 128); ``simulate --states`` records every
state at every time point."""

CSV_INPUT_BYTES = 16 * MiB
"""Forcing time series (``--input NAME=FILE.csv``, ``kind = "series"``): at most 20,000 points
of two numbers, well under 1 MiB; 16 MiB leaves room for comments and long numbers."""

GRID_BYTES = 16 * MiB
"""Parameter grid (``--grid FILE.csv``): at most 10,000 rows (each a run of its own), of a
few numbers each."""

RAW_FILE_BYTES = 2048 * MiB
"""Raw file (ngspice, LTspice) or results CSV: 268 million float64 values, e.g. the
wheelset's 4 states and time at 50 million points; the file is held in memory with the table
made of it."""

BOM_BYTES = 16 * MiB
"""Bill of materials (CSV): the 64-mass TL074 chain's (3,200 parts) is 0.31 MiB."""


class InputTooLargeError(OSError):
    """A user's file holds more than the limit for its kind (or never ends: a device).

    ``filename`` is the path as given; ``limit`` the most bytes accepted; ``size`` the size
    the file reports when that is already past the limit (None when the read found it out);
    ``what`` names the kind of file ("a model file"). ``str()`` reads ``FILE: REASON``;
    :attr:`reason` is the part without the file, for errors that name the file themselves.
    """

    def __init__(self, filename: str, limit: int, what: str, size: int | None = None):
        self.limit = limit
        self.what = what
        self.size = size
        super().__init__(errno.EFBIG, self.reason, filename)

    @property
    def reason(self) -> str:
        """``too large: ... (a model file is at most 16 MiB)``, without the file name."""
        found = (
            f"{self.size:,} bytes"
            if self.size is not None
            else f"more than {size_words(self.limit)}"
        )
        return f"too large: {found} ({self.what} is at most {size_words(self.limit)})"

    def __str__(self) -> str:
        return f"{self.filename}: {self.reason}"


def size_words(size: int) -> str:
    """``16 MiB``, ``2 GiB``, ``1,000 bytes``: a limit in the words of the messages."""
    for unit, scale in (("GiB", 2**30), ("MiB", MiB), ("KiB", 2**10)):
        if size >= scale and size % scale == 0:
            return f"{size // scale:,} {unit}"
    return f"{size:,} bytes"


def read_bytes(path: str | os.PathLike, limit: int, what: str = "an input file") -> bytes:
    """The bytes of ``path``, refused if more than ``limit``.

    Reads at most ``limit + 1`` bytes, so a device that never ends (``/dev/zero``), a FIFO, a
    pipe or a file still growing costs at most that much memory. A regular file that reports
    a size past the limit is refused before it is read.

    Parameters
    ----------
    path : path-like
        The file, as the user gave it.
    limit : int
        Most bytes accepted.
    what : str
        The kind of file, for the message ("a model file").

    Returns
    -------
    bytes
        The whole file (at most ``limit`` bytes).

    Raises
    ------
    InputTooLargeError
        The file holds more than ``limit`` bytes (an ``OSError``, ``errno.EFBIG``).
    OSError
        The file cannot be opened or read (missing, a folder, no permission ...).
    """
    given = os.fspath(path)
    if isinstance(given, bytes):
        given = os.fsdecode(given)
    with open(given, "rb") as handle:
        info = os.fstat(handle.fileno())
        if stat.S_ISREG(info.st_mode) and info.st_size > limit:
            raise InputTooLargeError(given, limit, what, info.st_size)
        data = handle.read(limit + 1)
    if len(data) > limit:
        raise InputTooLargeError(given, limit, what)
    return data


def read_text(
    path: str | os.PathLike,
    limit: int,
    what: str = "an input file",
    encoding: str = "utf-8",
    errors: str = "strict",
    newline: str | None = None,
) -> str:
    """The text of ``path``, refused if more than ``limit`` bytes (see :func:`read_bytes`).

    Decoded as ``open(path, encoding=encoding, errors=errors, newline=newline).read()``
    would: by default universal newlines (``\\r\\n`` and ``\\r`` become ``\\n``);
    ``newline=""`` keeps the line ends as written (what :mod:`csv` wants).

    Raises
    ------
    InputTooLargeError, OSError
        As :func:`read_bytes`.
    UnicodeDecodeError
        Not text in ``encoding`` (with ``errors="strict"``).
    """
    data = read_bytes(path, limit, what)
    wrapper = io.TextIOWrapper(io.BytesIO(data), encoding=encoding, errors=errors, newline=newline)
    with wrapper as text:
        return text.read()
