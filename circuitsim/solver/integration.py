"""Integration methods: charge history -> companion coefficients, and truncation error.

Each method gives, for order 1 or 2 and the last step sizes, coefficients such that

    dq/dt (t_n) = a0 q_n + a1 q_{n-1} + a2 q_{n-2} + b1 dq/dt (t_{n-1})

and the factor of its local truncation error (ngspice's trapCoeff / gearCoeff). Order 1 is
backward Euler for both methods. The time-step proposal follows ngspice's CKTterr: the
(order+1)-th divided difference of each charge against a tolerance built from reltol, abstol
and chgtol, scaled by trtol.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from circuitsim.solver.options import SimulationOptions


@dataclass(frozen=True)
class Method:
    """An integration method: name and error constants for orders 1 and 2."""

    name: str
    error_constants: tuple[float, float]

    def coefficients(self, order: int, h: float, h_prev: float) -> tuple[float, ...]:
        """(a0, a1, a2, b1) for a step ``h`` after a step ``h_prev`` (seconds)."""
        if order == 1:
            return 1.0 / h, -1.0 / h, 0.0, 0.0
        if self.name == "trap":
            return 2.0 / h, -2.0 / h, 0.0, -1.0
        # BDF2 on a variable grid.
        a0 = (2 * h + h_prev) / (h * (h + h_prev))
        a1 = -(h + h_prev) / (h * h_prev)
        a2 = h / (h_prev * (h + h_prev))
        return a0, a1, a2, 0.0


METHODS = {
    "trap": Method("trap", (0.5, 1.0 / 12.0)),
    "gear": Method("gear", (0.5, 2.0 / 9.0)),
}


def truncation_step(
    method: Method,
    order: int,
    times: list[float],
    charges: list[np.ndarray],
    currents: list[np.ndarray],
    options: SimulationOptions,
) -> float:
    """Largest step (s) the charges' truncation error allows, ngspice's CKTterr rule.

    Parameters
    ----------
    method : Method
    order : int
        1 or 2; needs ``order + 2`` points.
    times : list of float
        t_n, t_{n-1}, ... (newest first), seconds.
    charges : list of ndarray, shape (n_charges,)
        Charges (C) or fluxes (Wb) at those times, newest first.
    currents : list of ndarray, shape (n_charges,)
        Their derivatives at t_n and t_{n-1}.
    options : SimulationOptions
    """
    if charges[0].size == 0:
        return np.inf
    t0, t1, t2 = times[0], times[1], times[2]
    h = t0 - t1
    q0, q1, q2 = charges[0], charges[1], charges[2]
    # divided differences of all charges at once, time differences as Python floats
    d1a = (q0 - q1) * (1.0 / h)
    d1b = (q1 - q2) * (1.0 / (t1 - t2))
    diff = (d1a - d1b) * (1.0 / (t0 - t2))
    if order == 2:
        t3 = times[3]
        d1c = (q2 - charges[3]) * (1.0 / (t2 - t3))
        diff = (diff - (d1b - d1c) * (1.0 / (t1 - t3))) * (1.0 / (t0 - t3))
    reltol = options.reltol
    volttol = np.maximum(np.abs(currents[0]), np.abs(currents[1]))
    volttol *= reltol
    volttol += options.abstol
    chargetol = np.maximum(np.abs(q0), np.abs(q1))
    np.maximum(chargetol, options.chgtol, out=chargetol)
    chargetol *= reltol / h
    tol = np.maximum(volttol, chargetol)
    factor = method.error_constants[order - 1]
    denominator = np.abs(diff)
    denominator *= factor
    np.maximum(denominator, options.abstol, out=denominator)
    step = options.trtol * float(np.min(tol / denominator))
    return math.sqrt(step) if order == 2 else step
