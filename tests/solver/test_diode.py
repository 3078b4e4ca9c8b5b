"""The diode's limiting and characteristic against scalar transcriptions of SPICE's rules."""

import math

import numpy as np

from circuitsim.netlist.circuit import Circuit, Diode, Model
from circuitsim.solver.devices.diode import THERMAL_VOLTAGE, DiodeFamily, pnjlim
from circuitsim.solver.layout import Layout
from circuitsim.solver.options import SimulationOptions


def spice_pnjlim(vnew, vold, vt, vcrit):
    """DEVpnjlim as SPICE3/ngspice describe it, one junction at a time."""
    if vnew > vcrit and abs(vnew - vold) > 2 * vt:
        if vold > 0:
            arg = 1 + (vnew - vold) / vt
            return vold + vt * math.log(arg) if arg > 0 else vcrit
        return vt * math.log(vnew / vt)
    if vnew < 0:
        floor = -vold - 1 if vold > 0 else 2 * vold - 1
        if vnew < floor:
            return floor
    return vnew


def test_pnjlim_matches_the_scalar_rule():
    rng = np.random.default_rng(0)
    vnew, vold = rng.uniform(-20, 20, 20000), rng.uniform(-5, 5, 20000)
    vt, vcrit = np.full(vnew.size, 0.03), np.full(vnew.size, 0.6)
    limited, any_limited = pnjlim(vnew, vold, vt, vcrit)
    expected = [spice_pnjlim(*args) for args in zip(vnew, vold, vt, vcrit, strict=True)]
    assert np.allclose(limited, expected, rtol=1e-14, atol=1e-15)
    assert any_limited
    assert pnjlim(np.array([0.1]), np.array([0.09]), vt[:1], vcrit[:1])[1] is False


def test_current_is_shockley_forward_and_spice_cubic_reverse():
    c = Circuit(elements=[Diode("D1", "a", "0", "dm")])
    c.models["dm"] = Model("dm", "D", {"is": 2e-9, "n": 1.8})
    family = DiodeFamily(c.elements, c, Layout(["a"]), SimulationOptions(gmin=1e-12))
    vte = 1.8 * THERMAL_VOLTAGE
    vd = np.array([-2.0, -0.2, 0.0, 0.3, 0.7])
    cd, gd = family._current(vd)
    forward = vd >= -3 * vte
    shockley = 2e-9 * np.expm1(vd / vte)
    safe = np.minimum(vd, -3 * vte)
    cubic = -2e-9 * (1 + (3 * vte / (safe * math.e)) ** 3)
    expected = np.where(forward, shockley, cubic) + 1e-12 * vd
    assert np.allclose(cd, expected, rtol=1e-12, atol=1e-25)
    # conductance is the derivative of the current (central difference)
    h = 1e-7
    numeric = (family._current(vd + h)[0] - family._current(vd - h)[0]) / (2 * h)
    assert np.allclose(gd, numeric, rtol=1e-5)
