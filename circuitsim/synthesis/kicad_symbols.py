"""The KiCad symbols a generated schematic uses, embedded in its ``lib_symbols`` section.

Each symbol carries the name of KiCad's standard library entry (``Device:R``, ``Device:C``,
``Device:D``, ``Amplifier_Operational:TL074``, ``Simulation_SPICE:VDC`` / ``VSIN`` /
``VPULSE`` / ``VPWL``, ``Switch:SW_SPST``, ``power:GND``) and the same pin numbers and pin
positions as that entry, so a user's "update symbols from library" keeps every wire attached;
the drawings are plain outlines made here. Positions are in millimetres, library coordinates (y up).

:data:`PINS` lists, per library id, each pin as ``(unit, number, name, x, y)``; unit 0 is a
pin common to all units. The TL074 has sections A-D (units 1-4: output, inverting and
non-inverting input) and the supply unit E (unit 5: V+ on pin 4, V- on pin 11).
"""

from __future__ import annotations

from kiutils.items.common import Effects, Font, Position, Property
from kiutils.items.syitems import SyCircle, SyPolyLine, SyRect
from kiutils.symbol import Symbol, SymbolPin

#: (unit, number, name, x, y) of every pin, by library id (library coordinates, mm).
PINS: dict[str, list[tuple[int, str, str, float, float]]] = {
    "Device:R": [(0, "1", "~", 0.0, 3.81), (0, "2", "~", 0.0, -3.81)],
    "Device:C": [(0, "1", "~", 0.0, 3.81), (0, "2", "~", 0.0, -3.81)],
    "Device:D": [(0, "1", "K", 3.81, 0.0), (0, "2", "A", -3.81, 0.0)],
    "Switch:SW_SPST": [(0, "1", "A", -5.08, 0.0), (0, "2", "B", 5.08, 0.0)],
    "Simulation_SPICE:VDC": [(0, "1", "~", 0.0, 5.08), (0, "2", "~", 0.0, -5.08)],
    "Simulation_SPICE:VSIN": [(0, "1", "~", 0.0, 5.08), (0, "2", "~", 0.0, -5.08)],
    "Simulation_SPICE:VPULSE": [(0, "1", "~", 0.0, 5.08), (0, "2", "~", 0.0, -5.08)],
    "Simulation_SPICE:VPWL": [(0, "1", "~", 0.0, 5.08), (0, "2", "~", 0.0, -5.08)],
    "power:GND": [(0, "1", "GND", 0.0, 0.0)],
    "Amplifier_Operational:TL074": [
        (unit, number, name, x, y)
        for unit, (out, minus, plus) in enumerate(
            (("1", "2", "3"), ("7", "6", "5"), ("8", "9", "10"), ("14", "13", "12")), start=1
        )
        for number, name, x, y in (
            (out, "~", 7.62, 0.0), (minus, "-", -7.62, -2.54), (plus, "+", -7.62, 2.54)
        )
    ]
    + [(5, "4", "V+", -2.54, 7.62), (5, "11", "V-", -2.54, -7.62)],
}  # fmt: skip

#: TL074 pin numbers of each section: (non-inverting, inverting, output).
TL074_SECTIONS = {"A": ("3", "2", "1"), "B": ("5", "6", "7"), "C": ("10", "9", "8"),
                  "D": ("12", "13", "14")}  # fmt: skip


def _effects(hide: bool = False) -> Effects:
    return Effects(font=Font(height=1.27, width=1.27), hide=hide)


def _line(*points: tuple[float, float]) -> SyPolyLine:
    return SyPolyLine(points=[Position(x, y) for x, y in points])


def _pin(number: str, name: str, x: float, y: float, length: float, kind: str) -> SymbolPin:
    # a pin points from its connection point towards the body: the angle is that direction
    angle = 0 if x < 0 and abs(x) > abs(y) else 180 if x > 0 and abs(x) > abs(y) else (
        270 if y > 0 else 90)  # fmt: skip
    return SymbolPin(
        electricalType=kind, graphicalStyle="line", position=Position(x, y, angle),
        length=length, name=name, number=number, nameEffects=_effects(),
        numberEffects=_effects(),
    )  # fmt: skip


def _graphics(lib_id: str, unit: int) -> list:
    """The outline of ``lib_id`` (of one TL074 unit)."""
    if lib_id == "Device:R":
        return [SyRect(start=Position(-1.016, 2.54), end=Position(1.016, -2.54))]
    if lib_id == "Device:C":
        return [_line((-2.032, 0.762), (2.032, 0.762)), _line((-2.032, -0.762), (2.032, -0.762))]
    if lib_id == "Device:D":
        return [_line((1.27, 1.27), (1.27, -1.27)),
                _line((1.27, 0), (-1.27, 1.27), (-1.27, -1.27), (1.27, 0))]  # fmt: skip
    if lib_id == "Switch:SW_SPST":
        contacts = [SyCircle(center=Position(x, 0), radius=0.508) for x in (-2.54, 2.54)]
        return [_line((-2.54, 0), (2.032, 1.524)), *contacts]
    if lib_id.startswith("Simulation_SPICE:"):
        marks = [_line((-0.635, 1.905), (0.635, 1.905)), _line((0, 1.27), (0, 2.54))]
        if lib_id.endswith("VSIN"):
            marks.append(_line((-1.27, 0), (-0.635, 0.635), (0.635, -0.635), (1.27, 0)))
        if lib_id.endswith("VPULSE"):
            marks.append(_line((-1.27, -0.635), (-0.635, -0.635), (-0.635, 0.635), (0.635, 0.635),
                               (0.635, -0.635), (1.27, -0.635)))  # fmt: skip
        if lib_id.endswith("VPWL"):
            marks.append(_line((-1.27, -0.635), (-0.381, 0.635), (0.381, -0.254), (1.27, 0.635)))
        return [SyCircle(center=Position(0, 0), radius=2.54), *marks]
    if lib_id == "power:GND":
        return [_line((0, 0), (0, -1.27), (1.27, -1.27), (0, -2.54), (-1.27, -1.27), (0, -1.27))]
    if unit == 5:
        return []
    return [_line((-5.08, 5.08), (5.08, 0), (-5.08, -5.08), (-5.08, 5.08))]


def library_symbol(lib_id: str) -> Symbol:
    """The embedded definition of ``lib_id`` (a key of :data:`PINS`)."""
    nickname, entry = lib_id.split(":")
    reference = {
        "Device:R": "R",
        "Device:C": "C",
        "Device:D": "D",
        "Switch:SW_SPST": "SW",
        "power:GND": "#PWR",
    }.get(lib_id, "V" if nickname == "Simulation_SPICE" else "U")
    properties = [
        Property("Reference", reference, 0, Position(2.032, 0, 0), _effects(lib_id == "power:GND")),
        Property("Value", entry, 1, Position(-2.032, 0, 0), _effects()),
        Property("Footprint", "", 2, Position(0, 0, 0), _effects(True)),
        Property("Datasheet", "~", 3, Position(0, 0, 0), _effects(True)),
    ]
    symbol = Symbol(libraryNickname=nickname, entryName=entry, properties=properties,
                    isPower=lib_id == "power:GND", inBom=lib_id != "power:GND",
                    onBoard=lib_id != "power:GND", pinNamesOffset=0.254)  # fmt: skip
    symbol.pinNames = True
    symbol.pinNamesHide = lib_id != "Amplifier_Operational:TL074"
    symbol.hidePinNumbers = lib_id.startswith("Simulation_SPICE") or lib_id == "power:GND"
    pins = PINS[lib_id]
    units = sorted({unit for unit, *_ in pins}) or [0]
    for unit in units:
        part = Symbol(entryName=entry, unitId=unit, styleId=1, graphicItems=_graphics(lib_id, unit))
        for _, number, name, x, y in (p for p in pins if p[0] == unit):
            kind = "power_in" if lib_id == "power:GND" or name in ("V+", "V-") else (
                "output" if name == "~" and unit else "input" if unit else "passive")  # fmt: skip
            length = 0.0 if lib_id == "power:GND" else 2.54 if abs(x) > 3 or abs(y) > 4.5 else 1.27
            if lib_id == "Amplifier_Operational:TL074" and unit == 5:
                length = 3.81
            if lib_id in ("Device:C",):
                length = 2.794
            part.pins.append(_pin(number, name, x, y, length, kind))
            if lib_id == "power:GND":
                part.pins[-1].hide = True
        symbol.units.append(part)
    return symbol
