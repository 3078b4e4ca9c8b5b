"""Junction FETs (SPICE level 1, Shichman-Hodges, as ngspice's JFET with its B parameter).

Model parameters (``.model name NJF|PJF(...)``, ngspice's defaults): VTO -2 V, BETA 1e-4
A/V^2, LAMBDA 0 1/V, RD 0, RS 0 ohm, CGS 0, CGD 0 F, PB 1 V, IS 1e-14 A, FC 0.5, B 1 (the
Sydney University doping-tail parameter; B = 1 is the square law). ``area`` scales BETA, IS,
CGS, CGD and 1/RD, 1/RS. The nominal temperature is 27 C, where ngspice's temperature
adjustments are the identity.

Equations, in the n-channel frame (a p-channel device flips every voltage and current):
gate-source and gate-drain junctions are diodes IS (exp(v / Vt) - 1) (a cubic below -3 Vt, as
SPICE), each with gmin in parallel; the drain current, for v_ds >= 0 and v_gst = v_gs - VTO
> 0, is BETA (1 + LAMBDA v_ds) v_ds (2 v_gst - v_ds) below saturation (v_ds < v_gst) and
BETA (1 + LAMBDA v_ds) v_gst^2 above (B = 1), mirrored for v_ds < 0. Junction charges are the
depletion charges of CGS, CGD (grading 1/2, linear above FC PB). Newton steps are limited as
ngspice's JFETload: pnjlim on both junction voltages, then fetlim against VTO.

Kernel twin: :mod:`circuitsim.solver.devices.jfet_kernel` (the same equations for one
element, for the compiled MNA kernel; :meth:`JfetFamily.kernel_data` hands over its
parameters in ``jfet_kernel.PARAMS``'s order).
"""

from __future__ import annotations

import numpy as np

from circuitsim.netlist.circuit import Jfet
from circuitsim.solver.context import Stamps, StepContext
from circuitsim.solver.devices.base import model_params, number
from circuitsim.solver.devices.diode import THERMAL_VOLTAGE, pnjlim
from circuitsim.solver.devices.junction import (
    depletion_charge,
    fetlim,
    junction_current,
    series_resistance_nodes,
    unsupported_parameters,
)
from circuitsim.solver.devices.terminals import (
    TerminalStamp,
    TransistorFamily,
    find_model_any,
)

DEFAULTS = {
    "vto": -2.0,
    "beta": 1e-4,
    "lambda": 0.0,
    "rd": 0.0,
    "rs": 0.0,
    "cgs": 0.0,
    "cgd": 0.0,
    "pb": 1.0,
    "is": 1e-14,
    "fc": 0.5,
    "b": 1.0,
}
# parameters with no effect at the nominal temperature in a transient (noise, temperature
# coefficients) or naming the model level: accepted and ignored
IGNORED = ("kf", "af", "tnom", "tcv", "bex", "xti", "nlev", "gdsnoi", "level", "vtotc", "betatce")
KINDS = ("NJF", "PJF")
# the kernel twin's parameter columns (jfet_kernel.PARAMS; that module imports numba)
KERNEL_PARAMS = ("polarity", "isat", "vt", "vcrit", "gmin", "vto", "beta", "lambda", "b",
                 "b_factor", "cgs", "cgd", "pb", "fc")  # fmt: skip


class JfetFamily(TransistorFamily):
    """All JFETs; RD, RS > 0 add private drain and source nodes."""

    element_types = (Jfet,)

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        models = [find_model_any(circuit, e.model, KINDS, e.name) for e in elements]
        for model, element in zip(models, elements, strict=True):
            unsupported_parameters(model, element.name, DEFAULTS, IGNORED, {"level": (1.0,)})
        par = model_params(models, DEFAULTS, self.names)
        area = np.array([number(e.area, e.name, "area") for e in elements])
        self.polarity = np.array([1.0 if m.kind.upper() == "NJF" else -1.0 for m in models])
        self.vto, self.lam = par["vto"], par["lambda"]
        self.beta = par["beta"] * area
        self.isat = par["is"] * area
        self.b = par["b"]
        self.b_factor = (1 - par["b"]) / (par["pb"] - par["vto"])
        self.vt = THERMAL_VOLTAGE
        self.vcrit = self.vt * np.log(self.vt / (np.sqrt(2) * self.isat))
        self.gmin = options.gmin
        fc = np.minimum(par["fc"], 0.95)  # ngspice limits FC to 0.95
        self.cgs, self.cgd = par["cgs"] * area, par["cgd"] * area
        self.pb, self.fc = par["pb"], fc
        self.has_charge = bool(np.any(self.cgs > 0) or np.any(self.cgd > 0))
        drain = layout.nodes([e.drain for e in elements])
        self.gate = layout.nodes([e.gate for e in elements])
        source = layout.nodes([e.source for e in elements])
        names = [e.name for e in elements]
        self.drain_res = series_resistance_nodes(layout, names, drain, par["rd"] / area, "drain")
        self.source_res = series_resistance_nodes(layout, names, source, par["rs"] / area, "source")
        self.drain = self.drain_res.inner
        self.source = self.source_res.inner
        # terminals: drain', gate, source'; controls: v_gs, v_gd
        self.terminal = TerminalStamp(
            np.stack([self.drain, self.gate, self.source]),
            [(self.gate, self.source), (self.gate, self.drain)],
        )
        self.slots = layout.add_charges(2 * len(elements)) if self.has_charge else None
        m = len(elements)
        self.v = np.zeros((2, m))  # (v_gs, v_gd) of the last load, n-channel frame
        self.lin = None  # (currents, conductances, voltages) in the circuit's frame

    def stamp_linear(self, stamps: Stamps) -> None:
        self.drain_res.stamp(stamps)
        self.source_res.stamp(stamps)

    def _limited(self, v: np.ndarray, ctx: StepContext) -> np.ndarray:
        """ngspice's JFET limiting of (v_gs, v_gd), n-channel frame."""
        if ctx.init_junction:
            return np.full_like(v, -1.0)  # JFETload's MODEINITJCT start
        # against the last evaluation, also on a new step's first iteration and after
        # a failed attempt (ngspice's state0): a retry goes on where the failed
        # attempt's limiting had got to instead of climbing the same ladder again
        old = self.v
        out = np.empty_like(v)
        limited = False
        for k in range(2):
            out[k], hit = pnjlim(v[k], old[k], self.vt, self.vcrit)
            limited |= hit
            out[k] = fetlim(out[k], old[k], self.vto)
        ctx.noncon += limited
        return out

    def load(self, x_ext: np.ndarray, ctx: StepContext, stamps: Stamps, rhs: np.ndarray) -> None:
        pol = self.polarity
        v = self._limited(pol * self.terminal.voltages(x_ext), ctx)
        vgs, vgd = v
        cgs, ggs = junction_current(vgs, self.isat, self.vt, self.gmin)
        cgd, ggd = junction_current(vgd, self.isat, self.vt, self.gmin)
        cdrain, di_dvgs, di_dvgd = self._drain_current(vgs, vgd)
        if self.has_charge:
            qgs, capgs = depletion_charge(vgs, self.cgs, self.pb, 0.5, self.fc)
            qgd, capgd = depletion_charge(vgd, self.cgd, self.pb, 0.5, self.fc)
            m = len(self.elements)
            icap, gcap = ctx.integrate(
                self.slots, np.concatenate([qgs, qgd]), np.concatenate([capgs, capgd])
            )
            cgs, ggs = cgs + icap[:m], ggs + gcap[:m]
            cgd, ggd = cgd + icap[m:], ggd + gcap[m:]
        # currents into drain', gate, source' and their slopes in (v_gs, v_gd)
        current = np.stack([cdrain - cgd, cgs + cgd, -cdrain - cgs])
        slope = np.stack(
            [
                np.stack([di_dvgs, di_dvgd - ggd]),
                np.stack([ggs, ggd]),
                np.stack([-di_dvgs - ggs, -di_dvgd]),
            ]
        )
        self.v = v
        # back to the circuit's frame: voltages and currents flip, slopes do not
        self.lin = (pol * current, slope, pol * v)
        self.terminal.add(stamps, rhs, *self.lin)

    def kernel_data(self) -> dict:
        m = len(self.elements)
        columns = {
            "polarity": self.polarity, "isat": self.isat, "vt": self.vt, "vcrit": self.vcrit,
            "gmin": self.gmin, "vto": self.vto, "beta": self.beta, "lambda": self.lam,
            "b": self.b, "b_factor": self.b_factor, "cgs": self.cgs, "cgd": self.cgd,
            "pb": self.pb, "fc": self.fc,
        }  # fmt: skip
        return self.terminal_data(
            "jfet", [np.broadcast_to(columns[name], m) for name in KERNEL_PARAMS]
        )

    def _drain_current(self, vgs, vgd):
        """Drain current (A, drain' to source') and its slopes in v_gs and v_gd (S),
        ngspice's level-1 equations with B."""
        vds = vgs - vgd
        normal = vds >= 0
        # the inverse mode is the normal one with drain and source exchanged
        vgst = np.where(normal, vgs, vgd) - self.vto
        u = np.abs(vds)
        b, bf = self.b, self.b_factor
        on = vgst > 0
        betap = self.beta * (1 + self.lam * u)
        linear = vgst >= u
        apart = 2 * b + 3 * bf * (vgst - u)
        cpart = np.where(
            linear, u * (u * (bf * u - b) + vgst * apart), vgst * vgst * (b + bf * vgst)
        )
        f = np.where(on, betap * cpart, 0.0)
        # partial derivatives of f(vgst, u)
        f_vgst = np.where(
            linear, betap * u * (apart + 3 * bf * vgst), betap * vgst * (2 * b + 3 * bf * vgst)
        )
        f_u = np.where(linear, betap * (vgst - u) * apart, 0.0) + self.beta * self.lam * cpart
        f_vgst = np.where(on, f_vgst, 0.0)
        f_u = np.where(on, f_u, 0.0)
        # normal: i = f(vgs - vto, vgs - vgd); inverse: i = -f(vgd - vto, vgd - vgs)
        i = np.where(normal, f, -f)
        di_dvgs = np.where(normal, f_vgst + f_u, f_u)
        di_dvgd = np.where(normal, -f_u, -(f_vgst + f_u))
        return i, di_dvgs, di_dvgd
