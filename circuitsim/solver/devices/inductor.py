"""Inductors: a branch current i and a linear flux L i, with v+ - v- = d(L i)/dt."""

from __future__ import annotations

import numpy as np

from circuitsim.netlist.circuit import Inductor
from circuitsim.solver.context import Stamps
from circuitsim.solver.devices.base import DeviceFamily, number
from circuitsim.solver.layout import MatrixPattern, branch_stamp


class InductorFamily(DeviceFamily):
    """All inductors; ``IC=`` gives the starting current (n+ to n- inside) under ``uic``."""

    element_types = (Inductor,)

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        self.inductance = np.array([number(e.inductance, e.name, "inductance") for e in elements])
        self.p = layout.nodes([e.positive for e in elements])
        self.n = layout.nodes([e.negative for e in elements])
        self.branch = np.array([layout.add_branch(e.name) for e in elements], dtype=np.intp)
        self.slots = layout.add_charges(len(elements))
        ic = [number(e.ic, e.name, "IC") if e.ic is not None else np.nan for e in elements]
        self.ic = np.array(ic)

    def stamp_linear(self, stamps: Stamps) -> None:
        # KCL: the branch current leaves n+ and enters n-; branch row: v+ - v- - dphi/dt = 0.
        stamps.add(*branch_stamp(self.p, self.n, self.branch))

    def stamp_charges(self, charges: Stamps, incidence: Stamps) -> None:
        charges.add(MatrixPattern(self.slots[None, :], self.branch[None, :]), self.inductance)
        incidence.add(MatrixPattern(self.branch[None, :], self.slots[None, :]), -1.0)

    def initial_conditions(self, x0: np.ndarray, q0: np.ndarray) -> None:
        given = ~np.isnan(self.ic)
        x0[self.branch[given]] = self.ic[given]
        q0[self.slots[given]] = self.inductance[given] * self.ic[given]
