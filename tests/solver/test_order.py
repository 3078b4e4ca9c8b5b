"""Order of the integration methods: halve a fixed step and fit the error slope."""

import numpy as np
import pytest

from circuitsim.netlist.circuit import Capacitor, Circuit, Resistor, Sin, VoltageSource
from circuitsim.solver import SimulationOptions, transient

R, C, F = 1e3, 1e-6, 200.0


def exact(t):
    wt, k = 2 * np.pi * F * t, 2 * np.pi * F * R * C
    return (np.sin(wt) - k * np.cos(wt) + k * np.exp(-t / (R * C))) / (1 + k**2)


def final_error(method: str, maxord: int, h: float, kernel: str) -> float:
    c = Circuit(
        elements=[
            VoltageSource("V1", "in", "0", waveform=Sin(0.0, 1.0, F)),
            Resistor("R1", "in", "out", R),
            Capacitor("C1", "out", "0", C),
        ]
    )
    opts = SimulationOptions(method=method, maxord=maxord, fixed_step=h, kernel=kernel)
    w = transient(c, h, 4e-3, tmax=h, options=opts)
    return float(np.max(np.abs(w["out"] - exact(w.time))))


@pytest.mark.parametrize("kernel", ["python", "compiled"])
@pytest.mark.parametrize(
    ("method", "maxord", "order"), [("trap", 2, 2), ("gear", 2, 2), ("trap", 1, 1)]
)
def test_convergence_order(method, maxord, order, kernel):
    steps = 4e-3 / np.array([100, 200, 400, 800])
    errors = [final_error(method, maxord, h, kernel) for h in steps]
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - order) < 0.15, (slope, errors)
