"""Derived source values and initial conditions rounded to the digits they carry.

A value computed in floating point (an amplitude times a scale factor, a bias of
``-sigma * beta * c``) carries binary noise in its last digit: 3.3 * 4 is
``13.200000000000001``, and the writer, which writes the shortest text that reads back to
the same float, faithfully writes all 17 digits. :func:`round_derived` rounds such values to
``digits`` significant digits (12 by default: far below any tolerance of a part or a solver,
far above float noise), so the netlist says ``SIN(0 13.2 3)``.

It touches only the values a generator derives: DC and waveform values of independent
sources, capacitor and inductor initial conditions, and ``.ic`` values. Component values
(resistors, capacitors, gains, model parameters) are left exactly as they are: they are parts
with a bill of materials that must agree with the netlist bit for bit. Expressions are left
alone.
"""

from __future__ import annotations

import dataclasses
import math

from circuitsim.netlist.circuit import (
    Capacitor,
    Circuit,
    CurrentSource,
    Inductor,
    Pulse,
    Pwl,
    Sin,
    Subcircuit,
    Value,
    VoltageSource,
    Waveform,
)

DIGITS = 12
"""Significant digits kept of a derived value (binary noise sits in the 16th-17th)."""


def round_significant(value: Value, digits: int = DIGITS) -> Value:
    """``value`` rounded to ``digits`` significant digits; expressions and non-finite as given.

    The result is the float nearest the rounded decimal, so its shortest text has at most
    ``digits`` digits (``13.200000000000001`` -> ``13.2``). Negative zero stays negative.
    """
    if not isinstance(value, float | int) or isinstance(value, bool):
        return value
    number = float(value)
    if not math.isfinite(number) or number == 0.0:
        return number
    return float(f"{number:.{digits}g}")


def round_derived(circuit: Circuit, digits: int = DIGITS) -> Circuit:
    """Round the derived values of ``circuit`` (and its subcircuits) in place; returns it."""
    r = round_significant
    scopes: list[Circuit | Subcircuit] = [circuit]
    while scopes:
        scope = scopes.pop()
        for element in scope.elements:
            if isinstance(element, VoltageSource | CurrentSource):
                element.dc = r(element.dc, digits)
                if element.waveform is not None:
                    element.waveform = _rounded_waveform(element.waveform, digits)
            elif isinstance(element, Capacitor | Inductor) and element.ic is not None:
                element.ic = r(element.ic, digits)
        scopes.extend(scope.subcircuits.values())
    for node, value in circuit.initial_conditions.items():
        circuit.initial_conditions[node] = r(value, digits)
    return circuit


def _rounded_waveform(shape: Waveform, digits: int) -> Waveform:
    if isinstance(shape, Pwl):
        points = tuple(
            (round_significant(t, digits), round_significant(v, digits)) for t, v in shape.points
        )
        return Pwl(points)
    if isinstance(shape, Sin | Pulse):
        changes = {
            f.name: round_significant(getattr(shape, f.name), digits)
            for f in dataclasses.fields(shape)
            if getattr(shape, f.name) is not None
        }
        return dataclasses.replace(shape, **changes)
    return shape
