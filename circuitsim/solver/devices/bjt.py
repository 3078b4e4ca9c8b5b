"""Bipolar transistors: the Gummel-Poon model as ngspice's BJT (level 1) evaluates it.

Model parameters (``.model name NPN|PNP(...)``, ngspice's defaults): IS 1e-16 A, BF 100, NF 1,
VAF inf, IKF inf, ISE 0, NE 1.5, BR 1, NR 1, VAR inf, IKR inf, ISC 0, NC 2 (A, V);
RB 0, RBM = RB, RE 0, RC 0 ohm; CJE 0, VJE 0.75, MJE 0.33, CJC 0, VJC 0.75, MJC 0.33 (F, V),
FC 0.5, TF 0, XTF 0, VTF inf, ITF 0, TR 0 (s, A). ngspice's aliases VA, IK, VB, PE, ME, PC,
MC are read too. ``area`` scales IS, ISE, ISC, IKF, IKR, ITF, CJE, CJC and the conductances
of RB, RBM, RE, RC. The substrate junction (CJS, ISS), XCJC < 1, excess phase (PTF) and IRB
are not modelled and refused; temperature and noise parameters have no effect at 27 C.

Equations (n-p-n frame; a p-n-p flips every voltage and current), with v_be, v_bc at the
inner nodes: forward and reverse diffusion currents I_f = IS (exp(v_be/(NF Vt)) - 1),
I_r = IS (exp(v_bc/(NR Vt)) - 1); base charge q_b = q1 (1 + sqrt(1 + 4 q2)) / 2 with
q1 = 1 / (1 - v_bc/VAF - v_be/VAR), q2 = I_f/IKF + I_r/IKR; collector current
(I_f - I_r)/q_b - I_r/BR - I_bcn, base current I_f/BF + I_ben + I_r/BR + I_bcn (leakage
diodes ISE/NE, ISC/NC, each with gmin). Charges: Q_be = TF I_f' + depletion(CJE) with
ngspice's XTF/VTF/ITF transit-time modulation of I_f' = I_f (1 + argtf) / q_b, and
Q_bc = TR I_r + depletion(CJC). RB with RBM != RB is ngspice's q_b-modulated base resistance,
stamped as a conductance at the present q_b. Newton steps of v_be and v_bc are limited by
pnjlim (with Vt, ngspice's BJTload).

Kernel twin: :mod:`circuitsim.solver.devices.bjt_kernel` (the same equations for one element,
for the compiled MNA kernel; :meth:`BjtFamily.kernel_data` hands over its parameters in
``bjt_kernel.PARAMS``'s order).
"""

from __future__ import annotations

import numpy as np

from circuitsim.netlist.circuit import Bjt, Model
from circuitsim.solver.context import Stamps, StepContext
from circuitsim.solver.devices.base import model_params, number
from circuitsim.solver.devices.diode import THERMAL_VOLTAGE, pnjlim
from circuitsim.solver.devices.junction import (
    depletion_charge,
    exponential_current,
    series_resistance_nodes,
    unsupported_parameters,
)
from circuitsim.solver.devices.terminals import (
    TerminalStamp,
    TransistorFamily,
    find_model_any,
)
from circuitsim.solver.layout import two_terminal_pattern

DEFAULTS = {
    "is": 1e-16,
    "bf": 100.0,
    "nf": 1.0,
    "vaf": 0.0,  # 0: infinite (ngspice's convention for VAF, IKF, VAR, IKR, VTF)
    "ikf": 0.0,
    "ise": 0.0,
    "ne": 1.5,
    "br": 1.0,
    "nr": 1.0,
    "var": 0.0,
    "ikr": 0.0,
    "isc": 0.0,
    "nc": 2.0,
    "rb": 0.0,
    "rbm": -1.0,  # not given: RB
    "re": 0.0,
    "rc": 0.0,
    "cje": 0.0,
    "vje": 0.75,
    "mje": 0.33,
    "cjc": 0.0,
    "vjc": 0.75,
    "mjc": 0.33,
    "fc": 0.5,
    "tf": 0.0,
    "xtf": 0.0,
    "vtf": 0.0,
    "itf": 0.0,
    "tr": 0.0,
}
ALIASES = {
    "va": "vaf",
    "ik": "ikf",
    "vb": "var",
    "pe": "vje",
    "me": "mje",
    "pc": "vjc",
    "mc": "mjc",
}
IGNORED = (
    "eg", "xti", "xtb", "kf", "af", "tnom", "vjs", "mjs", "ns", "level", "nkf", "subs",
    "vbe_max", "vbc_max", "vce_max", "bv_max", "tlev", "tlevc",
)  # fmt: skip
ALLOWED = {"level": (1.0,), "xcjc": (1.0,), "cjs": (0.0,), "ccs": (0.0,), "iss": (0.0,),
           "ptf": (0.0,), "irb": (0.0,)}  # fmt: skip
KINDS = ("NPN", "PNP")
# the kernel twin's parameter columns (bjt_kernel.PARAMS; that module imports numba)
KERNEL_PARAMS = ("polarity", "vt", "vcrit", "isat", "vtf", "isat_bc", "vtr", "ise", "vte",
                 "isc", "vtc", "bf", "br", "inv_vaf", "inv_var", "inv_ikf", "inv_ikr", "gmin",
                 "tf", "tr", "xtf", "inv_vtf_scaled", "itf", "cje", "vje", "mje", "cjc", "vjc",
                 "mjc", "fc", "rb_min", "rb_excess", "modulated_rb")  # fmt: skip


def _normalized(model: Model) -> Model:
    """The model with ngspice's parameter aliases under their main names."""
    params = {ALIASES.get(k.lower(), k.lower()): v for k, v in model.params.items()}
    return Model(model.name, model.kind, params)


def _inverse(value: np.ndarray) -> np.ndarray:
    """1/value where value > 0, else 0 (ngspice's 'infinite when zero' parameters)."""
    return np.where(value > 0, 1.0 / np.where(value > 0, value, 1.0), 0.0)


class BjtFamily(TransistorFamily):
    """All BJTs; RB, RC, RE > 0 add private base, collector and emitter nodes."""

    element_types = (Bjt,)

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        models = [_normalized(find_model_any(circuit, e.model, KINDS, e.name)) for e in elements]
        for model, element in zip(models, elements, strict=True):
            unsupported_parameters(model, element.name, DEFAULTS, IGNORED, ALLOWED)
        par = model_params(models, DEFAULTS, self.names)
        area = np.array([number(e.area, e.name, "area") for e in elements])
        self.polarity = np.array([1.0 if m.kind.upper() == "NPN" else -1.0 for m in models])
        vt = self.vt = THERMAL_VOLTAGE
        self.isat = par["is"] * area
        # ngspice 39 scales the base-collector diffusion current by the area twice (IS * area
        # * AREAB, its base area defaulting to area): measured against it, the same answer
        # as area = 1 only when area is 1 (tests/solver/golden_vendor/bjt.cir has area 2)
        self.isat_bc = self.isat * area
        self.vcrit = vt * np.log(vt / (np.sqrt(2) * self.isat))
        self.vtf, self.vtr = par["nf"] * vt, par["nr"] * vt
        self.ise, self.vte = par["ise"] * area, par["ne"] * vt
        self.isc, self.vtc = par["isc"] * area, par["nc"] * vt
        self.bf, self.br = par["bf"], par["br"]
        self.inv_vaf, self.inv_var = _inverse(par["vaf"]), _inverse(par["var"])
        self.inv_ikf = _inverse(par["ikf"] * area)
        self.inv_ikr = _inverse(par["ikr"] * area)
        self.gmin = options.gmin
        self.tf, self.tr, self.xtf = par["tf"], par["tr"], par["xtf"]
        self.inv_vtf_scaled = _inverse(par["vtf"] * 1.44)
        self.itf = par["itf"] * area
        fc = np.minimum(par["fc"], 0.9999)
        self.cje, self.vje, self.mje = par["cje"] * area, par["vje"], par["mje"]
        self.cjc, self.vjc, self.mjc = par["cjc"] * area, par["vjc"], par["mjc"]
        self.fc = fc
        self.has_charge = bool(
            np.any(self.cje > 0) | np.any(self.cjc > 0) | np.any(self.tf > 0) | np.any(self.tr > 0)
        )
        names = self.names
        collector = layout.nodes([e.collector for e in elements])
        base = layout.nodes([e.base for e in elements])
        emitter = layout.nodes([e.emitter for e in elements])
        self.collector_res = series_resistance_nodes(
            layout, names, collector, par["rc"] / area, "collector"
        )
        self.emitter_res = series_resistance_nodes(
            layout, names, emitter, par["re"] / area, "emitter"
        )
        rb = par["rb"] / area
        rbm = np.where(par["rbm"] >= 0, par["rbm"], par["rb"]) / area
        self.base_res = series_resistance_nodes(layout, names, base, rb, "base")
        # RBM != RB: the base resistance rbm + (rb - rbm)/q_b changes with q_b (ngspice's gx)
        self.rb_min, self.rb_excess = rbm, rb - rbm
        self.modulated_rb = np.flatnonzero((rb > 0) & (self.rb_excess != 0))
        i = self.modulated_rb
        self.rb_pattern = two_terminal_pattern(base[i], self.base_res.inner[i])
        self.c, self.b, self.e = (
            self.collector_res.inner,
            self.base_res.inner,
            self.emitter_res.inner,
        )
        # terminals: collector', base', emitter'; controls: v_be, v_bc
        self.terminal = TerminalStamp(
            np.stack([self.c, self.b, self.e]), [(self.b, self.e), (self.b, self.c)]
        )
        self.slots = layout.add_charges(2 * len(elements)) if self.has_charge else None
        m = len(elements)
        self.v = np.zeros((2, m))  # (v_be, v_bc) of the last load, n-p-n frame
        self.lin = None

    def stamp_linear(self, stamps: Stamps) -> None:
        self.collector_res.stamp(stamps)
        self.emitter_res.stamp(stamps)
        fixed = self.base_res
        if self.modulated_rb.size:
            keep = np.setdiff1d(fixed.index, self.modulated_rb)
            g = 1.0 / (self.rb_min[keep] + self.rb_excess[keep])
            stamps.add(
                two_terminal_pattern(fixed.outer[keep], fixed.inner[keep]),
                np.stack([g, -g, -g, g]),
            )
        else:
            fixed.stamp(stamps)

    def _limited(self, v: np.ndarray, ctx: StepContext) -> np.ndarray:
        if ctx.init_junction:  # BJTload's MODEINITJCT start
            return np.stack([self.vcrit, np.zeros_like(self.vcrit)])
        # against the last evaluation, also on a new step's first iteration and after
        # a failed attempt (ngspice's state0): a retry goes on where the failed
        # attempt's limiting had got to instead of climbing the same ladder again
        old = self.v
        vbe, hit_be = pnjlim(v[0], old[0], self.vt, self.vcrit)
        vbc, hit_bc = pnjlim(v[1], old[1], self.vt, self.vcrit)
        ctx.noncon += hit_be or hit_bc
        return np.stack([vbe, vbc])

    def load(self, x_ext: np.ndarray, ctx: StepContext, stamps: Stamps, rhs: np.ndarray) -> None:
        pol = self.polarity
        v = self._limited(pol * self.terminal.voltages(x_ext), ctx)
        vbe, vbc = v
        gmin = self.gmin
        cbe, gbe = exponential_current(vbe, self.isat, self.vtf)
        cben, gben = exponential_current(vbe, self.ise, self.vte)
        cben, gben = cben + gmin * vbe, gben + gmin
        cbc, gbc = exponential_current(vbc, self.isat_bc, self.vtr)
        cbcn, gbcn = exponential_current(vbc, self.isc, self.vtc)
        cbcn, gbcn = cbcn + gmin * vbc, gbcn + gmin
        qb, dqbdve, dqbdvc = self._base_charge(vbe, vbc, cbe, gbe, cbc, gbc)
        cc = (cbe - cbc) / qb - cbc / self.br - cbcn
        cb = cbe / self.bf + cben + cbc / self.br + cbcn
        go = (gbc + (cbe - cbc) * dqbdvc / qb) / qb
        gm = (gbe - (cbe - cbc) * dqbdve / qb) / qb - go
        gpi = gbe / self.bf + gben
        gmu = gbc / self.br + gbcn
        # currents into collector', base' and slopes in (v_be, v_bc)
        ic, dic = cc, [gm + go, -go - gmu]
        ib, dib = cb, [gpi, gmu]
        if self.has_charge:
            m = len(self.elements)
            qbe, capbe, dqbe_dvbc, qbc, capbc = self._charges(
                vbe, vbc, cbe, gbe, cbc, gbc, qb, dqbdve, dqbdvc
            )
            icap, gcap = ctx.integrate(
                self.slots, np.concatenate([qbe, qbc]), np.concatenate([capbe, capbc])
            )
            ib = ib + icap[:m] + icap[m:]
            dib = [dib[0] + gcap[:m], dib[1] + ctx.a0 * dqbe_dvbc + gcap[m:]]
            ic = ic - icap[m:]
            dic = [dic[0], dic[1] - gcap[m:]]
        # the charges sit between base' and emitter' / collector': the emitter' current is
        # minus the other two, with charges or without
        dic = np.stack(np.broadcast_arrays(*dic))
        dib = np.stack(np.broadcast_arrays(*dib))
        current = np.stack([ic, ib, -(ic + ib)])
        slope = np.stack([dic, dib, -(dic + dib)])
        self.v = v
        self.lin = (pol * current, slope, pol * v)
        self.terminal.add(stamps, rhs, *self.lin)
        if self.modulated_rb.size:
            i = self.modulated_rb
            g = 1.0 / (self.rb_min[i] + self.rb_excess[i] / qb[i])
            stamps.add(self.rb_pattern, np.stack([g, -g, -g, g]))

    def kernel_data(self) -> dict:
        m = len(self.elements)
        modulated = np.zeros(m, dtype=bool)
        modulated[self.modulated_rb] = True
        columns = {name: getattr(self, name, None) for name in KERNEL_PARAMS}
        columns.update(modulated_rb=modulated.astype(float), gmin=self.gmin, vt=self.vt)
        data = self.terminal_data(
            "bjt", [np.broadcast_to(columns[name], m) for name in KERNEL_PARAMS]
        )
        # the outer base node of a modulated RB: a fourth row (its conductance's entries)
        rows = np.concatenate([data["rows"], self.base_res.outer[:, None]], axis=1)
        rb_g = np.zeros(m)
        rb_g[modulated] = 1.0 / (self.rb_min[modulated] + self.rb_excess[modulated])
        return data | {"rows": rows, "rb": modulated, "rb_g": rb_g}

    def _base_charge(self, vbe, vbc, cbe, gbe, cbc, gbc):
        """Normalized base charge q_b and its slopes in v_be, v_bc (1/V)."""
        q1 = 1.0 / (1.0 - self.inv_vaf * vbc - self.inv_var * vbe)
        q2 = self.inv_ikf * cbe + self.inv_ikr * cbc
        arg = np.maximum(0.0, 1 + 4 * q2)
        sqarg = np.where(arg != 0, np.sqrt(arg), 1.0)
        qb = q1 * (1 + sqarg) / 2
        dqbdve = q1 * (qb * self.inv_var + self.inv_ikf * gbe / sqarg)
        dqbdvc = q1 * (qb * self.inv_vaf + self.inv_ikr * gbc / sqarg)
        return qb, dqbdve, dqbdvc

    def _charges(self, vbe, vbc, cbe, gbe, cbc, gbc, qb, dqbdve, dqbdvc):
        """Q_be (C), dQ_be/dv_be (F), dQ_be/dv_bc (F), Q_bc (C), dQ_bc/dv_bc (F)."""
        argtf = self.xtf * np.exp(np.minimum(vbc * self.inv_vtf_scaled, 700.0))
        arg2 = argtf
        with_itf = self.itf > 0
        temp = cbe / np.where(with_itf, cbe + self.itf, 1.0)
        argtf = np.where(with_itf, argtf * temp * temp, argtf)
        arg2 = np.where(with_itf, argtf * (3 - 2 * temp), arg2)
        arg3 = cbe * argtf * self.inv_vtf_scaled
        modulated = (self.tf > 0) & (vbe > 0)
        cbe_t = np.where(modulated, cbe * (1 + argtf) / qb, cbe)
        gbe_t = np.where(modulated, (gbe * (1 + arg2) - cbe_t * dqbdve) / qb, gbe)
        dqbe_dvbc = np.where(modulated, self.tf * (arg3 - cbe_t * dqbdvc) / qb, 0.0)
        qdep, cdep = depletion_charge(vbe, self.cje, self.vje, self.mje, self.fc)
        qbe = self.tf * cbe_t + qdep
        capbe = self.tf * gbe_t + cdep
        qdep, cdep = depletion_charge(vbc, self.cjc, self.vjc, self.mjc, self.fc)
        return qbe, capbe, dqbe_dvbc, self.tr * cbc + qdep, self.tr * gbc + cdep
