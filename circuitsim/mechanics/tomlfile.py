"""A model file on disk: where it is, its TOML, and the checked walk through its tables.

:func:`model_path` finds the file ``--model`` means (a path, or the name of a model shipped
in the package); :func:`load_toml` reads it, every way that can fail (missing, a folder,
too large, not TOML, an integer past Python's digit limit, nesting too deep) a ModelError
naming the file; :class:`TableReader` walks the document, each wrong type, missing or unknown
key a ModelError naming the file and the dotted key. What the tables mean (the model
format): :mod:`circuitsim.mechanics.modelfile`.
"""

from __future__ import annotations

import re
import tomllib
from importlib import resources
from pathlib import Path

from circuitsim.inputfile import MODEL_FILE_BYTES, InputTooLargeError, read_bytes
from circuitsim.mechanics.errors import ModelError
from circuitsim.mechanics.expressions import RESERVED, ExpressionError, Item, parse

BUILTIN = "wheelset"

MAX_FILE_BYTES = MODEL_FILE_BYTES
"""Largest model file read (16 MiB; a dense 1,000-state model is about 10 MiB): a bigger one,
or a device that never ends, is refused having read at most this much
(:func:`circuitsim.inputfile.read_bytes`)."""


def builtin_path(name: str = BUILTIN) -> Path:
    """Path of a model file shipped inside the package (``"wheelset"``)."""
    return Path(str(resources.files("circuitsim.mechanics") / "models" / f"{name}.toml"))


def shipped_models() -> tuple[str, ...]:
    """Names of the model files shipped inside the package (``--model NAME``)."""
    folder = builtin_path().parent
    return tuple(sorted(p.stem for p in folder.glob("*.toml")))


def model_path(path: str | Path | None) -> Path:
    """The file ``--model`` means: a file that exists, else a shipped model's name.

    ``None`` is the built-in wheelset; ``"bogie"`` (no such file here) is the shipped
    ``bogie.toml``. Anything else is returned as given (reading it reports it missing).
    """
    if path is None:
        return builtin_path()
    path = Path(path)
    if not path.exists() and path.name == str(path) and path.stem in shipped_models():
        if path.suffix in ("", ".toml"):
            return builtin_path(path.stem)
    return path


class TableReader:
    """Walks the TOML document; ``fail`` raises the ModelError for this file."""

    def __init__(self, file: str):
        self.file = file

    def fail(self, key: str | None, message: str) -> ModelError:
        return ModelError(message, file=self.file, key=key)

    def table(self, value, key: str, required: bool = True) -> dict:
        if value is None:
            if required:
                raise self.fail(key, "missing table")
            return {}
        if not isinstance(value, dict):
            raise self.fail(key, f"wrong type: expected a table, got {type_name(value)}")
        return value

    def check_keys(self, table: dict, key: str, allowed: tuple[str, ...]) -> None:
        for name in table:
            if name not in allowed:
                where = f"{key}.{name}" if key else name
                raise self.fail(where, f"unknown key (allowed: {', '.join(allowed)})")

    def string(self, table: dict, name: str, key: str, default: str | None = None) -> str:
        if name not in table:
            if default is None:
                raise self.fail(f"{key}.{name}", "missing key")
            return default
        value = table[name]
        if not isinstance(value, str):
            raise self.fail(
                f"{key}.{name}", f"wrong type: expected a string, got {type_name(value)}"
            )
        return value

    def boolean(self, table: dict, name: str, key: str, default: bool) -> bool:
        value = table.get(name, default)
        if not isinstance(value, bool):
            raise self.fail(
                f"{key}.{name}", f"wrong type: expected true or false, got {type_name(value)}"
            )
        return value

    def names(self, table: dict, name: str, key: str) -> tuple[str, ...]:
        value = table.get(name)
        if value is None:
            raise self.fail(f"{key}.{name}", "missing key")
        if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
            raise self.fail(f"{key}.{name}", "wrong type: expected a non-empty list of strings")
        for entry in value:
            check_identifier(self, entry, f"{key}.{name}")
        if len(set(value)) != len(value):
            raise self.fail(f"{key}.{name}", "duplicate names")
        return tuple(value)

    def expression(self, value, key: str) -> Item:
        try:
            return Item(key, parse(value))
        except ExpressionError as exc:
            raise self.fail(key, f"bad expression: {exc}") from None


def type_name(value) -> str:
    return {dict: "a table", list: "an array", str: "a string", bool: "a boolean"}.get(
        type(value), type(value).__name__
    )


def check_identifier(reader: TableReader, name: str, key: str) -> None:
    if not name.isidentifier():
        raise reader.fail(key, f"{name!r} is not a valid name (letters, digits, _)")
    if name in RESERVED:
        raise reader.fail(key, f"{name!r} is reserved (a function or constant of expressions)")


def load_toml(path: Path, reader: TableReader) -> dict:
    """The TOML document of ``path``; every way reading it can fail is a ModelError."""
    try:
        data = read_bytes(path, MAX_FILE_BYTES, "a model file")
        return tomllib.loads(data.decode("utf-8"))
    except InputTooLargeError as exc:  # a device such as /dev/zero too: it is never read whole
        raise reader.fail(None, exc.reason) from None
    except FileNotFoundError:
        shipped = ", ".join(shipped_models())
        raise reader.fail(None, f"model file not found (shipped models: {shipped})") from None
    except IsADirectoryError:
        raise reader.fail(None, "is a folder, not a model file") from None
    except tomllib.TOMLDecodeError as exc:
        raise reader.fail(None, f"not valid TOML: {exc}") from None
    except ValueError as exc:  # not UTF-8, or tomllib's: an integer past the 4,300-digit limit
        if "digits" not in str(exc):
            raise reader.fail(None, f"not valid TOML: {exc}") from None
        line = _line_of_long_integer(data)
        raise reader.fail(
            None, f"not valid TOML: an integer of more than 4,300 digits{line}"
        ) from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise reader.fail(None, "not valid TOML: arrays or tables nested too deeply") from None
    except OSError as exc:
        raise reader.fail(None, f"cannot read: {exc}") from None


def _line_of_long_integer(data: bytes) -> str:
    """`` (line N)`` of the first run of more than 4,300 digits in ``data``, for the message
    (tomllib's own error has no position); empty if not found."""
    match = re.search(rb"\d{4301,}", data)
    if match is None:
        return ""
    line = data.count(b"\n", 0, match.start()) + 1
    return f" (line {line})"


def read_float(reader: TableReader, value, key: str, what: str) -> float:
    """``value`` as a float; a boolean, a string or an integer beyond the float range is
    refused naming ``key``; ``what`` names what is expected ("a number")."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise reader.fail(key, f"wrong type: expected {what}, got {type_name(value)}")
    try:
        return float(value)
    except OverflowError:  # an integer of hundreds of digits
        digits = len(str(abs(value)))
        raise reader.fail(key, f"number too large: an integer of {digits:,} digits") from None
