"""The inputs of a model file beyond one sinusoid: keys per kind, and time-series points.

A ``[forcing.NAME]`` table with ``kind = "series"`` takes its points from a CSV file (two
columns: time, value; ``#`` comments and one header line allowed) or inline (``points =
[[t, u], ...]``), in the units it states (``time_unit``, ``value_unit``), converted here to
seconds and the forcing's ``unit``. Every problem is a ModelError naming the model file and
the key (and the CSV file's line). The format is documented in docs/model.md.
"""

from __future__ import annotations

import math
from pathlib import Path

#: Keys each forcing kind takes besides description, enabled, kind, unit, enters.
FORCING_KEYS: dict[str, tuple[str, ...]] = {
    "sine": ("amplitude", "frequency", "phase"),
    "sines": ("amplitudes", "frequencies", "phases"),
    "series": ("file", "points", "time_unit", "value_unit", "amplitude", "speed"),
    "step": ("amplitude", "start", "rise"),
    "bump": ("amplitude", "start", "duration", "shape"),
}

#: Seconds per time unit (a distance column with ``speed``: metres per unit).
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0, "h": 3600.0}
DISTANCE_UNITS = {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "km": 1e3}

# SI prefixes a value unit may carry relative to the forcing's unit ("mm" for "m")
_PREFIXES = {"n": 1e-9, "u": 1e-6, "µ": 1e-6, "m": 1e-3, "c": 1e-2, "d": 1e-1, "k": 1e3,
             "M": 1e6}  # fmt: skip

#: A time series longer than this is refused: each point is a restart of the direct
#: solution and a corner of the netlist's PWL source.
MAX_POINTS = 20_000


def series_points(reader, table: dict, key: str) -> tuple[tuple[float, float], ...]:
    """The points of a ``series`` forcing, in seconds (or metres with ``speed``) and ``unit``.

    Parameters
    ----------
    reader : modelfile._Reader
        For ``fail`` (the ModelError of this model file) and ``file``.
    table : dict
        The ``[forcing.NAME]`` table.
    key : str
        ``"forcing.NAME"``.

    Raises
    ------
    ModelError
        Neither or both of ``file`` and ``points``; an unreadable file or line; fewer than
        two points; times that decrease; unknown units.
    """
    if ("file" in table) == ("points" in table):
        raise reader.fail(key, "a series needs exactly one of file (a CSV file) or points")
    distance = "speed" in table
    units = DISTANCE_UNITS if distance else TIME_UNITS
    time_unit = table.get("time_unit", "m" if distance else "s")
    if not isinstance(time_unit, str) or time_unit not in units:
        what = "distance unit (with speed)" if distance else "time unit"
        raise reader.fail(
            f"{key}.time_unit", f"unknown {what} {time_unit!r} (known: {', '.join(units)})"
        )
    scale_t = units[time_unit]
    scale_v = _value_scale(reader, table, key)
    if "file" in table:
        raw = _csv_points(reader, table["file"], f"{key}.file")
        where = f"{key}.file"
    else:
        raw = _inline_points(reader, table["points"], f"{key}.points")
        where = f"{key}.points"
    if len(raw) < 2:
        raise reader.fail(where, f"a series needs at least 2 points, got {len(raw)}")
    if len(raw) > MAX_POINTS:
        raise reader.fail(where, f"{len(raw)} points; at most {MAX_POINTS} are accepted")
    points = tuple((t * scale_t, v * scale_v) for t, v, _ in raw)
    for (t_a, _, _), (t_b, _, line) in zip(raw, raw[1:], strict=False):
        if t_b < t_a:
            raise reader.fail(where, f"{line}: time {t_b:g} is before the previous {t_a:g}")
    for (t_a, _, _), (t_b, _, _), (t_c, _, line) in zip(raw, raw[1:], raw[2:], strict=False):
        if t_a == t_b == t_c:
            raise reader.fail(where, f"{line}: three points at time {t_c:g} (a jump takes two)")
    return points


def _value_scale(reader, table: dict, key: str) -> float:
    """Factor from ``value_unit`` to the forcing's ``unit`` (an SI prefix apart)."""
    unit = table.get("unit", "")
    value_unit = table.get("value_unit", unit)
    if not isinstance(value_unit, str):
        raise reader.fail(f"{key}.value_unit", "wrong type: expected a string")
    if value_unit == unit:
        return 1.0
    prefix = value_unit[: len(value_unit) - len(unit)] if unit else ""
    if unit and value_unit.endswith(unit) and prefix in _PREFIXES:
        return _PREFIXES[prefix]
    raise reader.fail(
        f"{key}.value_unit",
        f"cannot convert {value_unit!r} to the forcing's unit {unit!r} (give value_unit as "
        f"{unit!r} with an SI prefix: {', '.join(p + unit for p in ('m', 'u', 'k'))} ...)",
    )


def _number(reader, text, where: str, what: str) -> float:
    if isinstance(text, bool):
        raise reader.fail(where, f"{what}: expected a number, got a boolean")
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise reader.fail(where, f"{what}: expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise reader.fail(where, f"{what}: must be finite, got {text!r}")
    return value


def _inline_points(reader, value, key: str) -> list[tuple[float, float, str]]:
    if not isinstance(value, list):
        raise reader.fail(key, "wrong type: expected an array of [time, value] pairs")
    out = []
    for i, pair in enumerate(value):
        where = f"point {i}"
        if not isinstance(pair, list) or len(pair) != 2:
            raise reader.fail(key, f"{where}: expected a [time, value] pair, got {pair!r}")
        out.append((_number(reader, pair[0], key, where), _number(reader, pair[1], key, where),
                    where))  # fmt: skip
    return out


def _csv_points(reader, value, key: str) -> list[tuple[float, float, str]]:
    """Rows of a two-column CSV file beside the model file (or an absolute path)."""
    if not isinstance(value, str) or not value.strip():
        raise reader.fail(key, "wrong type: expected a file name (a string)")
    path = Path(value)
    if not path.is_absolute():
        path = Path(reader.file).parent / path
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise reader.fail(key, f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise reader.fail(key, f"{path}: cannot read: {exc}") from None
    out: list[tuple[float, float, str]] = []
    header_allowed = True
    for number, line in enumerate(text.splitlines(), start=1):
        content = line.split("#", 1)[0].strip()
        if not content:
            continue
        fields = [f.strip() for f in content.replace(";", ",").split(",")]
        where = f"{path.name} line {number}"
        if len(fields) != 2:
            raise reader.fail(key, f"{where}: expected two columns (time, value), got "
                              f"{len(fields)}")  # fmt: skip
        if header_allowed and not _is_number(fields[0]):
            header_allowed = False
            continue  # the header ("time,value", "t_s,z_mm" ...)
        header_allowed = False
        out.append((_number(reader, fields[0], key, where), _number(reader, fields[1], key, where),
                    where))  # fmt: skip
    return out


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
