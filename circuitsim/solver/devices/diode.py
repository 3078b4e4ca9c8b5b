"""Junction diodes (SPICE level 1): Shockley current, depletion and diffusion charge.

Model parameters: IS, N, RS, CJO (alias CJ0), VJ, M, FC, TT; ``area`` scales IS, CJO and 1/RS.
BV (reverse breakdown) is not modelled. Every junction has gmin in parallel. Newton steps of
the junction voltage are limited with SPICE's ``pnjlim`` so Newton converges from any start;
a limited iterate is never declared converged. The nominal temperature is 27 C.

Kernel twin: diode_kernel.py, the same equations for one junction, compiled (numba) and
inlined by the compiled loops (solver/compiled/); ``kernel_data`` hands them the parameters.
"""

from __future__ import annotations

import numpy as np

from circuitsim.netlist.circuit import Diode
from circuitsim.solver.context import Stamps, StepContext
from circuitsim.solver.devices.base import DeviceFamily, find_model, model_params, number
from circuitsim.solver.layout import (
    VectorPattern,
    conductance_values,
    two_terminal_pattern,
)

BOLTZMANN = 1.38064852e-23  # J/K, the constants ngspice uses
CHARGE = 1.6021766208e-19  # C
TEMPERATURE = 300.15  # K (27 C)
THERMAL_VOLTAGE = BOLTZMANN * TEMPERATURE / CHARGE

CURRENT_SIGNS = np.array([[-1.0], [1.0]])  # rhs of anode, cathode

DEFAULTS = {
    "is": 1e-14,
    "n": 1.0,
    "rs": 0.0,
    "cjo": 0.0,
    "cj0": 0.0,
    "vj": 1.0,
    "m": 0.5,
    "fc": 0.5,
    "tt": 0.0,
}


def pnjlim(vnew: np.ndarray, vold: np.ndarray, vt: np.ndarray, vcrit: np.ndarray):
    """SPICE's junction-voltage limiting (DEVpnjlim), vectorized.

    Forward: a step beyond vcrit larger than 2 vt is compressed logarithmically. Reverse: a
    step below -vold - 1 (from a forward-biased start) or 2 vold - 1 is cut there.

    Returns
    -------
    v : ndarray
        The limited junction voltages, volts.
    limited : bool
        Whether any voltage was limited.
    """
    big = (vnew > vcrit) & (np.abs(vnew - vold) > 2 * vt)
    floor = np.where(vold > 0, -vold - 1, 2 * vold - 1)
    reverse = vnew < floor  # floor < 0, so this is SPICE's "vnew < 0 and below the floor"
    if not big.any():
        if not reverse.any():
            return vnew, False
        return np.maximum(vnew, floor), True
    # arguments kept positive so the logarithms are defined where they are not used
    arg = 1 + (vnew - vold) / vt
    from_positive = np.where(arg > 0, vold + vt * np.log(np.maximum(arg, 1e-300)), vcrit)
    from_negative = vt * np.log(np.maximum(vnew, vt) / vt)
    forward = np.where(vold > 0, from_positive, from_negative)
    v = np.where(big, forward, np.where(reverse, floor, vnew))
    return v, True


class DiodeFamily(DeviceFamily):
    """All diodes; RS > 0 adds a private node between RS and the junction."""

    element_types = (Diode,)
    nonlinear = True

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        models = [find_model(circuit, e.model, "D", e.name) for e in elements]
        par = model_params(models, DEFAULTS, self.names)
        area = np.array([number(e.area, e.name, "area") for e in elements])
        self.isat = par["is"] * area
        self.vte = par["n"] * THERMAL_VOLTAGE
        self.vcrit = self.vte * np.log(self.vte / (np.sqrt(2) * self.isat))
        self.cjo = np.where(par["cjo"] > 0, par["cjo"], par["cj0"]) * area
        self.vj, self.fc, self.tt = par["vj"], par["fc"], par["tt"]
        self.m = np.minimum(par["m"], 0.9999)  # M = 1 would divide by zero in the charge
        self.gmin = options.gmin
        anode = layout.nodes([e.anode for e in elements])
        self.cathode = layout.nodes([e.cathode for e in elements])
        rs = par["rs"] / area
        self.junction = anode.copy()
        series = np.flatnonzero(rs > 0)
        for i in series:
            self.junction[i] = layout.add_internal_node(f"{elements[i].name}#internal")
        self.series = series
        self.series_g = 1.0 / rs[series] if series.size else np.zeros(0)
        self.series_pattern = two_terminal_pattern(anode[series], self.junction[series])
        self.pattern = two_terminal_pattern(self.junction, self.cathode)
        self.rows = VectorPattern(np.stack([self.junction, self.cathode]))
        self.port_nodes = (self.junction, self.cathode)
        self.free_step = np.minimum(2 * self.vte, 1.0)
        self.bypass = bool(options.bypass)
        self.has_charge = bool(np.any(self.cjo > 0) or np.any(self.tt > 0))
        self.has_transit = bool(np.any(self.tt > 0))
        self.inv_vte = 1.0 / self.vte
        self.is_over_vte = self.isat / self.vte
        self.reverse_knee = -3 * self.vte
        self.cubic_scale = 3 * self.vte / np.e
        m, vj, fc, cjo = self.m, self.vj, self.fc, self.cjo
        self.knee = fc * vj
        f2, f3 = (1 - fc) ** (1 + m), 1 - fc * (1 + m)
        self.q_scale = vj * cjo / (1 - m)
        self.ext_linear = cjo / f2 * f3
        self.ext_quadratic = cjo / f2 * m / (2 * vj)
        self.ext_slope = cjo / f2 * m / vj
        self.ext_offset = self.ext_linear + self.ext_quadratic * self.knee
        self.inv_vj = 1.0 / vj
        self.neg_m = -m
        self.three_vte = 3 * self.vte
        self.slots = layout.add_charges(len(elements)) if self.has_charge else None
        m = len(elements)
        self.vd = np.zeros(m)  # linearization point of the last load
        self.cd = np.zeros(m)  # total junction current there, A
        self.gd = np.zeros(m)  # its conductance, S
        self.ieq = np.zeros(m)  # cd - gd vd, A
        self.vd_accepted = np.zeros(m)

    def stamp_linear(self, stamps: Stamps) -> None:
        if self.series.size:
            stamps.add(self.series_pattern, conductance_values(self.series_g))

    def _junction_voltage(self, x_ext: np.ndarray) -> np.ndarray:
        return x_ext[self.junction] - x_ext[self.cathode]

    def port_load(self, v: np.ndarray, ctx: StepContext) -> tuple[np.ndarray, np.ndarray]:
        if ctx.init_junction:
            vd = self.vcrit.copy()
        elif not ctx.first_iteration and self.bypass and self._unchanged(v):
            return self.gd, self.ieq
        else:
            vold = self.vd_accepted if ctx.first_iteration else self.vd
            # Steps within min(2 vt, 1 V) are never limited (pnjlim's forward rule needs a step
            # above 2 vt, its reverse rule one below -1 V): one test instead of pnjlim's dozen.
            if not np.count_nonzero(np.abs(v - vold) > self.free_step):
                vd = v
            else:
                vd, limited = pnjlim(v, vold, self.vte, self.vcrit)
                ctx.noncon += limited
        cd, gd = self._current(vd)
        if self.has_charge:
            q, c = self._charge(vd, cd, gd)
            icap, gcap = ctx.integrate(self.slots, q, c)
            cd = cd + icap
            gd = gd + gcap
        self.vd, self.cd, self.gd = vd, cd, gd
        self.ieq = cd - gd * vd
        return gd, self.ieq

    def _unchanged(self, v: np.ndarray) -> bool:
        """ngspice's bypass test: v and the linearized current at v within tolerance of the
        last evaluation (then that evaluation is kept, as dioload does)."""
        reltol = self.options.reltol
        dv = v - self.vd
        if np.count_nonzero(
            np.abs(dv) > reltol * np.maximum(np.abs(v), np.abs(self.vd)) + self.options.vntol
        ):
            return False
        delta = self.gd * dv
        tol = reltol * np.maximum(np.abs(self.cd + delta), np.abs(self.cd)) + self.options.abstol
        return not np.count_nonzero(np.abs(delta) > tol)

    def load(self, x_ext: np.ndarray, ctx: StepContext, stamps: Stamps, rhs: np.ndarray) -> None:
        gd, ieq = self.port_load(self._junction_voltage(x_ext), ctx)
        stamps.add_conductances(self.pattern, self.junction, self.cathode, gd)
        self.rows.add(rhs, CURRENT_SIGNS * ieq)

    def _current(self, vd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Static current (A) and conductance (S) with gmin, as SPICE's dioload.

        Below -3 N Vt SPICE replaces the exponential by a cubic that tends to -IS.
        """
        ex = np.exp(np.minimum(vd * self.inv_vte, 700.0))
        reverse = vd < self.reverse_knee
        if not np.count_nonzero(reverse):
            return self.isat * (ex - 1) + self.gmin * vd, self.is_over_vte * ex + self.gmin
        vr = np.minimum(vd, self.reverse_knee)  # negative everywhere, so 1/vr is defined
        arg = (self.cubic_scale / vr) ** 3
        # both branches as IS (e - 1) and IS/(N Vt) f: the cubic is e = -arg, f = 3 N Vt arg / vr
        cd = self.isat * (np.where(reverse, -arg, ex) - 1.0) + self.gmin * vd
        gd = self.is_over_vte * np.where(reverse, self.three_vte * arg / vr, ex) + self.gmin
        return cd, gd

    def _charge(self, vd, cd, gd) -> tuple[np.ndarray, np.ndarray]:
        """Depletion plus diffusion charge (C) and capacitance (F).

        Below FC*VJ the depletion charge is SPICE's power law; above it, its linear-quadratic
        continuation, written here as the power law at the knee plus the extension.
        """
        arg = 1 - np.minimum(vd, self.knee) * self.inv_vj
        sarg = arg**self.neg_m
        excess = np.maximum(vd - self.knee, 0.0)
        q = self.q_scale * (1 - arg * sarg) + excess * (self.ext_offset + self.ext_quadratic * vd)
        c = self.cjo * sarg + self.ext_slope * excess
        if self.has_transit:
            q = q + self.tt * cd
            c = c + self.tt * gd
        return q, c

    def converged(self, x_ext: np.ndarray, ctx: StepContext) -> bool:
        return self.port_converged(self._junction_voltage(x_ext), ctx)

    def port_converged(self, v: np.ndarray, ctx: StepContext) -> bool:
        delta = self.gd * (v - self.vd)  # cdhat - cd
        tol = self.options.reltol * np.maximum(np.abs(self.cd + delta), np.abs(self.cd))
        return not np.count_nonzero(np.abs(delta) > tol + self.options.abstol)

    def accept(self, x_ext: np.ndarray, ctx: StepContext) -> bool:
        self.vd_accepted = self._junction_voltage(x_ext)
        return False

    def kernel_data(self) -> dict:
        """The junctions as the compiled loops read them: parameter matrices whose columns are
        named in the kernel twin, diode_kernel.py, whose linearize_junction evaluates them."""
        if self.options.bypass:
            return None  # the kernel evaluates every junction at every iteration
        from circuitsim.solver.devices import diode_kernel as twin  # numba: compiled runs only

        m = self.isat.size
        params = np.empty((m, twin.JUNCTION_COLUMNS))
        params[:, twin.ISAT] = self.isat
        params[:, twin.VTE] = self.vte
        params[:, twin.INV_VTE] = self.inv_vte
        params[:, twin.IS_OVER_VTE] = self.is_over_vte
        params[:, twin.REVERSE_KNEE] = self.reverse_knee
        params[:, twin.CUBIC_SCALE] = self.cubic_scale
        params[:, twin.THREE_VTE] = self.three_vte
        params[:, twin.GMIN] = self.gmin
        params[:, twin.VCRIT] = self.vcrit
        params[:, twin.FREE_STEP] = self.free_step
        charge = np.empty((m, twin.CHARGE_COLUMNS))
        charge[:, twin.KNEE] = self.knee
        charge[:, twin.INV_VJ] = self.inv_vj
        charge[:, twin.NEG_M] = self.neg_m
        charge[:, twin.Q_SCALE] = self.q_scale
        charge[:, twin.EXT_OFFSET] = self.ext_offset
        charge[:, twin.EXT_QUADRATIC] = self.ext_quadratic
        charge[:, twin.EXT_SLOPE] = self.ext_slope
        charge[:, twin.CJO] = self.cjo
        charge[:, twin.TT] = self.tt
        return {
            "kind": "junctions",
            "p": self.junction,
            "n": self.cathode,
            "params": params,
            "charge": charge if self.has_charge else None,
            "slots": self.slots,
            "vd_accepted": self.vd_accepted,
            "state": (self.vd, self.cd, self.gd),
        }
