"""Kernel twin of jfet.py: one JFET linearized at the iterate, for the compiled MNA kernel.

The equations of :class:`~circuitsim.solver.devices.jfet.JfetFamily` (``_limited``, ``load``,
``_drain_current``) for one element: limiting against the last evaluation (pnjlim, then
fetlim), the gate junctions, the level-1 drain current with B, the CGS/CGD depletion charges
integrated through the kernel's charge slots. :func:`load` writes the element's terminal
currents and slopes into the terminal state (compiled/terminal_plan.py) in the circuit's
frame, as the family's ``lin``.
"""

from __future__ import annotations

from circuitsim.solver.devices.diode_kernel import pnjlim
from circuitsim.solver.devices.junction_kernel import depletion_charge, fetlim, junction_current
from circuitsim.solver.jit import njit

# columns of the terminal plan's ``par`` for a JFET (JfetFamily.kernel_data's order)
PARAMS = ("polarity", "isat", "vt", "vcrit", "gmin", "vto", "beta", "lambda", "b", "b_factor",
          "cgs", "cgd", "pb", "fc")  # fmt: skip
POLARITY, ISAT, VT, VCRIT, GMIN, VTO, BETA, LAMBDA, B, B_FACTOR, CGS, CGD, PB, FC = range(14)
# terminals: drain', gate, source'; controls: v_gs, v_gd
DRAIN, GATE, SOURCE = 0, 1, 2


@njit(cache=True)
def drain_current(vgs, vgd, vto, beta, lam, b, bf):
    """JfetFamily._drain_current of one element: (A, S, S)."""
    vds = vgs - vgd
    normal = vds >= 0
    # the inverse mode is the normal one with drain and source exchanged
    vgst = (vgs if normal else vgd) - vto
    if not vgst > 0:
        return 0.0, 0.0, 0.0
    u = abs(vds)
    betap = beta * (1 + lam * u)
    apart = 2 * b + 3 * bf * (vgst - u)
    if vgst >= u:  # below saturation
        cpart = u * (u * (bf * u - b) + vgst * apart)
        f_vgst = betap * u * (apart + 3 * bf * vgst)
        f_u = betap * (vgst - u) * apart + beta * lam * cpart
    else:
        cpart = vgst * vgst * (b + bf * vgst)
        f_vgst = betap * vgst * (2 * b + 3 * bf * vgst)
        f_u = 0.0 + beta * lam * cpart
    f = betap * cpart
    # normal: i = f(vgs - vto, vgs - vgd); inverse: i = -f(vgd - vto, vgd - vgs)
    if normal:
        return f, f_vgst + f_u, -f_u
    return -f, f_u, -(f_vgst + f_u)


@njit(cache=True)
def limit(vnew, vold, vt, vcrit, vto):
    """One gate junction's voltage as JfetFamily._limited limits it: pnjlim, then fetlim
    (volts, n-channel frame); and whether pnjlim limited it."""
    v, hit = pnjlim(vnew, vold, vt, vcrit)
    return fetlim(v, vold, vto), hit


@njit(cache=True, inline="always")
def load(tp, ts, k, x_ext, a0, hist, q, qdot) -> int:
    """Linearize JFET ``k`` (a row of the terminal plan ``tp``) at ``x_ext``, writing
    ts.cur/slope/vlin/v_last; returns 1 when pnjlim limited a junction voltage."""
    par, ctrl, v_last, cur, slope = tp.par, tp.ctrl, ts.v_last, ts.cur, ts.slope
    pol, vt, vcrit, vto = par[k, POLARITY], par[k, VT], par[k, VCRIT], par[k, VTO]
    # JfetFamily._limited, against the last evaluation
    vgs, hit_gs = limit(pol * (x_ext[ctrl[k, 0, 0]] - x_ext[ctrl[k, 0, 1]]), v_last[k, 0],
                        vt, vcrit, vto)  # fmt: skip
    vgd, hit_gd = limit(pol * (x_ext[ctrl[k, 1, 0]] - x_ext[ctrl[k, 1, 1]]), v_last[k, 1],
                        vt, vcrit, vto)  # fmt: skip
    isat, gmin = par[k, ISAT], par[k, GMIN]
    cgs, ggs = junction_current(vgs, isat, vt, gmin)
    cgd, ggd = junction_current(vgd, isat, vt, gmin)
    cdrain, di_dvgs, di_dvgd = drain_current(
        vgs, vgd, vto, par[k, BETA], par[k, LAMBDA], par[k, B], par[k, B_FACTOR]
    )
    slot_gs, slot_gd = tp.slot[k, 0], tp.slot[k, 1]
    if slot_gs >= 0:  # the family has CGS/CGD: ctx.integrate
        qgs, capgs = depletion_charge(vgs, par[k, CGS], par[k, PB], 0.5, par[k, FC])
        qgd, capgd = depletion_charge(vgd, par[k, CGD], par[k, PB], 0.5, par[k, FC])
        icap = a0 * qgs + hist[slot_gs]
        q[slot_gs], qdot[slot_gs] = qgs, icap
        cgs, ggs = cgs + icap, ggs + a0 * capgs
        icap = a0 * qgd + hist[slot_gd]
        q[slot_gd], qdot[slot_gd] = qgd, icap
        cgd, ggd = cgd + icap, ggd + a0 * capgd
    # currents into drain', gate, source' (circuit's frame) and slopes in (v_gs, v_gd)
    cur[k, DRAIN] = pol * (cdrain - cgd)
    cur[k, GATE] = pol * (cgs + cgd)
    cur[k, SOURCE] = pol * (-cdrain - cgs)
    slope[k, DRAIN, 0], slope[k, DRAIN, 1] = di_dvgs, di_dvgd - ggd
    slope[k, GATE, 0], slope[k, GATE, 1] = ggs, ggd
    slope[k, SOURCE, 0], slope[k, SOURCE, 1] = -di_dvgs - ggs, -di_dvgd
    v_last[k, 0], v_last[k, 1] = vgs, vgd
    ts.vlin[k, 0], ts.vlin[k, 1] = pol * vgs, pol * vgd
    return 1 if hit_gs or hit_gd else 0
