"""Linear controlled sources: E (VCVS), G (VCCS), F (CCCS), H (CCVS).

All four are constant matrix stamps. E and H own a branch current; F and H read the branch
current of their controlling source, resolved in :meth:`bind` once every branch exists.
"""

from __future__ import annotations

import numpy as np

from circuitsim.netlist.circuit import Cccs, Ccvs, Vccs, Vcvs
from circuitsim.solver.context import Stamps
from circuitsim.solver.devices.base import DeviceFamily, number
from circuitsim.solver.layout import MatrixPattern


def _terminals(layout, elements):
    return (
        layout.nodes([e.positive for e in elements]),
        layout.nodes([e.negative for e in elements]),
    )


class VcvsFamily(DeviceFamily):
    """E: v(n+) - v(n-) = gain (v(nc+) - v(nc-)), with a branch current."""

    element_types = (Vcvs,)

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        self.p, self.n = _terminals(layout, elements)
        self.cp = layout.nodes([e.control_positive for e in elements])
        self.cn = layout.nodes([e.control_negative for e in elements])
        self.gain = np.array([number(e.gain, e.name, "gain") for e in elements])
        self.branch = np.array([layout.add_branch(e.name) for e in elements], dtype=np.intp)

    def stamp_linear(self, stamps: Stamps) -> None:
        b, one, k = self.branch, np.ones(len(self.branch)), self.gain
        stamps.add(
            MatrixPattern(
                np.stack([self.p, self.n, b, b, b, b]),
                np.stack([b, b, self.p, self.n, self.cp, self.cn]),
            ),
            np.stack([one, -one, one, -one, -k, k]),
        )


class VccsFamily(DeviceFamily):
    """G: current gm (v(nc+) - v(nc-)) leaves n+ through the source into n-."""

    element_types = (Vccs,)

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        self.p, self.n = _terminals(layout, elements)
        self.cp = layout.nodes([e.control_positive for e in elements])
        self.cn = layout.nodes([e.control_negative for e in elements])
        self.gm = np.array(
            [number(e.transconductance, e.name, "transconductance") for e in elements]
        )

    def stamp_linear(self, stamps: Stamps) -> None:
        g = self.gm
        stamps.add(
            MatrixPattern(
                np.stack([self.p, self.p, self.n, self.n]),
                np.stack([self.cp, self.cn, self.cp, self.cn]),
            ),
            np.stack([g, -g, -g, g]),
        )


class CccsFamily(DeviceFamily):
    """F: current gain * i(vcontrol) leaves n+ through the source into n-."""

    element_types = (Cccs,)

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        self.p, self.n = _terminals(layout, elements)
        self.gain = np.array([number(e.gain, e.name, "gain") for e in elements])

    def bind(self, layout) -> None:
        self.control = np.array(
            [layout.branch(e.control, e.name) for e in self.elements], dtype=np.intp
        )

    def stamp_linear(self, stamps: Stamps) -> None:
        k = self.gain
        stamps.add(
            MatrixPattern(np.stack([self.p, self.n]), np.stack([self.control, self.control])),
            np.stack([k, -k]),
        )


class CcvsFamily(DeviceFamily):
    """H: v(n+) - v(n-) = r * i(vcontrol), with a branch current."""

    element_types = (Ccvs,)

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        self.p, self.n = _terminals(layout, elements)
        self.r = np.array([number(e.transresistance, e.name, "transresistance") for e in elements])
        self.branch = np.array([layout.add_branch(e.name) for e in elements], dtype=np.intp)

    def bind(self, layout) -> None:
        self.control = np.array(
            [layout.branch(e.control, e.name) for e in self.elements], dtype=np.intp
        )

    def stamp_linear(self, stamps: Stamps) -> None:
        b, one = self.branch, np.ones(len(self.branch))
        stamps.add(
            MatrixPattern(
                np.stack([self.p, self.n, b, b, b]), np.stack([b, b, self.p, self.n, self.control])
            ),
            np.stack([one, -one, one, -one, -self.r]),
        )
