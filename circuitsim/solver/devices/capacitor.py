"""Capacitors: a linear charge q = C (v+ - v-) per element, handed to the integrator."""

from __future__ import annotations

import numpy as np

from circuitsim.netlist.circuit import Capacitor
from circuitsim.solver.context import Stamps
from circuitsim.solver.devices.base import DeviceFamily, number
from circuitsim.solver.layout import MatrixPattern


class CapacitorFamily(DeviceFamily):
    """All capacitors; ``IC=`` gives the starting voltage under ``uic``."""

    element_types = (Capacitor,)

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        self.capacitance = np.array(
            [number(e.capacitance, e.name, "capacitance") for e in elements]
        )
        self.p = layout.nodes([e.positive for e in elements])
        self.n = layout.nodes([e.negative for e in elements])
        self.slots = layout.add_charges(len(elements))
        ic = [number(e.ic, e.name, "IC") if e.ic is not None else np.nan for e in elements]
        self.ic = np.array(ic)

    def stamp_charges(self, charges: Stamps, incidence: Stamps) -> None:
        c = self.capacitance
        charges.add(
            MatrixPattern(np.stack([self.slots, self.slots]), np.stack([self.p, self.n])),
            np.stack([c, -c]),
        )
        incidence.add(
            MatrixPattern(np.stack([self.p, self.n]), np.stack([self.slots, self.slots])),
            np.stack([np.ones_like(c), -np.ones_like(c)]),
        )

    def initial_conditions(self, x0: np.ndarray, q0: np.ndarray) -> None:
        given = ~np.isnan(self.ic)
        q0[self.slots[given]] = self.capacitance[given] * self.ic[given]
