"""Resistors: one constant conductance stamp per element."""

from __future__ import annotations

import copy

import numpy as np

from circuitsim.netlist.circuit import Resistor
from circuitsim.solver.context import Stamps
from circuitsim.solver.devices.base import DeviceFamily, number
from circuitsim.solver.errors import CircuitInputError
from circuitsim.solver.layout import conductance_values, two_terminal_pattern


class ResistorFamily(DeviceFamily):
    """All resistors: G += 1/R between n+ and n-."""

    element_types = (Resistor,)

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        r = np.array([number(e.resistance, e.name, "resistance") for e in elements])
        self.conductance = _conductances(r, self.names)
        p = layout.nodes([e.positive for e in elements])
        n = layout.nodes([e.negative for e in elements])
        self.pattern = two_terminal_pattern(p, n)

    def with_values(self, values: dict[str, float]) -> ResistorFamily:
        """A copy with the named resistors' resistances (ohm) replaced; its conductances equal,
        bit for bit, those of a family built with the new values."""
        index = {name: k for k, name in enumerate(self.names)}
        unknown = [name for name in values if name not in index]
        if unknown:
            raise CircuitInputError(f"{', '.join(unknown)}: no such resistor")
        names = list(values)
        chosen = np.array([index[name] for name in names], dtype=np.int64)
        new = np.array([number(values[name], name, "resistance") for name in names])
        changed = copy.copy(self)
        changed.conductance = self.conductance.copy()
        changed.conductance[chosen] = _conductances(new, names)
        return changed

    def stamp_linear(self, stamps: Stamps) -> None:
        stamps.add(self.pattern, conductance_values(self.conductance))


def _conductances(r: np.ndarray, names: list[str]) -> np.ndarray:
    """1 / r (S), or a clear error naming the first zero resistance."""
    bad = np.flatnonzero(r == 0)
    if bad.size:
        raise CircuitInputError(f"{names[bad[0]]}: resistance 0 is not allowed")
    return 1.0 / r
