"""The bill of materials as two CSV files: every part (``FILE.bom.csv``) and what to order
(``FILE.order.csv``).

The per-part file has one row per element of the circuit, in netlist order, with the columns
``part,designator,kind,value,unit,series,device,model,role,target,realized,error``: resistors,
capacitors, op-amp sections (designator ``U3A``: quad package U3, section A), diodes,
switches and voltage sources. ``target`` is the coefficient a resistor was meant to set (model
units), ``realized`` the one its value sets, ``error`` = realized / target - 1; the three are
empty for parts that set no coefficient by themselves. ``series`` names the standard series a
value belongs to (the series a resistor was rounded to, else the coarsest one holding it),
``exact`` for a value in none.

The order file groups them: one row per distinct item a shop sells, with the columns
``item,description,value,tolerance,series,package,quantity,designators,note``; op-amp sections
are ordered as quad packages (quantity = packages), every other row's quantity is its number of
per-part rows.
"""

from __future__ import annotations

import csv
import io
import math
import os

from circuitsim.atomic import write_text_atomic
from circuitsim.inputfile import BOM_BYTES, InputTooLargeError, read_text
from circuitsim.netlist.circuit import Circuit
from circuitsim.synthesis.blocks import BomEntry
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.parts import Part, board_parts, series_label

COLUMNS = (
    "part", "designator", "kind", "value", "unit", "series", "device", "model", "role",
    "target", "realized", "error",
)  # fmt: skip

#: The per-part header before op-amps, diodes, switches and sources were listed; still read.
LEGACY_COLUMNS = ("part", "value", "unit", "series", "role", "target", "realized", "error")

ORDER_COLUMNS = (
    "item", "description", "value", "tolerance", "series", "package", "quantity",
    "designators", "note",
)  # fmt: skip

#: Order rows come in this order of kinds.
KINDS = (
    "op-amp section", "resistor", "potentiometer", "capacitor", "diode", "switch", "supply rail",
    "reference voltage", "switch control", "signal generator",
)  # fmt: skip


def _number(x: float) -> str:
    return "" if math.isnan(x) else repr(float(x))


def _series(part: Part) -> str:
    """A resistor keeps the series it was rounded to; any other value is labelled by
    membership (:func:`~circuitsim.synthesis.parts.series_label`)."""
    if part.entry is not None and part.kind == "resistor" and part.entry.series in ("E24", "E96"):
        return part.entry.series
    return part.series


def bom_text(circuit: Circuit, entries: list[BomEntry]) -> str:
    """The per-part CSV text of ``circuit`` (header row first, full-precision numbers).

    ``entries`` are the translator's records (roles, coefficient targets) of the resistors and
    capacitors it placed.
    """
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(COLUMNS)
    for p in board_parts(circuit, entries):
        e = p.entry or BomEntry(p.part, p.value, p.unit, p.series, p.role)
        writer.writerow(
            [p.part, p.designator, p.kind, _number(p.value), p.unit, _series(p), p.device,
             p.model, p.role, _number(e.target), _number(e.realized), _number(e.error)]
        )  # fmt: skip
    return out.getvalue()


def save_bom(circuit: Circuit, entries: list[BomEntry], path: str | os.PathLike) -> None:
    """Write the per-part bill of materials atomically."""
    write_text_atomic(path, bom_text(circuit, entries))


def load_bom(path: str | os.PathLike) -> list[BomEntry]:
    """Read a file written by :func:`save_bom`; SynthesisError naming file and line if bad."""
    try:  # newline="" as csv wants it: the text as written, line ends and all
        text = read_text(path, BOM_BYTES, "a bill of materials", newline="")
    except InputTooLargeError as exc:
        raise SynthesisError(str(exc)) from None
    return parse_bom(text, source=str(path))


def parse_bom(text: str, source: str = "<bill of materials>") -> list[BomEntry]:
    """Parse :func:`bom_text`'s CSV (every row; value NaN for parts without one) or the
    older resistors-and-capacitors one (:data:`LEGACY_COLUMNS`); SynthesisError naming
    ``source`` and the line if bad."""
    entries = []
    reader = csv.DictReader(io.StringIO(text, newline=""))
    if tuple(reader.fieldnames or ()) not in (COLUMNS, LEGACY_COLUMNS):
        raise SynthesisError(f"{source}:1: expected the header {','.join(COLUMNS)}")
    for line, row in enumerate(reader, start=2):
        try:
            entries.append(
                BomEntry(
                    row["part"], float(row["value"] or "nan"), row["unit"], row["series"],
                    row["role"], float(row["target"] or "nan"), float(row["realized"] or "nan"),
                    # a potentiometer's row holds its full resistance (the netlist its setting)
                    float(row["value"]) if row.get("kind") == "potentiometer" else math.nan,
                )
            )  # fmt: skip
        except (TypeError, ValueError) as exc:
            raise SynthesisError(
                f"{source}:{line}: malformed bill-of-materials row ({exc})"
            ) from None
    return entries


def engineering(value: float, unit: str) -> str:
    """A value as a shop writes it: 30100 ohm -> ``"30.1 kOhm"``, 1e-7 F -> ``"100 nF"``."""
    if math.isnan(value):
        return ""
    symbol = {"ohm": "Ohm"}.get(unit, unit)
    if unit == "V" or value == 0:
        return f"{value:g} {symbol}"
    exponent = min(max(3 * math.floor(math.log10(abs(value)) / 3), -12), 9)
    prefix = {-12: "p", -9: "n", -6: "u", -3: "m", 0: "", 3: "k", 6: "M", 9: "G"}[exponent]
    return f"{float(f'{value / 10.0**exponent:.6g}'):g} {prefix}{symbol}"


def order_rows(circuit: Circuit, entries: list[BomEntry]) -> list[dict[str, str]]:
    """The grouped order view: one dict per distinct item (keys :data:`ORDER_COLUMNS`)."""
    groups: dict[tuple, list[Part]] = {}
    for p in board_parts(circuit, entries):
        key = (KINDS.index(p.kind), p.device, p.model, p.value if p.value == p.value else 0.0)
        groups.setdefault(key, []).append(p)
    rows = []
    for key in sorted(groups, key=lambda k: (k[0], k[1], k[2], k[3])):
        parts = groups[key]
        row = _describe(parts[0], circuit)
        if parts[0].kind == "op-amp section":
            packages = sorted({p.designator[:-1] for p in parts}, key=lambda u: int(u[1:]))
            row["quantity"] = str(len(packages))
            row["designators"] = " ".join(packages)
            row["note"] += f"; {len(parts)} sections: " + " ".join(
                f"{p.designator}={p.part}" for p in parts
            )
        else:
            row["quantity"] = str(len(parts))
            row["designators"] = " ".join(p.designator for p in parts)
        rows.append({"item": str(len(rows) + 1), **row})
    return rows


def _describe(p: Part, circuit: Circuit) -> dict[str, str]:
    """description, value, tolerance, series, package and note of ``p``'s order row."""
    value = engineering(p.value, p.unit)
    row = {"description": "", "value": value, "tolerance": "", "series": "", "package": "",
           "note": ""}  # fmt: skip
    if p.kind == "op-amp section":
        row.update(description=f"{p.device} quad op-amp", package="DIP-14")
        if p.model == "OPAMP_IDEAL":
            row["note"] = (
                f"proposed part: the netlist used the ideal op-amp model {p.model}; a {p.device} "
                "needs +/-15 V supplies, which that netlist does not have"
            )
        else:
            row["note"] = f"netlist model: subcircuit {p.model}"
    elif p.kind == "resistor":
        series = p.series  # by membership: 20 kOhm rounded in E96 is ordered as E24
        row.update(description="metal-film resistor 0.25 W", series=series, package="axial")
        row["tolerance"] = "1 %" if series != "exact" else "0.1 %"
        if series == "exact":
            row["note"] = _nonstandard_note(p.value)
    elif p.kind == "potentiometer":
        row.update(description="linear potentiometer, wiper to one end (variable resistor)",
                   tolerance="20 %", series=p.series, package="panel mount",
                   note="set by the dial table (FILE.knob.csv); trim at the range's ends")
    elif p.kind == "capacitor":
        row.update(description="film capacitor (integrator)", tolerance="1 %",
                   series=p.series, package="radial")  # fmt: skip
    elif p.kind == "diode":
        row.update(description=f"{p.device} small-signal diode", package="DO-35",
                   note=f"netlist model: {p.model}")  # fmt: skip
    elif p.kind == "switch":
        model = circuit.models.get(p.model.lower())
        ron = model.params.get("ron") if model is not None else None
        row.update(description="SPST toggle switch", package="panel mount",
                   note=f"netlist model: voltage-controlled switch {p.model}"
                   + (f" (Ron {float(ron):g} Ohm)" if ron is not None else ""))  # fmt: skip
    elif p.kind == "supply rail":
        row.update(description="supply rail", value=f"{p.value:+g} V", package="bench supply",
                   note="one dual bench supply serves both rails")  # fmt: skip
    elif p.kind == "reference voltage":
        row.update(description="DC reference voltage", value=f"{p.value:+g} V",
                   package="bench source or adjustable reference",
                   note="the netlist uses an ideal source")  # fmt: skip
    elif p.kind == "switch control":
        row.update(description="switch control voltage", package="none",
                   note="drives the switch's control input in the simulation; a manual "
                   "switch needs no part")  # fmt: skip
    else:
        row.update(description="function generator", value=f"{value} amplitude",
                   package="bench instrument", note=p.role)  # fmt: skip
    return row


def _nonstandard_note(ohms: float) -> str:
    """How to build a value in no standard series from two standard ones (equal pair)."""
    if series_label(2 * ohms, "resistor") != "exact":
        return f"not in E24/E96: two {engineering(2 * ohms, 'ohm')} (1 %) in parallel"
    if series_label(ohms / 2, "resistor") != "exact":
        return f"not in E24/E96: two {engineering(ohms / 2, 'ohm')} (1 %) in series"
    return "not in E24/E96: order at 0.1 % or trim"


def order_text(circuit: Circuit, entries: list[BomEntry]) -> str:
    """The order CSV text (header row first)."""
    out = io.StringIO()
    writer = csv.DictWriter(out, ORDER_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(order_rows(circuit, entries))
    return out.getvalue()
