"""Equations shared by the transistor families: pn-junction current and depletion charge,
ngspice's FET voltage limiting, series resistances with private nodes, model checks.

All functions take and return numpy arrays (one entry per device). Kernel twin:
:mod:`circuitsim.solver.devices.junction_kernel` (the same equations for one element, for the
compiled MNA kernel).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from circuitsim.netlist.circuit import Model
from circuitsim.solver.context import Stamps
from circuitsim.solver.errors import CircuitInputError
from circuitsim.solver.layout import Layout, conductance_values, two_terminal_pattern


def junction_current(v, isat, vt, gmin) -> tuple[np.ndarray, np.ndarray]:
    """Ideal junction IS (exp(v / vt) - 1) plus gmin v, A, and its slope, S.

    Below -3 vt SPICE replaces the exponential by a cubic tending to -IS (DIOload, JFETload).
    """
    reverse = v < -3 * vt
    ex = np.exp(np.minimum(v / vt, 700.0))
    vr = np.minimum(v, -3 * vt)  # negative where used, so the division is defined
    arg = (3 * vt / (vr * np.e)) ** 3
    current = np.where(reverse, -isat * (1 + arg), isat * (ex - 1)) + gmin * v
    slope = np.where(reverse, isat * 3 * arg / vr, isat * ex / vt) + gmin
    return current, slope


def exponential_current(v, isat, vt) -> tuple[np.ndarray, np.ndarray]:
    """:func:`junction_current` without gmin (the BJT adds gmin once per junction)."""
    return junction_current(v, isat, vt, 0.0)


def depletion_charge(v, cj0, pj, mj, fc) -> tuple[np.ndarray, np.ndarray]:
    """SPICE's depletion charge (C) and capacitance (F) of a junction.

    Below FC PJ: PJ CJ0 (1 - (1 - v/PJ)^(1 - MJ)) / (1 - MJ); above, its linear-quadratic
    continuation (ngspice's f1, f2, f3).
    """
    knee = fc * pj
    below = v < knee
    arg = 1 - np.minimum(v, knee) / pj
    sarg = arg ** (-mj)
    q_below = pj * cj0 * (1 - arg * sarg) / (1 - mj)
    f1 = pj * (1 - (1 - fc) ** (1 - mj)) / (1 - mj)
    f2 = (1 - fc) ** (1 + mj)
    f3 = 1 - fc * (1 + mj)
    q_above = cj0 * f1 + cj0 / f2 * (f3 * (v - knee) + mj / (2 * pj) * (v * v - knee * knee))
    c_above = cj0 / f2 * (f3 + mj * v / pj)
    return np.where(below, q_below, q_above), np.where(below, cj0 * sarg, c_above)


def fetlim(vnew: np.ndarray, vold: np.ndarray, vto: np.ndarray) -> np.ndarray:
    """ngspice's DEVfetlim, vectorized: keeps a gate voltage step from crossing far past the
    threshold ``vto`` in one Newton iteration (volts)."""
    vtsthi = np.abs(2 * (vold - vto)) + 2
    vtstlo = np.abs(vold - vto) + 1
    vtox = vto + 3.5
    delv = vnew - vold
    falling = delv <= 0
    # on, far above threshold
    on_high = np.where(
        falling,
        np.where(
            vnew >= vtox,
            np.where(-delv > vtstlo, vold - vtstlo, vnew),
            np.maximum(vnew, vto + 2),
        ),
        np.where(delv >= vtsthi, vold + vtsthi, vnew),
    )
    # on, just above threshold
    on_middle = np.where(falling, np.maximum(vnew, vto - 0.5), np.minimum(vnew, vto + 4))
    # off
    off = np.where(
        falling,
        np.where(-delv > vtsthi, vold - vtsthi, vnew),
        np.where(vnew <= vto + 0.5, np.where(delv > vtstlo, vold + vtstlo, vnew), vto + 0.5),
    )
    return np.where(vold >= vto, np.where(vold >= vtox, on_high, on_middle), off)


@dataclass
class SeriesResistance:
    """Resistors between each device's outer terminal and a private inner node (where R > 0).

    ``inner`` is the node the device's equations use: the outer node where R = 0.
    """

    outer: np.ndarray
    inner: np.ndarray
    index: np.ndarray  # devices with R > 0
    conductance: np.ndarray

    def stamp(self, stamps: Stamps) -> None:
        if self.index.size:
            pattern = two_terminal_pattern(self.outer[self.index], self.inner[self.index])
            stamps.add(pattern, conductance_values(self.conductance))


def series_resistance_nodes(
    layout: Layout, names: list[str], outer: np.ndarray, resistance: np.ndarray, what: str
) -> SeriesResistance:
    """Private nodes ``NAME#what`` behind series resistances > 0 (ohms)."""
    inner = outer.copy()
    index = np.flatnonzero(resistance > 0)
    for i in index:
        inner[i] = layout.add_internal_node(f"{names[i]}#{what}")
    return SeriesResistance(outer, inner, index, 1.0 / resistance[index])


def unsupported_parameters(
    model: Model,
    owner: str,
    modelled: dict[str, float],
    ignored: tuple[str, ...],
    allowed_values: dict[str, tuple[float, ...]],
) -> None:
    """Refuse model parameters the family does not model (a clear error, not a silent
    difference from ngspice); ``ignored`` ones have no effect at 27 C in a transient.

    ``allowed_values``: parameters accepted only at these values (LEVEL=1 ...).
    """
    for key, value in model.params.items():
        key = key.lower()
        if key in allowed_values:
            try:
                ok = float(value) in allowed_values[key]
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise CircuitInputError(
                    f"{owner} (.model {model.name}): {key.upper()}={value} is not supported "
                    f"(only {', '.join(f'{v:g}' for v in allowed_values[key])})"
                )
        elif key not in modelled and key not in ignored:
            raise CircuitInputError(
                f"{owner} (.model {model.name}): parameter {key.upper()} is not modelled by "
                f"the builtin engine (it models {', '.join(k.upper() for k in modelled)}); "
                "--engine ngspice runs it"
            )
