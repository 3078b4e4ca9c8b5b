"""Resistors: one constant conductance stamp per element."""

from __future__ import annotations

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
        bad = np.flatnonzero(r == 0)
        if bad.size:
            raise CircuitInputError(f"{elements[bad[0]].name}: resistance 0 is not allowed")
        self.conductance = 1.0 / r
        p = layout.nodes([e.positive for e in elements])
        n = layout.nodes([e.negative for e in elements])
        self.pattern = two_terminal_pattern(p, n)

    def stamp_linear(self, stamps: Stamps) -> None:
        stamps.add(self.pattern, conductance_values(self.conductance))
