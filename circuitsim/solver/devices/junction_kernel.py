"""Kernel twins of junction.py: the shared transistor equations for one element, compiled.

The same equations as :mod:`circuitsim.solver.devices.junction`, written for scalars so that
the compiled MNA kernel (solver/compiled/mna_terminals.py) evaluates a device without
allocating; each function names the numpy function it mirrors. Scalars only: an array
argument of a compiled function costs a reference-count update per call.
"""

from __future__ import annotations

import math

from circuitsim.solver.jit import njit


@njit(cache=True)
def junction_current(v: float, isat: float, vt: float, gmin: float) -> tuple[float, float]:
    """junction.junction_current of one junction: IS (exp(v / vt) - 1) + gmin v (A) and its
    slope (S), SPICE's cubic below -3 vt."""
    if v < -3 * vt:
        arg = (3 * vt / (v * math.e)) ** 3
        return -isat * (1 + arg) + gmin * v, isat * 3 * arg / v + gmin
    ex = math.exp(min(v / vt, 700.0))
    return isat * (ex - 1) + gmin * v, isat * ex / vt + gmin


@njit(cache=True)
def depletion_charge(v: float, cj0: float, pj: float, mj: float, fc: float):
    """junction.depletion_charge of one junction: charge (C) and capacitance (F)."""
    knee = fc * pj
    if v < knee:
        arg = 1 - v / pj
        sarg = arg ** (-mj)
        return pj * cj0 * (1 - arg * sarg) / (1 - mj), cj0 * sarg
    f1 = pj * (1 - (1 - fc) ** (1 - mj)) / (1 - mj)
    f2 = (1 - fc) ** (1 + mj)
    f3 = 1 - fc * (1 + mj)
    q = cj0 * f1 + cj0 / f2 * (f3 * (v - knee) + mj / (2 * pj) * (v * v - knee * knee))
    return q, cj0 / f2 * (f3 + mj * v / pj)


@njit(cache=True)
def fetlim(vnew: float, vold: float, vto: float) -> float:
    """junction.fetlim (ngspice's DEVfetlim) of one gate voltage, volts."""
    vtsthi = abs(2 * (vold - vto)) + 2
    vtstlo = abs(vold - vto) + 1
    vtox = vto + 3.5
    delv = vnew - vold
    falling = delv <= 0
    if vold >= vto:
        if vold >= vtox:  # on, far above threshold
            if falling:
                if vnew >= vtox:
                    return vold - vtstlo if -delv > vtstlo else vnew
                return max(vnew, vto + 2)
            return vold + vtsthi if delv >= vtsthi else vnew
        # on, just above threshold
        return max(vnew, vto - 0.5) if falling else min(vnew, vto + 4)
    if falling:  # off
        return vold - vtsthi if -delv > vtsthi else vnew
    if vnew <= vto + 0.5:
        return vold + vtstlo if delv > vtstlo else vnew
    return vto + 0.5
