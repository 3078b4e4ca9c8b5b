"""The ports kernel's state (numpy only): what time_loop.run_ports changes between calls."""

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
from circuitsim.solver.devices.switch_kernel import CONTROL_NEGATIVE, CONTROL_POSITIVE


class PortState(NamedTuple):
    """Everything the ports kernel changes (shapes: md junctions, ms switches, rR = ms + nl
    eliminated ports: the switches' and the linear charges', r = md + rR, nq charge slots,
    nrows recorded unknowns). The matrices' names are ports.py's."""

    fs: np.ndarray  # (FLOAT_SLOTS,) slots.T, H, SAVED_H, LAST_A0, CFG_A0
    ints: np.ndarray  # (INT_SLOTS,) counters and flags: slots.ORDER, ..., CFG_COUNT, ...
    t_history: np.ndarray  # (4,) accepted times, newest first
    q_history: np.ndarray  # (4, nq) charges there
    qdot_history: np.ndarray  # (2, nq) their derivatives
    v_history: np.ndarray  # (2, md) junction voltages at the last two accepted points
    control_history: np.ndarray  # (2, ms) switch control voltages there
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
    # the configuration (a0 and switch states): the eliminated ports' value changes since the
    # factorization (D_R), F = (I + K_RR D_R)^-1, G = D_R F, the columns of H formed so far
    d_eliminated: np.ndarray  # (rR,)
    F: np.ndarray  # (rR, rR)
    G: np.ndarray  # (rR, rR)
    H: np.ndarray  # (md, md) columns formed for the present configuration (formed_at)
    h_max: np.ndarray  # (md,) max |H[:, k]| of the formed columns
    bound: np.ndarray  # (md,) an upper bound of it for every column
    formed_at: np.ndarray  # (md,) int: the configuration count column k was formed at
    scratch: np.ndarray  # (rR,)
    scratch2: np.ndarray  # (rR,)
    h_ieq: np.ndarray  # (md,) H ieq_applied
    ieq_applied: np.ndarray  # (md,)
    y_junctions: np.ndarray  # (n,) the recorded unknowns' junction part (ports.all_unknowns)
    current_applied: np.ndarray  # (md,) the junction currents y_junctions holds
    active: np.ndarray  # (md,) int: active junctions of the iteration
    x_active: np.ndarray  # (md,) their solution
    c0: np.ndarray  # (r,) time point: port response of sources and charge history
    e0: np.ndarray  # (md,) c0_J - K_JR G c0_R
    Fc0: np.ndarray  # (rR,) F c0_R
    A: np.ndarray  # (md, md) the active junctions' system
    b: np.ndarray  # (md,)
    v_junction: np.ndarray  # (md,) the iterate's junction voltages
    v_new: np.ndarray  # (md,) the next iterate's
    dg: np.ndarray  # (md,) junction conductance changes since the factorization (D_J)
    current_dev: np.ndarray  # (md,) junction current deviation j = ieq + D_J p_J
    p_eliminated: np.ndarray  # (rR,) the eliminated ports' values p_R
    w: np.ndarray  # (rR,) D_R p_R
    v_control: np.ndarray  # (ms,) the iterate's control voltages
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
    control_nodes = plan.sw[:, CONTROL_POSITIVE], plan.sw[:, CONTROL_NEGATIVE]
    control = x_ext[control_nodes[0]] - x_ext[control_nodes[1]] if ms else np.zeros(0)
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
        t_history=z(4),
        q_history=hq,
        qdot_history=z((2, nq)),
        v_history=np.ascontiguousarray(np.stack([ports, ports])),
        control_history=np.ascontiguousarray(np.stack([control, control])),
        x_ext=x_ext.copy(),
        x_prev_ext=x_ext.copy(),
        **device_states(families),
        fac=empty_factors(n, r, md, plan.lin_slots.size, plan.src_kind.size, dense=n < SPARSE_FROM),
        d_eliminated=z(rR),
        F=z((rR, rR)),
        G=z((rR, rR)),
        H=z((md, md)),
        h_max=z(md),
        bound=z(md),
        formed_at=np.full(md, -1, dtype=np.int64),
        scratch=z(rR),
        scratch2=z(rR),
        h_ieq=z(md),
        ieq_applied=z(md),
        y_junctions=z(n),
        current_applied=z(md),
        active=np.zeros(md, dtype=np.int64),
        x_active=z(md),
        c0=z(r),
        e0=z(md),
        Fc0=z(rR),
        A=z((md, md)),
        b=z(md),
        v_junction=z(md),
        v_new=z(md),
        dg=z(md),
        current_dev=z(md),
        p_eliminated=z(rR),
        w=z(rR),
        v_control=z(ms),
        fail_v=z((2, md)),
        rows=rows,
        out_t=z(capacity),
        out_x=out_x,
    )
