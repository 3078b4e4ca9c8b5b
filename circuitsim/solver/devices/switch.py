"""Voltage-controlled switches with ngspice's SW model: VT, VH, RON, ROFF.

The switch is a resistor of RON (on) or ROFF (off). It turns on when the control voltage
v(nc+) - v(nc-) exceeds VT + VH and off when it falls below VT - VH; in between it keeps the
state of the last accepted time point (hysteresis). As in ngspice, the state is re-decided at
every Newton iteration against the last *accepted* state, and a change forces another
iteration. ROFF defaults to 1/gmin, RON to 1 ohm. An ``ON``/``OFF`` keyword sets the state for
the operating point (default off when the control voltage is inside the hysteresis band).
Negative VH (ngspice's smooth transition) is not modelled.

Kernel twin: switch_kernel.py, the same rules for the compiled loops (solver/compiled/), which
read the switches as ``kernel_data`` describes them (columns named there).
"""

from __future__ import annotations

import numpy as np

from circuitsim.netlist.circuit import Switch
from circuitsim.solver.context import Stamps, StepContext
from circuitsim.solver.devices.base import DeviceFamily, find_model, model_params
from circuitsim.solver.errors import CircuitInputError
from circuitsim.solver.layout import conductance_values, two_terminal_pattern

# Fraction of the remaining distance to the threshold that one step may cover, plus a floor
# (volts) so that the step does not shrink without bound right at the threshold.
APPROACH_FRACTION = 0.75
APPROACH_FLOOR = 0.05
# Locating a switch transition (transition_retry): a step that crosses a threshold well inside
# is cut to end this fraction of the way short of the crossing, the switch unchanged; a
# crossing within NEAR_START of the last accepted step from the step's start is then taken in
# a step of twice that lead, so the switch's new state acts over little more than after the
# crossing (implicit integration applies it over the whole step).
SHORT_OF_CROSSING = 1e-3
NEAR_START = 0.01


def transition_retry(fraction: float, h: float, h_last: float, min_step: float) -> float:
    """The step (s) to retry a time point with when a switch toggled at ``fraction`` (0..1)
    of the step ``h`` (s), or 0.0 to accept the step (with its transition, if fraction < 1).

    ngspice only bounds the step by how fast the control nears its threshold (SWtrunc: our
    :meth:`SwitchFamily.truncate`) and turns the switch on for the whole step that crosses;
    here the step that crosses is cut in two, before and just past the crossing.
    ``h_last``: the last accepted step (s), ``min_step``: the run's smallest step (s). Plain
    arithmetic: the compiled loops run this function compiled.
    """
    if fraction >= 1.0:
        return 0.0
    lead = fraction * h  # from the step's start to the crossing, s
    if lead > max(NEAR_START * h_last, 10.0 * min_step):
        return lead * (1.0 - SHORT_OF_CROSSING)
    past = 2.0 * max(lead, 10.0 * min_step)
    if h > past * (1.0 + 1e-9):
        return past
    return 0.0


class SwitchFamily(DeviceFamily):
    """All voltage-controlled switches."""

    element_types = (Switch,)
    discrete = True

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        models = [find_model(circuit, e.model, "SW", e.name) for e in elements]
        defaults = {
            "vt": 0.0,
            "vh": 0.0,
            "ron": 1.0,
            "roff": 1.0 / options.gmin if options.gmin > 0 else 1e12,
        }
        par = model_params(models, defaults, self.names)
        if np.any(par["ron"] <= 0) or np.any(par["roff"] <= 0):
            raise CircuitInputError("switch model: RON and ROFF must be > 0")
        negative = [name for name, vh in zip(self.names, par["vh"], strict=True) if vh < 0]
        if negative:
            # ngspice 39 reverses the hysteresis band for VH < 0 (on at VT+VH rising, off at
            # VT-VH falling: a switch that toggles at every time point inside the band); the
            # reader warns and `check` reports it, and the engine refuses rather than guess.
            raise CircuitInputError(
                f"switch {', '.join(negative)}: model VH < 0 is not supported by the builtin "
                "engine (ngspice 39 reverses the hysteresis band); give VH >= 0"
            )
        self.vh = par["vh"]
        self.on_above = par["vt"] + self.vh
        self.off_below = par["vt"] - self.vh
        self.g_on, self.g_off = 1.0 / par["ron"], 1.0 / par["roff"]
        p = layout.nodes([e.positive for e in elements])
        n = layout.nodes([e.negative for e in elements])
        self.terminals = (p, n)
        self.cp = layout.nodes([e.control_positive for e in elements])
        self.cn = layout.nodes([e.control_negative for e in elements])
        self.pattern = two_terminal_pattern(p, n)
        for e in elements:
            if e.initial not in (None, "on", "off"):
                raise CircuitInputError(f"{e.name}: initial state {e.initial!r}, expected on/off")
        self.initial = np.array([e.initial == "on" for e in elements])
        self.accepted = self.initial.copy()
        self.state = self.initial.copy()
        self.version = 0

    def control(self, x_ext: np.ndarray) -> np.ndarray:
        """Control voltages, shape (m,), volts."""
        return x_ext[self.cp] - x_ext[self.cn]

    def update_state(self, x_ext: np.ndarray, ctx: StepContext) -> None:
        if ctx.init_junction:
            new = self.accepted.copy()
        else:
            vc = self.control(x_ext)
            # Inside the band the state is kept: the accepted one at the first iteration of
            # a time point, then the one of the previous iteration (ngspice's swload).
            keep = self.accepted if ctx.first_iteration else self.state
            new = (keep | (vc > self.on_above)) & (vc >= self.off_below)
        if np.count_nonzero(new != self.state):
            self.state = new
            self.version += 1
            ctx.noncon += 1

    def state_key(self) -> object:
        return ("switch", self.version)

    def stamp_state(self, stamps: Stamps) -> None:
        stamps.add(self.pattern, conductance_values(np.where(self.state, self.g_on, self.g_off)))

    def truncate(self, x_ext: np.ndarray, x_prev_ext: np.ndarray, h_prev: float) -> float:
        vc = self.control(x_ext)
        rate = (vc - self.control(x_prev_ext)) / h_prev
        threshold = np.where(self.accepted, self.off_below, self.on_above)
        distance = threshold - vc
        approaching = (rate * distance > 0) & (distance != 0)
        if not approaching.any():
            return np.inf
        allowed = (APPROACH_FRACTION * np.abs(distance) + APPROACH_FLOOR) / np.abs(rate)
        return float(np.min(allowed[approaching]))

    def transition_fraction(self, x_ext: np.ndarray, x_prev_ext: np.ndarray) -> float:
        toggled = self.state != self.accepted
        if not toggled.any():
            return 1.0
        vc, vc_prev = self.control(x_ext)[toggled], self.control(x_prev_ext)[toggled]
        threshold = np.where(self.state[toggled], self.on_above[toggled], self.off_below[toggled])
        with np.errstate(divide="ignore", invalid="ignore"):
            fraction = (threshold - vc_prev) / (vc - vc_prev)
        fraction = np.where(np.isfinite(fraction), np.clip(fraction, 0.0, 1.0), 1.0)
        return float(fraction.min())

    def accept(self, x_ext: np.ndarray, ctx: StepContext) -> bool:
        if not np.count_nonzero(self.state != self.accepted):
            return False
        self.accepted = self.state.copy()
        return True

    def kernel_data(self) -> dict:
        from circuitsim.solver.devices import switch_kernel as twin  # numba: compiled runs only

        p, n = self.terminals
        m = p.size
        nodes = np.empty((m, twin.NODE_COLUMNS), dtype=np.int64)
        nodes[:, twin.POSITIVE] = p
        nodes[:, twin.NEGATIVE] = n
        nodes[:, twin.CONTROL_POSITIVE] = self.cp
        nodes[:, twin.CONTROL_NEGATIVE] = self.cn
        approach = np.empty((m, twin.APPROACH_COLUMNS))
        approach[:, twin.ON_ABOVE] = self.on_above
        approach[:, twin.OFF_BELOW] = self.off_below
        approach[:, twin.FRACTION] = APPROACH_FRACTION
        approach[:, twin.FLOOR] = APPROACH_FLOOR
        g = np.empty((m, 2))
        g[:, twin.G_ON] = self.g_on
        g[:, twin.G_OFF] = self.g_off
        return {
            "kind": "switches",
            "nodes": nodes,
            "approach": approach,
            "g": g,
            "accepted": self.accepted,
            "state": self.state,
        }
