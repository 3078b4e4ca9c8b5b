"""Device families, one file each; ``FAMILIES`` is the only list the engine reads.

To add a device: write a :class:`~circuitsim.solver.devices.base.DeviceFamily` subclass in a
new file with ``element_types`` naming the circuit element classes it simulates, and append it
here. The engine groups a circuit's elements by these types and never switches on them.
"""

from circuitsim.solver.devices.base import DeviceFamily
from circuitsim.solver.devices.bjt import BjtFamily
from circuitsim.solver.devices.capacitor import CapacitorFamily
from circuitsim.solver.devices.controlled import CccsFamily, CcvsFamily, VccsFamily, VcvsFamily
from circuitsim.solver.devices.diode import DiodeFamily
from circuitsim.solver.devices.inductor import InductorFamily
from circuitsim.solver.devices.jfet import JfetFamily
from circuitsim.solver.devices.poly import (
    PolyCccsFamily,
    PolyCcvsFamily,
    PolyVccsFamily,
    PolyVcvsFamily,
)
from circuitsim.solver.devices.resistor import ResistorFamily
from circuitsim.solver.devices.sources import CurrentSourceFamily, VoltageSourceFamily
from circuitsim.solver.devices.switch import SwitchFamily

FAMILIES: list[type[DeviceFamily]] = [
    ResistorFamily,
    CapacitorFamily,
    InductorFamily,
    VoltageSourceFamily,
    CurrentSourceFamily,
    VcvsFamily,
    VccsFamily,
    CccsFamily,
    CcvsFamily,
    DiodeFamily,
    SwitchFamily,
    PolyVcvsFamily,
    PolyVccsFamily,
    PolyCccsFamily,
    PolyCcvsFamily,
    JfetFamily,
    BjtFamily,
]

__all__ = ["FAMILIES", "DeviceFamily"]
