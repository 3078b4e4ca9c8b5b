"""The bill of materials as CSV: ``part,value,unit,series,role,target,realized,error``.

``target`` is the coefficient the part was meant to set (model units), ``realized`` the one its
standard value sets, ``error`` = realized / target - 1; the three are empty for parts that set
no coefficient by themselves (capacitors, inverter pairs, block-internal resistors).
"""

from __future__ import annotations

import csv
import io
import math
import os

from circuitsim.atomic import write_text_atomic
from circuitsim.synthesis.blocks import BomEntry
from circuitsim.synthesis.errors import SynthesisError

COLUMNS = ("part", "value", "unit", "series", "role", "target", "realized", "error")


def _number(x: float) -> str:
    return "" if math.isnan(x) else repr(float(x))


def bom_text(entries: list[BomEntry]) -> str:
    """The CSV text (header row first, full-precision numbers)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(COLUMNS)
    for e in entries:
        writer.writerow(
            [e.part, repr(float(e.value)), e.unit, e.series, e.role,
             _number(e.target), _number(e.realized), _number(e.error)]
        )  # fmt: skip
    return out.getvalue()


def save_bom(entries: list[BomEntry], path: str | os.PathLike) -> None:
    """Write the bill of materials atomically."""
    write_text_atomic(path, bom_text(entries))


def load_bom(path: str | os.PathLike) -> list[BomEntry]:
    """Read a file written by :func:`save_bom`; SynthesisError naming file and line if bad."""
    with open(path, newline="") as handle:
        return parse_bom(handle.read(), source=str(path))


def parse_bom(text: str, source: str = "<bill of materials>") -> list[BomEntry]:
    """Parse :func:`bom_text`'s CSV; SynthesisError naming ``source`` and the line if bad."""
    entries = []
    reader = csv.DictReader(io.StringIO(text, newline=""))
    if tuple(reader.fieldnames or ()) != COLUMNS:
        raise SynthesisError(f"{source}:1: expected the header {','.join(COLUMNS)}")
    for line, row in enumerate(reader, start=2):
        try:
            entries.append(
                BomEntry(
                    row["part"], float(row["value"]), row["unit"], row["series"], row["role"],
                    float(row["target"] or "nan"), float(row["realized"] or "nan"),
                )
            )  # fmt: skip
        except (TypeError, ValueError) as exc:
            raise SynthesisError(
                f"{source}:{line}: malformed bill-of-materials row ({exc})"
            ) from None
    return entries
