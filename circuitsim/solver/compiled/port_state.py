"""The ports kernel's state (numpy only): what port_loop.run changes between calls."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from circuitsim.solver.compiled.plan import (
    KernelPlan,
    device_states,
    empty_factors,
    start_counters,
    start_floats,
)
from circuitsim.solver.compiled.slots import CFG_A0, CFG_VERSION
from circuitsim.solver.compiled.sparse_factors import SPARSE_FROM


class PortState(NamedTuple):
    """Everything the ports kernel changes (shapes: md junctions, ms switches, rR = ms + nl
    eliminated ports, r = md + rR, nq charge slots, nrows recorded unknowns)."""

    fs: np.ndarray  # (FLOAT_SLOTS,) slots.T, H, SAVED_H, LAST_A0, CFG_A0
    ints: np.ndarray  # (INT_SLOTS,) counters and flags: slots.ORDER, ..., CFG_COUNT, ...
    ht: np.ndarray  # (4,) accepted times, newest first
    hq: np.ndarray  # (4, nq) charges there
    hi: np.ndarray  # (2, nq) their derivatives
    hv: np.ndarray  # (2, md) junction voltages at the last two accepted points
    hc: np.ndarray  # (2, ms) switch control voltages there
    x_ext: np.ndarray  # (n + 1,) control nodes of the present iterate (others unused)
    x_prev_ext: np.ndarray  # (n + 1,) control nodes at the last accepted point
    vd: np.ndarray  # (md,) junction linearization: voltage, current, conductance, ieq
    cd: np.ndarray
    gd: np.ndarray
    ieq: np.ndarray
    vd_accepted: np.ndarray
    state: np.ndarray  # (ms,) switch states, bool
    accepted: np.ndarray
    fac: object  # plan.Factors
    dR: np.ndarray  # (rR,) configuration: R ports' value changes since the factorization
    F: np.ndarray  # (rR, rR)
    G: np.ndarray  # (rR, rR) D_R F
    H: np.ndarray  # (md, md) columns formed for the present configuration (colv)
    hcol: np.ndarray  # (md,) max |H[:, k]| of the formed columns
    bound: np.ndarray  # (md,) an upper bound of it for every column
    colv: np.ndarray  # (md,) int: the configuration count column k was formed at
    tr: np.ndarray  # (rR,) scratch
    tr2: np.ndarray  # (rR,) scratch
    Hieq: np.ndarray  # (md,) H ieq_applied
    ieq_applied: np.ndarray  # (md,)
    act: np.ndarray  # (md,) int: active junctions of the iteration
    xa: np.ndarray  # (md,) their solution
    c0: np.ndarray  # (r,) time point: port response of sources and charge history
    e0: np.ndarray  # (md,)
    Fc0: np.ndarray  # (rR,)
    A: np.ndarray  # (md, md) Newton scratch
    b: np.ndarray  # (md,)
    pJ: np.ndarray  # (md,) iterate's junction voltages
    pJ_new: np.ndarray
    dJ: np.ndarray
    j: np.ndarray  # (md,) junction current deviation
    pR: np.ndarray  # (rR,)
    w: np.ndarray  # (rR,) dR * pR
    vc: np.ndarray  # (ms,) iterate's control voltages
    fail_v: np.ndarray  # (2, md) the last Newton iterate's junction voltages and the one before
    rows: np.ndarray  # (nrows,) unknowns recorded at every accepted point
    out_t: np.ndarray
    out_x: np.ndarray  # (capacity, nrows)


def initial_port_state(
    plan: KernelPlan,
    families: dict,
    x0: np.ndarray,
    q0: np.ndarray,
    capacity: int,
    rows: np.ndarray,
) -> PortState:
    """The ports kernel's state at t = 0 from the start solution ``x0`` (shape (n,)), its
    charges ``q0`` and the families' states; ``rows``: the unknowns to record."""
    n, nq = x0.size, q0.size
    md, ms, r = plan.jp.shape[0], plan.sw.shape[0], plan.VT.shape[0]
    rR = r - md
    x_ext = np.append(x0, 0.0)
    ports = x_ext[plan.port_p[:md]] - x_ext[plan.port_n[:md]]
    control = x_ext[plan.sw[:, 2]] - x_ext[plan.sw[:, 3]] if ms else np.zeros(0)
    hq = np.zeros((4, nq))
    hq[0] = q0
    rows = np.ascontiguousarray(rows, dtype=np.int64)
    out_x = np.zeros((capacity, rows.size))
    out_x[0] = x0[rows]
    ints = start_counters()
    ints[CFG_VERSION] = -1
    fs = start_floats()
    fs[CFG_A0] = np.nan
    z = np.zeros
    return PortState(
        fs=fs,
        ints=ints,
        ht=z(4),
        hq=hq,
        hi=z((2, nq)),
        hv=np.ascontiguousarray(np.stack([ports, ports])),
        hc=np.ascontiguousarray(np.stack([control, control])),
        x_ext=x_ext.copy(),
        x_prev_ext=x_ext.copy(),
        **device_states(families),
        fac=empty_factors(n, r, md, plan.lin_slots.size, plan.src_kind.size, dense=n < SPARSE_FROM),
        dR=z(rR),
        F=z((rR, rR)),
        G=z((rR, rR)),
        H=z((md, md)),
        hcol=z(md),
        bound=z(md),
        colv=np.full(md, -1, dtype=np.int64),
        tr=z(rR),
        tr2=z(rR),
        Hieq=z(md),
        ieq_applied=z(md),
        act=np.zeros(md, dtype=np.int64),
        xa=z(md),
        c0=z(r),
        e0=z(md),
        Fc0=z(rR),
        A=z((md, md)),
        b=z(md),
        pJ=z(md),
        pJ_new=z(md),
        dJ=z(md),
        j=z(md),
        pR=z(rR),
        w=z(rR),
        vc=z(ms),
        fail_v=z((2, md)),
        rows=rows,
        out_t=z(capacity),
        out_x=out_x,
    )
