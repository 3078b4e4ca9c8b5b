"""The junction diode's kernel twin: diode.py's equations for one junction, compiled by numba.

:class:`~circuitsim.solver.devices.diode.DiodeFamily` evaluates all diodes at once with numpy
(the reference engine); the compiled loops (solver/compiled/) evaluate one junction at a time
without allocating, with these functions, written once here and inlined by both loops. Each
names the family method it mirrors; their agreement is tested in
tests/solver/test_device_kernels.py (value for value) and
tests/solver/test_compiled_kernel.py (whole circuits).

The parameters reach the loops as two matrices, one row per junction, whose columns are named
below (``DiodeFamily.kernel_data`` builds them by these names). The scalar equations take
scalars: a function that is not inlined pays an atomic reference-count update per array
argument on entry and exit.
"""

from __future__ import annotations

import math

from circuitsim.solver.jit import njit

# columns of the junction parameters (KernelPlan.jp): saturation current IS area (A), N Vt (V),
# 1 / (N Vt), IS / (N Vt) (S), -3 N Vt (the cubic reverse branch's knee, V), 3 N Vt / e (V),
# 3 N Vt (V), gmin (S), pnjlim's critical voltage (V), the step never limited (V)
(
    ISAT,
    VTE,
    INV_VTE,
    IS_OVER_VTE,
    REVERSE_KNEE,
    CUBIC_SCALE,
    THREE_VTE,
    GMIN,
    VCRIT,
    FREE_STEP,
) = range(10)
JUNCTION_COLUMNS = 10
# columns of the charge parameters (KernelPlan.cp): FC VJ (V), 1 / VJ, -M, VJ CJO / (1 - M) (C),
# the linear-quadratic continuation's offset (F), quadratic (F/V) and slope (F/V), CJO (F), TT (s)
(
    KNEE,
    INV_VJ,
    NEG_M,
    Q_SCALE,
    EXT_OFFSET,
    EXT_QUADRATIC,
    EXT_SLOPE,
    CJO,
    TT,
) = range(9)
CHARGE_COLUMNS = 9


@njit(cache=True)
def pnjlim(vnew: float, vold: float, vt: float, vcrit: float) -> tuple[float, bool]:
    """SPICE's junction-voltage limiting of one junction (diode.pnjlim); (volts, limited)."""
    if vnew > vcrit and abs(vnew - vold) > 2 * vt:
        if vold > 0:
            arg = 1 + (vnew - vold) / vt
            if arg > 0:
                return vold + vt * math.log(arg), True
            return vcrit, True
        return vt * math.log(max(vnew, vt) / vt), True
    floor = -vold - 1 if vold > 0 else 2 * vold - 1
    if vnew < floor:
        return floor, True
    return vnew, False


@njit(cache=True)
def junction_current(vd, isat, inv_vte, is_over_vte, knee, cubic_scale, three_vte, gmin):
    """Static current (A) and conductance (S) of one junction at vd (V) with gmin
    (DiodeFamily._current)."""
    if vd < knee:
        arg = (cubic_scale / vd) ** 3
        return isat * (-arg - 1.0) + gmin * vd, is_over_vte * (three_vte * arg / vd) + gmin
    ex = math.exp(min(vd * inv_vte, 700.0))
    return isat * (ex - 1.0) + gmin * vd, is_over_vte * ex + gmin


@njit(cache=True)
def junction_charge(
    vd, cd, gd, knee, inv_vj, neg_m, q_scale, ext_offset, ext_quadratic, ext_slope, cjo, tt
):
    """Depletion plus diffusion charge (C) and capacitance (F) of one junction at vd (V),
    whose static current is cd (A) and conductance gd (S) (DiodeFamily._charge)."""
    arg = 1.0 - min(vd, knee) * inv_vj
    sarg = arg**neg_m
    excess = max(vd - knee, 0.0)
    q = q_scale * (1.0 - arg * sarg) + excess * (ext_offset + ext_quadratic * vd)
    c = cjo * sarg + ext_slope * excess
    return q + tt * cd, c + tt * gd


@njit(cache=True, inline="always")
def linearize_junction(jp, cp, k, v, v_old, charged, a0, history):
    """Junction k linearized at the iterate's voltage ``v`` (DiodeFamily.port_load): limited
    against ``v_old`` (the accepted voltage at a time point's first iteration, the last
    linearization's after), its current and, when ``charged`` (CJO or TT), its charge turned
    into a companion by the step coefficient ``a0`` (1/s) and the charge's ``history`` (A):
    the solver's integration, as StepContext.integrate. ``jp``, ``cp``: the junction and
    charge parameters (columns above), shapes (md, JUNCTION_COLUMNS), (md, CHARGE_COLUMNS).

    Returns
    -------
    vd : float
        The linearization voltage (V), ``v`` or its limited value.
    limited : bool
        Whether pnjlim limited it (the iteration cannot be the last).
    current, conductance : float
        The junction's total current (A) and conductance (S) at vd, the charge's included.
    charge, charge_current : float
        Its charge (C) and dq/dt = a0 q + history (A); both 0 without ``charged``: a junction
        without CJO and TT has none, exactly (the op-amp macromodel's clamp diodes, 52 of the
        TL074 wheelset's 56 junctions, skip the evaluation: 17 % of its step).
    """
    # every parameter read here, in one basic block, where the arrays' lifetimes end: numba's
    # reference-count pruning then drops the atomic updates of the arguments (not inlined or
    # read behind a branch, they cost 2-3 atomic operations per junction and iteration)
    isat, vte, inv_vte, is_over_vte = jp[k, ISAT], jp[k, VTE], jp[k, INV_VTE], jp[k, IS_OVER_VTE]
    reverse_knee, cubic_scale, three_vte = jp[k, REVERSE_KNEE], jp[k, CUBIC_SCALE], jp[k, THREE_VTE]
    gmin, vcrit, free_step = jp[k, GMIN], jp[k, VCRIT], jp[k, FREE_STEP]
    knee, inv_vj, neg_m, q_scale = cp[k, KNEE], cp[k, INV_VJ], cp[k, NEG_M], cp[k, Q_SCALE]
    ext_offset, ext_quadratic = cp[k, EXT_OFFSET], cp[k, EXT_QUADRATIC]
    ext_slope, cjo, tt = cp[k, EXT_SLOPE], cp[k, CJO], cp[k, TT]
    vd = v
    limited = False
    # Steps within min(2 vt, 1 V) are never limited (pnjlim's forward rule needs a step above
    # 2 vt, its reverse rule one below -1 V): one test instead of pnjlim's dozen
    if abs(v - v_old) > free_step:
        vd, limited = pnjlim(v, v_old, vte, vcrit)
    current, conductance = junction_current(
        vd, isat, inv_vte, is_over_vte, reverse_knee, cubic_scale, three_vte, gmin
    )
    charge = 0.0
    charge_current = 0.0
    if charged:
        charge, capacitance = junction_charge(
            vd, current, conductance, knee, inv_vj, neg_m, q_scale, ext_offset, ext_quadratic,
            ext_slope, cjo, tt,
        )  # fmt: skip
        charge_current = a0 * charge + history
        current += charge_current
        conductance += a0 * capacitance
    return vd, limited, current, conductance, charge, charge_current
