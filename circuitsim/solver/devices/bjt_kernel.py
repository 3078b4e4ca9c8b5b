"""Kernel twin of bjt.py: one Gummel-Poon BJT linearized at the iterate, for the compiled
MNA kernel.

The equations of :class:`~circuitsim.solver.devices.bjt.BjtFamily` (``_limited``, ``load``,
``_base_charge``, ``_charges``) for one element: pnjlim on v_be and v_bc against the last
evaluation, the diffusion and leakage currents, the base charge q_b, the Q_be (TF with
XTF/VTF/ITF, CJE) and Q_bc (TR, CJC) charges integrated through the kernel's charge slots, and
the q_b-modulated base resistance (RBM != RB) as a conductance at the present q_b.
:func:`load` writes the element's terminal currents and slopes into the terminal state
(compiled/terminal_plan.py) in the circuit's frame, as the family's ``lin``.
"""

from __future__ import annotations

import math

from circuitsim.solver.devices.diode_kernel import pnjlim
from circuitsim.solver.devices.junction_kernel import depletion_charge, junction_current
from circuitsim.solver.jit import njit

# columns of the terminal plan's ``par`` for a BJT (BjtFamily.kernel_data's order)
PARAMS = ("polarity", "vt", "vcrit", "isat", "vtf", "isat_bc", "vtr", "ise", "vte", "isc",
          "vtc", "bf", "br", "inv_vaf", "inv_var", "inv_ikf", "inv_ikr", "gmin", "tf", "tr",
          "xtf", "inv_vtf_scaled", "itf", "cje", "vje", "mje", "cjc", "vjc", "mjc", "fc",
          "rb_min", "rb_excess", "modulated_rb")  # fmt: skip
(POLARITY, VT, VCRIT, ISAT, VTF, ISAT_BC, VTR, ISE, VTE, ISC, VTC, BF, BR, INV_VAF, INV_VAR,
 INV_IKF, INV_IKR, GMIN, TF, TR, XTF, INV_VTF_SCALED, ITF, CJE, VJE, MJE, CJC, VJC, MJC, FC,
 RB_MIN, RB_EXCESS, MODULATED_RB) = range(33)  # fmt: skip
# terminals: collector', base', emitter' (and the outer base of a modulated RB, rows only);
# controls: v_be, v_bc
COLLECTOR, BASE, EMITTER = 0, 1, 2


@njit(cache=True)
def base_charge(vbe, vbc, cbe, gbe, cbc, gbc, inv_vaf, inv_var, inv_ikf, inv_ikr):
    """BjtFamily._base_charge of one element: q_b and its slopes in v_be, v_bc (1/V)."""
    q1 = 1.0 / (1.0 - inv_vaf * vbc - inv_var * vbe)
    q2 = inv_ikf * cbe + inv_ikr * cbc
    arg = max(0.0, 1 + 4 * q2)
    sqarg = math.sqrt(arg) if arg != 0 else 1.0
    qb = q1 * (1 + sqarg) / 2
    dqbdve = q1 * (qb * inv_var + inv_ikf * gbe / sqarg)
    dqbdvc = q1 * (qb * inv_vaf + inv_ikr * gbc / sqarg)
    return qb, dqbdve, dqbdvc


@njit(cache=True, inline="always")
def charges(par, k, vbe, vbc, cbe, gbe, cbc, gbc, qb, dqbdve, dqbdvc):
    """BjtFamily._charges of element k: Q_be (C), dQ_be/dv_be (F), dQ_be/dv_bc (F), Q_bc (C),
    dQ_bc/dv_bc (F)."""
    tf, itf, inv_vtf = par[k, TF], par[k, ITF], par[k, INV_VTF_SCALED]
    argtf = par[k, XTF] * math.exp(min(vbc * inv_vtf, 700.0))
    arg2 = argtf
    if itf > 0:
        temp = cbe / (cbe + itf)
        argtf = argtf * temp * temp
        arg2 = argtf * (3 - 2 * temp)
    arg3 = cbe * argtf * inv_vtf
    cbe_t, gbe_t, dqbe_dvbc = cbe, gbe, 0.0
    if tf > 0 and vbe > 0:  # transit-time modulation
        cbe_t = cbe * (1 + argtf) / qb
        gbe_t = (gbe * (1 + arg2) - cbe_t * dqbdve) / qb
        dqbe_dvbc = tf * (arg3 - cbe_t * dqbdvc) / qb
    fc = par[k, FC]
    qdep, cdep = depletion_charge(vbe, par[k, CJE], par[k, VJE], par[k, MJE], fc)
    qbe, capbe = tf * cbe_t + qdep, tf * gbe_t + cdep
    qdep, cdep = depletion_charge(vbc, par[k, CJC], par[k, VJC], par[k, MJC], fc)
    return qbe, capbe, dqbe_dvbc, par[k, TR] * cbc + qdep, par[k, TR] * gbc + cdep


@njit(cache=True, inline="always")
def load(tp, ts, k, x_ext, a0, hist, q, qdot) -> int:
    """Linearize BJT ``k`` (a row of the terminal plan ``tp``) at ``x_ext``, writing
    ts.cur/slope/vlin/v_last and ts.rb_g; returns 1 when pnjlim limited a junction voltage."""
    par, ctrl, v_last, cur, slope = tp.par, tp.ctrl, ts.v_last, ts.cur, ts.slope
    pol, vt, vcrit = par[k, POLARITY], par[k, VT], par[k, VCRIT]
    # BjtFamily._limited, against the last evaluation
    vbe, hit_be = pnjlim(pol * (x_ext[ctrl[k, 0, 0]] - x_ext[ctrl[k, 0, 1]]), v_last[k, 0],
                         vt, vcrit)  # fmt: skip
    vbc, hit_bc = pnjlim(pol * (x_ext[ctrl[k, 1, 0]] - x_ext[ctrl[k, 1, 1]]), v_last[k, 1],
                         vt, vcrit)  # fmt: skip
    gmin = par[k, GMIN]
    cbe, gbe = junction_current(vbe, par[k, ISAT], par[k, VTF], 0.0)
    cben, gben = junction_current(vbe, par[k, ISE], par[k, VTE], 0.0)
    cben, gben = cben + gmin * vbe, gben + gmin
    cbc, gbc = junction_current(vbc, par[k, ISAT_BC], par[k, VTR], 0.0)
    cbcn, gbcn = junction_current(vbc, par[k, ISC], par[k, VTC], 0.0)
    cbcn, gbcn = cbcn + gmin * vbc, gbcn + gmin
    qb, dqbdve, dqbdvc = base_charge(vbe, vbc, cbe, gbe, cbc, gbc, par[k, INV_VAF],
                                     par[k, INV_VAR], par[k, INV_IKF], par[k, INV_IKR])  # fmt: skip
    bf, br = par[k, BF], par[k, BR]
    ic = (cbe - cbc) / qb - cbc / br - cbcn
    ib = cbe / bf + cben + cbc / br + cbcn
    go = (gbc + (cbe - cbc) * dqbdvc / qb) / qb
    gm = (gbe - (cbe - cbc) * dqbdve / qb) / qb - go
    gpi = gbe / bf + gben
    gmu = gbc / br + gbcn
    dic0, dic1, dib0, dib1 = gm + go, -go - gmu, gpi, gmu
    slot_be, slot_bc = tp.slot[k, 0], tp.slot[k, 1]
    if slot_be >= 0:  # the family has charges: ctx.integrate
        qbe, capbe, dqbe_dvbc, qbc, capbc = charges(
            par, k, vbe, vbc, cbe, gbe, cbc, gbc, qb, dqbdve, dqbdvc
        )
        icap_be = a0 * qbe + hist[slot_be]
        q[slot_be], qdot[slot_be] = qbe, icap_be
        icap_bc = a0 * qbc + hist[slot_bc]
        q[slot_bc], qdot[slot_bc] = qbc, icap_bc
        ib = ib + icap_be + icap_bc
        dib0 = dib0 + a0 * capbe
        dib1 = dib1 + a0 * dqbe_dvbc + a0 * capbc
        ic = ic - icap_bc
        dic1 = dic1 - a0 * capbc
    # the emitter' current is minus the other two
    cur[k, COLLECTOR], cur[k, BASE], cur[k, EMITTER] = pol * ic, pol * ib, pol * -(ic + ib)
    slope[k, COLLECTOR, 0], slope[k, COLLECTOR, 1] = dic0, dic1
    slope[k, BASE, 0], slope[k, BASE, 1] = dib0, dib1
    slope[k, EMITTER, 0], slope[k, EMITTER, 1] = -(dic0 + dib0), -(dic1 + dib1)
    v_last[k, 0], v_last[k, 1] = vbe, vbc
    ts.vlin[k, 0], ts.vlin[k, 1] = pol * vbe, pol * vbc
    if par[k, MODULATED_RB] != 0:
        ts.rb_g[k] = 1.0 / (par[k, RB_MIN] + par[k, RB_EXCESS] / qb)
    return 1 if hit_be or hit_bc else 0
