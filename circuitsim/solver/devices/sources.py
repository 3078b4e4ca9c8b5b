"""Independent voltage and current sources (DC, SIN, PULSE, PWL)."""

from __future__ import annotations

import numpy as np

from circuitsim.netlist.circuit import CurrentSource, VoltageSource
from circuitsim.solver.context import Stamps
from circuitsim.solver.devices.base import DeviceFamily, number
from circuitsim.solver.devices.source_waveforms import SourceValues
from circuitsim.solver.errors import CircuitInputError
from circuitsim.solver.layout import VectorPattern, branch_stamp


class VoltageSourceFamily(DeviceFamily):
    """All V sources: a branch current each, v(n+) - v(n-) = V(t).

    Their branch currents are outputs, ``i(vname)``, flowing from n+ through the source to n-.
    """

    element_types = (VoltageSource,)

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        self.p = layout.nodes([e.positive for e in elements])
        self.n = layout.nodes([e.negative for e in elements])
        self.branch = np.array([layout.add_branch(e.name) for e in elements], dtype=np.intp)
        self.values = SourceValues(elements)
        self.phasors = ac_phasors(elements)

    def stamp_linear(self, stamps: Stamps) -> None:
        stamps.add(*branch_stamp(self.p, self.n, self.branch))

    def output_signals(self) -> dict[str, int]:
        return {
            f"i({name.lower()})": int(b) for name, b in zip(self.names, self.branch, strict=True)
        }

    def set_timing(self, tstep: float, tstop: float) -> None:
        self.values.set_timing(tstep, tstop)

    def set_sine(self, name: str, amplitude: float, phase: float) -> None:
        """Set a SIN source's amplitude (V) and phase (degrees) for the next run of this
        assembly (solver/continuation.py: a generator whose phase follows the time a chain
        of runs has reached).

        Raises
        ------
        CircuitInputError
            ``name`` is not a SIN source of this family.
        """
        index = self.names.index(name) if name in self.names else -1
        if index not in self.values.sin_index:
            raise CircuitInputError(f"{name}: no SIN voltage source of that name")
        j = self.values.sin_index.index(index)
        self.values.sin["amplitude"][j] = float(amplitude)
        self.values.sin["phase"][j] = float(phase)

    def source_rhs(self, time: float, scale: float, rhs: np.ndarray, dc: bool) -> None:
        rhs[self.branch] += scale * self.values.values(time, dc)

    def ac_source(self, rhs: np.ndarray) -> None:
        rhs[self.branch] += self.phasors

    def breakpoints(self, tstop: float) -> np.ndarray:
        return self.values.breakpoints(tstop)

    def kernel_data(self) -> dict:
        none = np.full(self.branch.size, -1)
        rows = np.stack([self.branch, none], axis=1)
        signs = np.tile([1.0, 0.0], (self.branch.size, 1))
        return {"kind": "sources", "values": self.values, "rows": rows, "signs": signs}


class CurrentSourceFamily(DeviceFamily):
    """All I sources: current I(t) leaves n+ through the source and enters n-."""

    element_types = (CurrentSource,)

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        p = layout.nodes([e.positive for e in elements])
        n = layout.nodes([e.negative for e in elements])
        self.terminals = np.stack([p, n], axis=1)
        self.rows = VectorPattern(np.stack([p, n]))
        self.values = SourceValues(elements)
        self.phasors = ac_phasors(elements)

    def set_timing(self, tstep: float, tstop: float) -> None:
        self.values.set_timing(tstep, tstop)

    def source_rhs(self, time: float, scale: float, rhs: np.ndarray, dc: bool) -> None:
        i = scale * self.values.values(time, dc)
        self.rows.add(rhs, np.stack([-i, i]))

    def ac_source(self, rhs: np.ndarray) -> None:
        self.rows.add(rhs, np.stack([-self.phasors, self.phasors]))

    def breakpoints(self, tstop: float) -> np.ndarray:
        return self.values.breakpoints(tstop)

    def kernel_data(self) -> dict:
        signs = np.tile([-1.0, 1.0], (self.terminals.shape[0], 1))
        return {"kind": "sources", "values": self.values, "rows": self.terminals, "signs": signs}


def ac_phasors(elements) -> np.ndarray:
    """Each source's ``AC mag phase`` as a complex amplitude (V or A; phase in degrees)."""
    magnitude = np.array([number(e.ac_magnitude, e.name, "AC magnitude") for e in elements])
    phase = np.array([number(e.ac_phase, e.name, "AC phase") for e in elements])
    return magnitude * np.exp(1j * np.radians(phase))
