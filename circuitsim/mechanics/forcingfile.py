"""The ``[forcing.NAME]`` tables of a model file: sinusoids, sums of sines, time series,
steps and bumps.

A ``[forcing.NAME]`` table with ``kind = "series"`` takes its points from a CSV file (two
columns: time, value; ``#`` comments and one header line allowed) or inline (``points =
[[t, u], ...]``), in the units it states (``time_unit``, ``value_unit``), converted here to
seconds and the forcing's ``unit``. Every problem is a ModelError naming the model file and
the key (and the CSV file's line). The format is documented in docs/model.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from importlib import resources
from pathlib import Path

from circuitsim.inputfile import CSV_INPUT_BYTES, InputTooLargeError, read_text
from circuitsim.mechanics.errors import ModelError
from circuitsim.mechanics.expressions import Item, parse

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


@dataclass(frozen=True)
class ForcingSpec:
    """A forcing group as written in ``[forcing.<name>]`` (docs/model.md, "Forcing").

    ``kind`` says which fields matter: ``sine`` (amplitude, frequency, phase), ``sines``
    (``components``: (amplitude, frequency, phase) Items), ``series`` (``points`` read from
    the file or inline, in SI seconds and ``unit``, times ``amplitude``; ``speed``: the first
    column is a distance in metres travelled at this speed), ``step`` (amplitude, ``start``,
    ``rise``), ``bump`` (amplitude, ``start``, ``duration``, ``shape``).
    """

    name: str
    key: str
    description: str
    enabled: bool
    amplitude: Item
    unit: str
    frequency: Item
    phase: Item
    enters: dict[int, Item]
    kind: str = "sine"
    components: tuple[tuple[Item, Item, Item], ...] = ()
    points: tuple[tuple[float, float], ...] = ()
    speed: Item | None = None
    start: Item | None = None
    duration: Item | None = None
    rise: Item | None = None
    shape: str = "haversine"


def _optional(reader, table: dict, name: str, key: str, default) -> Item:
    return reader.expression(table.get(name, default), f"{key}.{name}")


def read_forcing(reader, table: dict, key: str, enters: dict[int, Item]) -> ForcingSpec:
    """The ``[forcing.NAME]`` table ``table`` (``enters`` already read) as a ForcingSpec.

    Raises
    ------
    ModelError
        An unknown kind, a key the kind does not take, a missing key, a bad series.
    """
    kind = reader.string(table, "kind", key, default="sine")
    if kind not in FORCING_KEYS:
        raise reader.fail(f"{key}.kind", f"must be one of {', '.join(FORCING_KEYS)}, got {kind!r}")
    common = ("description", "enabled", "kind", "unit", "enters")
    reader.check_keys(table, key, common + FORCING_KEYS[kind])
    needed = {"sine": ("amplitude", "frequency"), "sines": ("amplitudes", "frequencies"),
              "step": ("amplitude",), "bump": ("amplitude", "duration")}  # fmt: skip
    for name in needed.get(kind, ()):
        if name not in table:
            raise reader.fail(f"{key}.{name}", "missing key")
    default_amplitude = 1.0 if kind in ("series", "sines") else 0.0
    spec = ForcingSpec(
        name=key.split(".", 1)[1],
        key=key,
        description=reader.string(table, "description", key, default=""),
        enabled=reader.boolean(table, "enabled", key, True),
        amplitude=_optional(reader, table, "amplitude", key, default_amplitude),
        unit=reader.string(table, "unit", key, default=""),
        frequency=_optional(reader, table, "frequency", key, 0.0),
        phase=_optional(reader, table, "phase", key, 0.0),
        enters=enters,
        kind=kind,
    )
    extra: dict = {}
    if kind == "sines":
        extra["components"] = _sine_components(reader, table, key)
    elif kind == "series":
        extra["points"] = series_points(reader, table, key)
        if "speed" in table:
            extra["speed"] = reader.expression(table["speed"], f"{key}.speed")
    elif kind in ("step", "bump"):
        extra["start"] = _optional(reader, table, "start", key, 0.0)
        if kind == "step":
            extra["rise"] = _optional(reader, table, "rise", key, 0.0)
        else:
            extra["duration"] = reader.expression(table["duration"], f"{key}.duration")
            extra["shape"] = reader.string(table, "shape", key, default="haversine")
            if extra["shape"] not in ("haversine", "half_sine"):
                raise reader.fail(
                    f"{key}.shape", f"must be haversine or half_sine, got {extra['shape']!r}"
                )
    return replace(spec, **extra)


def _sine_components(reader, table: dict, key: str) -> tuple[tuple[Item, Item, Item], ...]:
    """``amplitudes``, ``frequencies`` and optional ``phases``: arrays of one length."""
    arrays = {}
    for name in ("amplitudes", "frequencies", "phases"):
        value = table.get(name)
        if value is None:
            continue
        if not isinstance(value, list) or not value:
            raise reader.fail(f"{key}.{name}", "wrong type: expected a non-empty array")
        arrays[name] = [reader.expression(v, f"{key}.{name}[{i}]") for i, v in enumerate(value)]
    count = len(arrays["amplitudes"])
    for name, items in arrays.items():
        if len(items) != count:
            raise reader.fail(
                f"{key}.{name}", f"wrong length: {len(items)} entries for {count} amplitudes"
            )
    zero = Item(f"{key}.phases", parse(0.0))
    phases = arrays.get("phases", [zero] * count)
    return tuple(zip(arrays["amplitudes"], arrays["frequencies"], phases, strict=True))


def series_points(reader, table: dict, key: str) -> tuple[tuple[float, float], ...]:
    """The points of a ``series`` forcing, in seconds (or metres with ``speed``) and ``unit``.

    Parameters
    ----------
    reader : tomlfile.TableReader
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
    for (t, v), (_, _, line) in zip(points, raw, strict=True):
        if not (math.isfinite(t) and math.isfinite(v)):  # finite as written, not in SI units
            unit = table.get("unit", "") or "the forcing's unit"
            raise reader.fail(where, f"{line}: a point beyond the float range in s and {unit}")
    for (t_a, _, _), (t_b, _, line) in zip(raw, raw[1:], strict=False):
        if t_b < t_a:
            raise reader.fail(where, f"{line}: time {t_b:g} is before the previous {t_a:g}")
    for (t_a, _, _), (t_b, _, _), (t_c, _, line) in zip(raw, raw[1:], raw[2:], strict=False):
        if t_a == t_b == t_c:
            raise reader.fail(where, f"{line}: three points at time {t_c:g} (a jump takes two)")
    return points


class _InputFileReader:
    """What :func:`series_points` needs of a model-file reader, for a CSV file named outside
    any model file (``--input NAME=FILE.csv``): relative names from the working directory,
    errors naming the option and the file."""

    def __init__(self, option: str):
        self.file = str(Path.cwd() / "input")  # series_points looks beside this name
        self.option = option

    def fail(self, key: str, message: str) -> ModelError:
        return ModelError(message, key=self.option)


def series_from_file(spec: ForcingSpec, path: str) -> ForcingSpec:
    """``spec`` with its input replaced by the time series of a CSV file, switched on.

    The file has the format of a ``series`` forcing's ``file`` (docs/model.md): two columns,
    time in seconds and the value in the group's ``unit``, one header line and ``#``
    comments allowed, at most ``MAX_POINTS`` points; linear interpolation between them.

    Parameters
    ----------
    spec : ForcingSpec
        The model file's ``[forcing.NAME]`` group (its ``enters`` and ``unit`` are kept).
    path : str
        The CSV file (relative to the working directory).

    Raises
    ------
    ModelError
        Keyed ``--input NAME=FILE``: a missing or unreadable file, a bad line (with its
        number), fewer than two points, decreasing times.
    """
    reader = _InputFileReader(f"--input {spec.name}={path}")
    points = series_points(reader, {"file": path, "unit": spec.unit}, spec.key)
    return replace(
        spec,
        kind="series",
        enabled=True,
        points=points,
        amplitude=Item(f"{spec.key}.amplitude", parse(1.0)),
        speed=None,
        components=(),
        start=None,
        duration=None,
        rise=None,
    )


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
    except OverflowError:  # an integer of hundreds of digits
        value = math.inf
    if not math.isfinite(value):
        raise reader.fail(where, f"{what}: must be finite, got {str(text)[:40]!r}")
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
    """Rows of a two-column CSV file: an absolute path, or a name beside the model file, else
    among the shipped models' files (circuitsim/mechanics/models/)."""
    if not isinstance(value, str) or not value.strip():
        raise reader.fail(key, "wrong type: expected a file name (a string)")
    path = Path(value)
    if not path.is_absolute():
        beside = Path(reader.file).parent / path
        # a copy of a shipped model still finds the shipped profile it names
        shipped = Path(str(resources.files("circuitsim.mechanics") / "models")) / path
        try:
            path = beside if beside.exists() or not shipped.exists() else shipped
        except (OSError, ValueError) as exc:  # a name too long for the file system, a NUL
            reason = getattr(exc, "strerror", None) or str(exc)
            raise reader.fail(key, f"cannot read: {reason}") from None
    try:
        text = read_text(path, CSV_INPUT_BYTES, "a time-series file")
    except InputTooLargeError as exc:  # /dev/zero too: at most the limit is read
        raise reader.fail(key, f"{str(path)[:200]}: {exc.reason}") from None
    except FileNotFoundError:
        raise reader.fail(key, f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise reader.fail(key, f"{str(path)[:200]}: cannot read: {exc}") from None
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
