"""The physical parts of a generated circuit: what a person solders or connects.

:func:`board_parts` walks a :class:`~circuitsim.netlist.circuit.Circuit` and lists every
element as a :class:`Part`: resistors and capacitors (with the translator's coefficient records),
op-amp sections packed into quad packages, diodes, switches and voltage sources (supply rails,
reference voltages, switch controls, signal generators). Op-amp sections whose names follow the
paper (``XU1A`` ... ``XU2D``: package U1, section A) keep that place; every other section fills
the free places of those packages first, then new packages U3, U4 ..., so a circuit of n sections
needs ceil(n / 4) packages when the named ones leave no gaps.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from circuitsim.netlist.circuit import (
    Capacitor,
    Circuit,
    Diode,
    Resistor,
    SubcircuitCall,
    Switch,
    VoltageSource,
)
from circuitsim.synthesis.blocks import BomEntry
from circuitsim.synthesis.eseries import E24, E96, _decade
from circuitsim.synthesis.opamps import SUPPLY_NODES, is_opamp_call

E6 = (1.0, 1.5, 2.2, 3.3, 4.7, 6.8)
E12 = (1.0, 1.2, 1.5, 1.8, 2.2, 2.7, 3.3, 3.9, 4.7, 5.6, 6.8, 8.2)

#: Series a value is looked up in, coarsest first (a shop stocks the coarse ones everywhere).
RESISTOR_SERIES = (("E24", E24), ("E96", E96))
CAPACITOR_SERIES = (("E6", E6), ("E12", E12), ("E24", E24))

SECTIONS_PER_PACKAGE = 4
SECTION_LETTERS = "ABCD"

#: The quad package proposed for each op-amp model; an ideal model is built with a TL074.
QUAD_PART = {"TL074": "TL074", "OPAMP_IDEAL": "TL074"}

#: The diode part proposed for each library diode model.
DIODE_PART = {"D1N4148": "1N4148"}

_PAPER_SECTION = re.compile(r"^XU(\d+)([A-D])$", re.IGNORECASE)


@dataclass(frozen=True)
class Part:
    """One part of the board (a row of the per-part bill of materials).

    Attributes
    ----------
    part : str
        Netlist element name (``"R31"``, ``"XU1A"``, ``"DFLANGE_ABS1_1"``).
    designator : str
        Reference designator on the board: the name without SPICE's type letter for op-amp
        sections (``"U3A"``: package U3, section A), the element name otherwise.
    kind : str
        ``resistor``, ``potentiometer`` (value: its full resistance; the netlist holds its
        setting), ``capacitor``, ``op-amp section``, ``diode``, ``switch``,
        ``supply rail``, ``reference voltage``, ``switch control`` or ``signal generator``.
    value : float
        Ohms, farads or volts (a generator's amplitude); NaN for parts with no value.
    unit : str
        ``ohm``, ``F``, ``V`` or empty.
    series : str
        ``E24``/``E96`` (resistors), ``E6``/``E12``/``E24`` (capacitors) when the value is a
        member, ``exact`` when it is in none; empty for parts with no value.
    device : str
        The real part proposed (``TL074``, ``1N4148``) or empty.
    model : str
        The netlist's model or subcircuit for the part (``TL074``, ``OPAMP_IDEAL``,
        ``D1N4148``, ``SW_FLANGE``) or empty.
    role : str
        What the part does, in words.
    entry : BomEntry or None
        The translator's record (coefficient target, realized, error) for resistors and
        capacitors it placed.
    """

    part: str
    designator: str
    kind: str
    value: float
    unit: str
    series: str
    device: str
    model: str
    role: str
    entry: BomEntry | None = None


def series_label(value: float, kind: str) -> str:
    """The coarsest standard series holding ``value`` (relative 1e-9), else ``exact``.

    Resistors are looked up in E24 then E96, capacitors in E6, E12 then E24.
    """
    if not (value > 0 and math.isfinite(value)):
        return "exact"
    mantissa = _decade(value)[1]
    table = CAPACITOR_SERIES if kind == "capacitor" else RESISTOR_SERIES
    for name, members in table:
        if any(abs(mantissa / m - 1.0) < 1e-9 for m in (*members, 10.0)):
            return name
    return "exact"


def board_parts(circuit: Circuit, bom: list[BomEntry]) -> list[Part]:
    """Every part of ``circuit`` in netlist order, op-amp sections packed into quad packages.

    Parameters
    ----------
    circuit : Circuit
        The generated circuit (its elements are read, nothing is changed).
    bom : list of BomEntry
        The translator's records; a resistor or capacitor's role and coefficient come from its
        record (matched by name, case-insensitive).

    Returns
    -------
    list of Part
    """
    records = {e.part.lower(): e for e in bom}
    controls = {e.control_positive.lower() for e in circuit.elements if isinstance(e, Switch)}
    designators = _pack_sections(
        [e.name for e in circuit.elements if _opamp_model(circuit, e) is not None]
    )
    parts = []
    for element in circuit.elements:
        name = element.name
        record = records.get(name.lower())
        if record is not None and not math.isnan(record.nominal):  # a potentiometer
            parts.append(
                Part(name, name, "potentiometer", record.nominal, "ohm", record.series, "",
                     "", record.role, record)
            )  # fmt: skip
        elif isinstance(element, Resistor | Capacitor):
            kind = "resistor" if isinstance(element, Resistor) else "capacitor"
            value = float(element.resistance if kind == "resistor" else element.capacitance)
            role = record.role if record else ""
            unit = "ohm" if kind == "resistor" else "F"
            parts.append(
                Part(name, name, kind, value, unit, series_label(value, kind), "", "", role,
                     record)
            )  # fmt: skip
        elif (model := _opamp_model(circuit, element)) is not None:
            parts.append(
                Part(name, designators[name], "op-amp section", math.nan, "", "",
                     QUAD_PART.get(model, model), model, _opamp_role(element))
            )  # fmt: skip
        elif isinstance(element, Diode):
            model = circuit.models[element.model.lower()].name
            parts.append(
                Part(name, name, "diode", math.nan, "", "", DIODE_PART.get(model.upper(), model),
                     model, f"{element.anode} -> {element.cathode}")
            )  # fmt: skip
        elif isinstance(element, Switch):
            parts.append(
                Part(name, name, "switch", math.nan, "", "", "SPST switch", element.model,
                     f"connects {element.positive} and {element.negative}")
            )  # fmt: skip
        elif isinstance(element, VoltageSource):
            parts.append(_source_part(element, controls))
    return parts


def _opamp_model(circuit: Circuit, element) -> str | None:
    """The library subcircuit name if ``element`` is an op-amp section, else None."""
    if not is_opamp_call(circuit, element):
        return None
    definition = circuit.subcircuits.get(element.subcircuit.lower())
    name = definition.name if definition is not None else element.subcircuit
    return name.upper()


def _opamp_role(element: SubcircuitCall) -> str:
    return f"op-amp section, output {element.connections[-1]}"


def _pack_sections(names: list[str]) -> dict[str, str]:
    """Designator (``U3A``) of every op-amp section name, each place used once.

    Paper names (``XU<p><A-D>``) keep their place; the rest fill the free places of the
    packages in use (lowest package and letter first), then new packages after the highest.
    """
    taken: dict[tuple[int, str], str] = {}
    placed: dict[str, str] = {}
    for name in names:
        found = _PAPER_SECTION.match(name)
        if found:
            place = (int(found.group(1)), found.group(2).upper())
            if place not in taken:
                taken[place] = name
                placed[name] = f"U{place[0]}{place[1]}"
    free = [
        (package, letter)
        for package in sorted({p for p, _ in taken})
        for letter in SECTION_LETTERS
        if (package, letter) not in taken
    ]
    package = max((p for p, _ in taken), default=0)
    for name in names:
        if name in placed:
            continue
        if not free:
            package += 1
            free = [(package, letter) for letter in SECTION_LETTERS]
        place = free.pop(0)
        placed[name] = f"U{place[0]}{place[1]}"
    return placed


def _source_part(source: VoltageSource, controls: set[str]) -> Part:
    """A voltage source as a supply rail, switch control, signal generator or reference."""
    name = source.name
    node = source.positive.lower()
    if node in controls:  # checked first: a switch closing at t_on is driven by a PULSE
        volts = float(source.dc) if source.waveform is None else _pulsed(source.waveform)
        return Part(
            name, name, "switch control", volts, "V", "", "", "",
            f"drives the control input {node} of a switch",
        )  # fmt: skip
    if source.waveform is not None:
        amplitude = _level(source.waveform, "amplitude")
        frequency = _level(source.waveform, "frequency")
        return Part(
            name, name, "signal generator", float(amplitude), "V", "", "", "",
            f"{type(source.waveform).__name__.upper()} into {node}, {frequency:g} Hz",
        )  # fmt: skip
    volts = float(source.dc)
    if node in SUPPLY_NODES and source.negative == "0":
        return Part(name, name, "supply rail", volts, "V", "", "", "", f"op-amp supply {node}")
    return Part(name, name, "reference voltage", volts, "V", "", "", "", f"bias at {node}")


def _pulsed(waveform) -> float:
    """The level a switch-control waveform switches to (volts), NaN if it has none."""
    return _level(waveform, "pulsed")


def _level(waveform, attribute: str) -> float:
    """``waveform.attribute`` as a number, NaN if absent or an expression."""
    try:
        return float(getattr(waveform, attribute, math.nan))
    except (TypeError, ValueError):
        return math.nan
