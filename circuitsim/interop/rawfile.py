"""ngspice and LTspice rawfiles, binary or ASCII, to :class:`Waveforms`.

Layout (both kinds): text header lines ``Key: value`` (``Plotname``, ``Flags: real|complex``,
``No. Variables``, ``No. Points``), then ``Variables:`` with one ``index name type`` line per
vector, then either

- ``Binary:`` and the points as native float64: per point one number per vector (two, real
  and imaginary, per vector of a complex plot, the axis included); or
- ``Values:`` and per point its index followed by one number per vector (``re,im`` when
  complex), whitespace separated. ngspice prints 16 significant digits here, so ASCII values
  are rounded where binary ones are exact, and reading them is some 100 times slower.

Only the first plot of a file is read. Names are turned into ours: ``v(node)``,
``i(vname)`` (``vname#branch`` -> ``i(vname)``), lower case. Complex vectors (an ``.ac``
sweep) become magnitude and phase in degrees, ``vm(node)``/``vp(node)`` and
``im(vname)``/``ip(vname)``, over the frequency axis, which takes the place of ``time``.

LTspice writes the same layout in UTF-16 (little endian), and its binary section differs:
the time axis is float64 (its sign bit is a marker LTspice sets on some points, so the
absolute value is taken), every other vector float32 unless ``Flags`` says ``double``;
``fastaccess`` files store vector after vector instead of point after point. Only real
(transient, operating point) LTspice plots are read.
"""

from __future__ import annotations

import os

import numpy as np

from circuitsim.inputfile import RAW_FILE_BYTES, InputTooLargeError, read_bytes
from circuitsim.interop.errors import NgspiceError
from circuitsim.solver.waveforms import Waveforms

_BINARY = b"Binary:\n"
_VALUES = b"Values:\n"

MAX_VARIABLES = 1_000_000
"""Most vectors (``No. Variables``) a raw file may declare: the 64-mass TL074 chain, the
largest circuit generated here, has 11,782 unknowns."""


def read_rawfile(path: str | os.PathLike) -> Waveforms:
    """The first plot of an ngspice or LTspice rawfile (binary or ASCII) as Waveforms.

    ``engine`` is ``"ngspice"`` or ``"ltspice"``.

    Raises
    ------
    NgspiceError
        Not a rawfile, cut short, counts that are negative or beyond any circuit
        (:data:`MAX_VARIABLES`), a value that is not finite, or a file larger than
        :data:`~circuitsim.inputfile.RAW_FILE_BYTES` (the message names the file).
    OSError
        The file cannot be read.
    """
    try:
        data = read_bytes(path, RAW_FILE_BYTES, "a raw file")
    except InputTooLargeError as exc:
        raise NgspiceError(str(exc)) from None
    try:
        return parse_rawfile(data)
    except NgspiceError as exc:
        exc.args = (f"{path}: {exc.args[0]}", *exc.args[1:])
        raise


def parse_rawfile(data: bytes) -> Waveforms:
    """The first plot of an ngspice or LTspice rawfile (binary or ASCII) as Waveforms.

    Raises
    ------
    NgspiceError
        Not a rawfile, cut short, bad counts, or a value that is not finite.
    """
    if _is_utf16(data):
        return _parse_ltspice(data)
    binary_at, values_at = data.find(_BINARY), data.find(_VALUES)
    starts = [at for at in (binary_at, values_at) if at >= 0]
    if not starts:
        raise NgspiceError("not an ngspice rawfile: no Binary: or Values: section", _head(data))
    start = min(starts)
    header = data[:start].decode("utf-8", errors="replace")
    names, kinds, points, is_complex, plotname = _header(header)
    count = len(names)
    width = 2 if is_complex else 1
    body = start + len(_BINARY if start == binary_at else _VALUES)
    if start == binary_at:
        needed = points * count * width
        if (len(data) - body) // 8 < needed:
            raise _cut_short(points, count)
        flat = np.frombuffer(data, dtype=np.float64, count=needed, offset=body)
        table = flat.reshape(points, count * width)
        table = table[:, 0::2] + 1j * table[:, 1::2] if is_complex else table
    else:
        table = _ascii_values(data[body:].decode("ascii", errors="replace"), points, count)
        if np.iscomplexobj(table) and not is_complex:
            raise NgspiceError("ngspice's rawfile has complex values (re,im) in a real plot")
    return _waveforms(names, kinds, table, is_complex, plotname)


def _is_utf16(data: bytes) -> bool:
    """LTspice's UTF-16LE text: every second byte of the ASCII header is zero."""
    head = data[:64].removeprefix(b"\xff\xfe")
    return len(head) >= 8 and head[1::2][:4] == b"\0\0\0\0" and head[0::2][:4].isascii()


def _parse_ltspice(data: bytes) -> Waveforms:
    bom = 2 if data.startswith(b"\xff\xfe") else 0
    marks = {kind: data.find(kind.encode("utf_16_le"), bom) for kind in ("Binary:\n", "Values:\n")}
    found = {kind: at for kind, at in marks.items() if at >= 0 and (at - bom) % 2 == 0}
    if not found:
        raise NgspiceError("not an LTspice rawfile: no Binary: or Values: section")
    kind, start = min(found.items(), key=lambda item: item[1])
    header = data[bom:start].decode("utf_16_le", errors="replace")
    names, kinds, points, is_complex, plotname = _header(header)
    if is_complex:
        raise NgspiceError("an LTspice rawfile of complex values (.ac) is not read here")
    flags = header.lower().split("flags:", 1)[-1].splitlines()[0].split()
    body = start + len(kind.encode("utf_16_le"))
    count = len(names)
    if kind == "Values:\n":
        text = data[body:].decode("utf_16_le", errors="replace")
        table = _ascii_values(text, points, count)
        if np.iscomplexobj(table):
            raise NgspiceError("an LTspice rawfile with complex values (re,im) in a real plot")
    else:
        table = _ltspice_binary(data[body:], points, count, "double" in flags,
                                "fastaccess" in flags)  # fmt: skip
    table[:, 0] = np.abs(table[:, 0])
    waves = _waveforms(names, kinds, table, False, plotname)
    waves.engine = "ltspice"
    return waves


def _ltspice_binary(body: bytes, points: int, count: int, double: bool, fast: bool) -> np.ndarray:
    """The (points, count) table: time float64, the others float32 (float64 if ``double``)."""
    other = np.dtype("<f8" if double else "<f4")
    size = 8 + (count - 1) * other.itemsize
    if len(body) < points * size:
        raise _cut_short(points, count)
    table = np.empty((points, count))
    if fast:  # vector after vector
        table[:, 0] = np.frombuffer(body, "<f8", points)
        for column in range(1, count):
            offset = points * 8 + (column - 1) * points * other.itemsize
            table[:, column] = np.frombuffer(body, other, points, offset)
        return table
    rows = np.frombuffer(body, np.dtype([("t", "<f8"), ("v", other, (count - 1,))]), points)
    table[:, 0] = rows["t"]
    table[:, 1:] = rows["v"]
    return table


def parse_ascii_raw(text: str) -> Waveforms:
    """The first plot of an ngspice ASCII rawfile, given as text."""
    return parse_rawfile(text.encode("utf-8"))


def _head(data: bytes) -> str:
    return data[:400].decode("utf-8", errors="replace")


def _cut_short(points: int, count: int) -> NgspiceError:
    return NgspiceError(
        f"ngspice's rawfile is cut short: expected {points} points of {count} values"
    )


def _header(text: str) -> tuple[list[str], list[str], int, bool, str]:
    lines = text.splitlines()
    fields: dict[str, str] = {}
    row = 0
    while row < len(lines) and not lines[row].startswith("Variables:"):
        key, _, value = lines[row].partition(":")
        fields[key.strip().lower()] = value.strip()
        row += 1
    try:
        count = int(fields["no. variables"])
        points = int(fields["no. points"])
    except (KeyError, ValueError):
        raise NgspiceError("ngspice's rawfile has no variable/point counts", text[:400]) from None
    if not 1 <= count <= MAX_VARIABLES:
        raise NgspiceError(
            f"the rawfile's No. Variables: {fields['no. variables'][:40]} is not a count of "
            f"vectors (1 to {MAX_VARIABLES:,}, the time or frequency axis included)"
        )
    if points < 0:
        raise NgspiceError(f"the rawfile's No. Points: {fields['no. points'][:40]} is negative")
    names, kinds = [], []
    for line in lines[row + 1 : row + 1 + count]:
        parts = line.split()
        if len(parts) < 2:
            raise NgspiceError(f"ngspice's rawfile has a bad variable line: {line!r}")
        names.append(parts[1])
        kinds.append(parts[2] if len(parts) > 2 else "")
    if len(names) != count:
        raise NgspiceError(f"ngspice's rawfile lists {len(names)} of its {count} variables")
    is_complex = "complex" in fields.get("flags", "").lower()
    return names, kinds, points, is_complex, fields.get("plotname", "")


def _ascii_values(text: str, points: int, count: int) -> np.ndarray:
    # Each point is its index followed by one number per variable ("re,im" when complex);
    # every number takes at least two characters (a digit and a separator).
    if points * (count + 1) > (len(text) + 1) // 2:
        raise _cut_short(points, count)
    tokens = text.split()[: points * (count + 1)]
    if len(tokens) < points * (count + 1):
        raise _cut_short(points, count)
    try:
        if any("," in token for token in tokens[: count + 1]):
            values = [complex(*map(float, z.split(","))) if "," in z else float(z) for z in tokens]
            table = np.array(values, dtype=complex)
        else:
            table = np.array(tokens, dtype=float)
    except (TypeError, ValueError):
        raise NgspiceError("ngspice's rawfile has a value that is not a number") from None
    return table.reshape(points, count + 1)[:, 1:]


def _waveforms(
    names: list[str], kinds: list[str], table: np.ndarray, is_complex: bool, plotname: str
) -> Waveforms:
    _refuse_non_finite(names, kinds, table)
    signals: dict[str, np.ndarray] = {}
    axis = np.zeros(1)
    for column, (name, kind) in enumerate(zip(names, kinds, strict=True)):
        key = signal_name(name, kind)
        values = table[:, column]
        if key in ("time", "frequency"):
            axis = np.ascontiguousarray(np.real(values), dtype=float)
        elif is_complex:
            inner = key[1:]  # "(node)"
            signals[key[0] + "m" + inner] = np.abs(values).astype(float)
            signals[key[0] + "p" + inner] = np.degrees(np.angle(values)).astype(float)
        else:
            signals[key] = np.ascontiguousarray(values, dtype=float)
    if "operating point" in plotname.lower():
        axis = np.zeros(1)
    scale = "frequency" if "frequency" in (n.lower() for n in names) else "time"
    return Waveforms(time=axis, signals=signals, engine="ngspice", axis=scale)


def _refuse_non_finite(names: list[str], kinds: list[str], table: np.ndarray) -> None:
    """Refuse a table holding inf or NaN, naming the first such vector, point and time."""
    finite = np.isfinite(table)
    if finite.all():
        return
    point, column = (int(k) for k in np.argwhere(~finite)[0])
    where = f"point {point}"
    if column != 0 and np.isfinite(table[point, 0]):
        where += f" ({names[0].lower()} {np.real(table[point, 0]):.6g})"
    name, value = signal_name(names[column], kinds[column]), table[point, column]
    raise NgspiceError(
        f"the rawfile's {name} is {value} at {where}: a result that went non-finite cannot "
        "be compared"
    )


def signal_name(name: str, kind: str) -> str:
    """ngspice's vector name in our spelling: ``v(node)``, ``i(vname)``, ``time``."""
    name = name.lower()
    if name in ("time", "frequency") or name.startswith(("v(", "i(")):
        return name
    if name.endswith("#branch"):
        return f"i({name[: -len('#branch')]})"
    if kind.lower() == "current":
        return f"i({name})"
    return f"v({name})"
