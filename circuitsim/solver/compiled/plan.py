"""The arrays the compiled kernel runs on, gathered from an assembled MnaSystem.

The plan is plain numpy, built from the system's matrices and from each device family's
:meth:`~circuitsim.solver.devices.base.DeviceFamily.kernel_data` (the families describe
themselves; the plan never asks which class a family is). The columns of the device parameter
matrices are named in the families' kernel twins (devices/diode_kernel.py, switch_kernel.py,
source_kernel.py), the slots of ``real``, ``ints`` and the loops' state in slots.py.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from circuitsim.solver.compiled import slots
from circuitsim.solver.compiled.terminal_plan import (
    TerminalPlan,
    TerminalState,
    terminal_plan,
    terminal_state,
)
from circuitsim.solver.compressed import Compressed
from circuitsim.solver.devices import diode_kernel, source_kernel, switch_kernel
from circuitsim.solver.integration import METHODS
from circuitsim.solver.system import MnaSystem

# The MNA kernel's chord (compiled/mna_newton.py): a junction whose conductance is within this
# fraction of the one its port was factored with keeps the factored one (its current is
# exact, so the converged point is the same; a Newton step then contracts the error by about
# this fraction instead of quadratically). Measured on the golden netlists: 1e-4 keeps the
# compiled kernel's time points those of the reference loop, 1e-3 moves one of halfwave.cir's
# accept decisions (docs/solver.md, "The MNA kernel").
CHORD_TOLERANCE = 1e-4
# From WIDE_CHORD_FROM unknowns on, the chord's tolerance is WIDE_CHORD_TOLERANCE: there the
# refactor is most of a Newton iteration, and the wider chord leaves 0.5-0.65 of the
# refactors at the same steps within 1 % and Newton iterations within 3 % (the chains of 8-64
# masses, docs/solver.md "The wide chord"); below, the golden netlists keep the reference
# loop's time points.
WIDE_CHORD_TOLERANCE = 0.05
WIDE_CHORD_FROM = 100


class KernelPlan(NamedTuple):
    """Constant data of one transient run (shapes: n unknowns, md junctions, ms switches,
    nl linear charges, r = md + ms + nl low-rank columns, ns sources)."""

    # (n, n) constant stamps, and E Q, the linear charges' matrix (times a0); U and VT dense:
    # all four (0, 0) in the MNA kernel's plan (it takes G and M sparse from the system,
    # runner._constant_parts, and U and VT in the compressed forms below)
    G: np.ndarray
    M: np.ndarray
    U: np.ndarray  # (n, r) low-rank columns: junction ports, switch ports, E of linear charges
    VT: np.ndarray  # (r, n) low-rank rows: the same ports, Q of linear charges
    VT_ptr: np.ndarray  # VT in CSR form
    VT_idx: np.ndarray
    VT_val: np.ndarray
    UT_ptr: np.ndarray  # U^T in CSR form (the columns of U)
    UT_idx: np.ndarray
    UT_val: np.ndarray
    port_p: np.ndarray  # (md + ms,) node of each port's + side (-1 ground)
    port_n: np.ndarray  # (md + ms,)
    jp: np.ndarray  # (md, JUNCTION_COLUMNS) junction parameters (diode_kernel.ISAT, ...)
    cp: np.ndarray  # (md, CHARGE_COLUMNS) charge parameters (diode_kernel.KNEE, ...)
    jslot: np.ndarray  # (md,) charge slot of each junction
    has_charge: bool
    charged: np.ndarray  # (md,) bool: the junction has CJO or TT (else q = C = 0 exactly)
    sw: np.ndarray  # (ms, 4) nodes: switch_kernel.POSITIVE, ..., CONTROL_NEGATIVE
    approach: np.ndarray  # (ms, 4) switch_kernel.ON_ABOVE, OFF_BELOW, FRACTION, FLOOR
    g_switch: np.ndarray  # (ms, 2) switch_kernel.G_ON, G_OFF (S)
    rhs_const: np.ndarray  # (n,) right-hand side of the constant (DC-only) sources
    src_kind: np.ndarray  # (ns,) source_kernel.SIN, PULSE, PWL (time-dependent sources only)
    src_par: np.ndarray  # (ns, PARAM_COLUMNS) source_kernel.OFFSET, ... / INITIAL, ...
    src_dc: np.ndarray  # (ns,)
    pwl_start: np.ndarray  # (ns + 1,) offsets into pwl_t / pwl_v
    pwl_t: np.ndarray
    pwl_v: np.ndarray
    src_unit: np.ndarray  # (n, ns) each time-dependent source's right-hand side at value 1
    src_rows: np.ndarray  # (ns, 2) rhs rows (-1: none)
    src_signs: np.ndarray  # (ns, 2)
    lin_slots: np.ndarray  # (nl,) charge slots of the linear charges
    abs_tol: np.ndarray  # (n,) vntol or abstol per unknown
    breaks: np.ndarray  # sorted breakpoints, seconds, ending with tstop
    real: np.ndarray  # (REAL_SLOTS,) slots.RELTOL, ..., TSTOP
    ints: np.ndarray  # (PLAN_INT_SLOTS,) slots.METHOD, MAXORD, ITL4, MAX_STEPS, UIC
    terms: TerminalPlan  # JFETs, BJTs, nonlinear POLY sources (MNA kernel only)


class Factors(NamedTuple):
    """One factorization and what is derived from it (shapes: n unknowns, r low-rank
    columns, md junctions, nl linear charges, ns time-dependent sources)."""

    B: np.ndarray  # (n, n) the factored matrix
    Binv: np.ndarray  # (n, n) its inverse
    Z: np.ndarray  # (n, r) B^-1 U
    ZT: np.ndarray  # (r, n) Z transposed (rows contiguous)
    K: np.ndarray  # (r, r) V^T Z
    ref: np.ndarray  # (r,) port values at the factorization (a0 for the charges)
    ZdT: np.ndarray  # (md, n) junction columns of Z, as rows
    KdT: np.ndarray  # (md, r) junction columns of K, as rows
    zrel: np.ndarray  # (md,) max over unknowns i of |Z[i, j]| / (vntol or abstol of i)
    Zq: np.ndarray  # (n, nl) charge columns of Z: response to the charge history
    Kq: np.ndarray  # (r, nl)
    yc: np.ndarray  # (n,) B^-1 of the constant sources' right-hand side
    cc: np.ndarray  # (r,) V^T yc
    Yb: np.ndarray  # (n, ns) B^-1 of each time-dependent source's unit right-hand side
    Cb: np.ndarray  # (r, ns) V^T Yb
    b_ptr: np.ndarray  # B in CSR form (the residual products are sparse)
    b_idx: np.ndarray
    b_val: np.ndarray


def empty_factors(n: int, r: int, md: int, nl: int, ns: int, dense: bool = True) -> Factors:
    """Zero arrays of the right shapes, for :func:`rebuild` to fill; without ``dense``, B, its
    inverse and its CSR form are empty (the runner then factors sparse, sparse_factors.py)."""
    z = np.zeros
    nd = n if dense else 0
    return Factors(
        z((nd, nd)),
        z((nd, nd)),
        z((n, r)),
        z((r, n)),
        z((r, r)),
        z(r),
        z((md, n)),
        z((md, r)),
        z(md),
        z((n, nl)),
        z((r, nl)),
        z(n),
        z(r),
        z((n, ns)),
        z((r, ns)),
        z(nd + 1, dtype=np.int64),
        z(nd * nd, dtype=np.int64),
        z(nd * nd),
    )


class KernelState(NamedTuple):
    """Everything the MNA kernel's loop (time_loop.run_mna) changes, kept between calls."""

    fs: np.ndarray  # (FLOAT_SLOTS,) slots.T, H, SAVED_H, LAST_A0, REPIVOT_A0
    ints: np.ndarray  # (INT_SLOTS,) slots.ORDER, ...
    ht: np.ndarray  # (4,) accepted times, newest first
    hx: np.ndarray  # (4, n) solutions there
    hq: np.ndarray  # (4, nq) charges
    hi: np.ndarray  # (2, nq) their derivatives
    x_prev_ext: np.ndarray  # (n + 1,) last accepted solution with ground
    vd: np.ndarray  # (md,) junction linearization point, current, conductance, ieq
    cd: np.ndarray
    gd: np.ndarray
    ieq: np.ndarray
    vd_accepted: np.ndarray
    state: np.ndarray  # (ms,) switch states, bool
    accepted: np.ndarray
    lu: object  # sparse_lu.SparseLU: the whole matrix's pattern, pivot order and factors
    out_t: np.ndarray
    out_x: np.ndarray
    fail_x: np.ndarray
    fail_prev: np.ndarray
    terms: TerminalState


def unsupported(system: MnaSystem, kernel: str = "compiled") -> str | None:
    """Why ``kernel`` (``"compiled"``, the MNA kernel, or ``"ports"``) cannot run this
    system, or None when it can."""
    parts = []
    for family in system.families:
        part = family.kernel_data()
        if part is None:
            return f"no compiled model for {type(family).__name__}"
        if part["kind"] == "terminals" and kernel == "ports":
            return (
                f"no compiled model for {type(family).__name__} in the ports kernel (the MNA "
                "kernel, kernel=compiled, runs it)"
            )
        parts.append(part)
    ranks = system.linear_slots.size + sum(
        len(p["p"]) if p["kind"] == "junctions" else len(p["nodes"]) if p["kind"] == "switches"
        else len(p["rows"])
        for p in parts
        if p["kind"] in ("junctions", "switches", "terminals")
    )  # fmt: skip
    if ranks == 0:
        return "no charges, junctions or switches (nothing for the kernel to integrate)"
    return None


def _csr(name: str, transposed: Compressed) -> dict:
    """Matrix ``name`` in compressed rows, column indices ascending, from its transpose in
    compressed columns (the same three arrays)."""
    return {f"{name}_ptr": transposed.ptr, f"{name}_idx": transposed.row,
            f"{name}_val": transposed.val}  # fmt: skip


def low_rank_columns(system: MnaSystem, port_p, port_n, lin) -> tuple[Compressed, Compressed]:
    """U = [W, E_lin] and V = [W, Q_lin^T] (both (n, r), compressed columns; VT = V^T):
    W's column k is e_p - e_n of port k (ground rows left out), E_lin the columns ``lin`` of
    E, Q_lin the rows ``lin`` of Q. Sparse throughout: dense, U and V took 2 x 0.31 GB
    and the plan 3.7-3.9 s at the TL074 chain of 64 masses (11 782 unknowns, 3328 columns),
    now 0.014 s."""
    n, nports = system.size, port_p.size
    rows = np.concatenate([port_p, port_n]).astype(np.int64)
    cols = np.tile(np.arange(nports, dtype=np.int64), 2)
    signs = np.repeat([1.0, -1.0], nports)
    inside = rows >= 0
    w = (rows[inside], cols[inside], signs[inside])
    slot_of = np.full(n, -1, dtype=np.int64)  # column of E (row of Q) -> its place in lin
    slot_of[lin] = np.arange(lin.size)
    e_row, e_col, e_val = system.compressed("E").triplets()
    kept = slot_of[e_col] >= 0
    u = (e_row[kept], nports + slot_of[e_col[kept]], e_val[kept])
    q_row, q_col, q_val = system.compressed("Q").triplets()
    kept = slot_of[q_row] >= 0
    v = (q_col[kept], nports + slot_of[q_row[kept]], q_val[kept])
    shape = (n, nports + lin.size)
    return tuple(
        Compressed.from_triplets(
            *(np.concatenate([a, b]) for a, b in zip(w, part, strict=True)), shape
        )  # fmt: skip
        for part in (u, v)
    )


def _unit_columns(n: int, rows: list[np.ndarray], signs: list[np.ndarray]) -> np.ndarray:
    """(n, ns): column k is source k's right-hand side per unit value."""
    all_rows = np.concatenate(rows) if rows else np.zeros((0, 2), dtype=np.int64)
    all_signs = np.concatenate(signs) if signs else np.zeros((0, 2))
    unit = np.zeros((n + 1, all_rows.shape[0]))
    for k, (pair, sign) in enumerate(zip(all_rows, all_signs, strict=True)):
        for row, value in zip(pair, sign, strict=True):
            if row >= 0:
                unit[row, k] += value
    return np.ascontiguousarray(unit[:n])


def _dense(system: MnaSystem, name: str) -> np.ndarray:
    """The system's matrix ``name`` as a dense array (a sparse system's from its compressed
    form: no scipy)."""
    dense = getattr(system, name) if system.dense else system.compressed(name).toarray()
    return np.ascontiguousarray(dense, dtype=float)  # one dtype: one compiled kernel


def build_plan(
    system: MnaSystem,
    breaks: np.ndarray,
    tstop: float,
    max_step: float,
    min_step: float,
    uic: bool = False,
    dense: bool = True,
) -> tuple[KernelPlan, dict]:
    """The plan, and the families' present states (for the kernel's initial state).

    ``uic``: the run starts from initial conditions, not a solution (``ints[UIC]``: the first
    step then locates no switch transition: solver/transient.py, run_transient). ``dense``:
    G and M as dense (n, n) arrays (the ports kernel's), else empty (the MNA kernel's: 2 x
    52 MB at 2562 unknowns, and 80-90 ms of CPU to fill).
    """
    options = system.options
    n = system.size
    parts = [f.kernel_data() for f in system.families]
    junctions = [p for p in parts if p["kind"] == "junctions"]
    switches = [p for p in parts if p["kind"] == "switches"]
    sources = [p for p in parts if p["kind"] == "sources"]

    def cat(items, key, shape, dtype=float):
        arrays = [np.asarray(p[key], dtype=dtype) for p in items]
        return np.concatenate(arrays) if arrays else np.zeros(shape, dtype=dtype)

    jp = cat(junctions, "params", (0, diode_kernel.JUNCTION_COLUMNS))
    md = jp.shape[0]
    has_charge = any(p["charge"] is not None for p in junctions)
    cp = np.zeros((md, diode_kernel.CHARGE_COLUMNS))
    jslot = np.zeros(md, dtype=np.int64)
    start = 0
    for p in junctions:
        m = len(p["p"])
        if p["charge"] is not None:
            cp[start : start + m] = p["charge"]
            jslot[start : start + m] = p["slots"]
        start += m
    sw = cat(switches, "nodes", (0, switch_kernel.NODE_COLUMNS), np.int64)
    port_p = np.concatenate([cat(junctions, "p", (0,), np.int64), sw[:, 0]])
    port_n = np.concatenate([cat(junctions, "n", (0,), np.int64), sw[:, 1]])

    lin = np.asarray(system.linear_slots, dtype=np.int64)
    U, V = low_rank_columns(system, port_p, port_n, lin)

    kinds, pars, dcs, rows, signs, pwl = [], [], [], [], [], []
    rhs_const = np.zeros(n)
    for p in sources:
        kind, par, dc, tables = p["values"].kernel_arrays()
        p_rows = np.asarray(p["rows"], dtype=np.int64)
        p_signs = np.asarray(p["signs"], dtype=float)
        for j in np.flatnonzero(kind == source_kernel.DC):  # constant: folded in once
            for row, sign in zip(p_rows[j], p_signs[j], strict=True):
                if row >= 0:
                    rhs_const[row] += sign * dc[j]
        varying = np.flatnonzero(kind != source_kernel.DC)
        kinds.append(kind[varying])
        pars.append(par[varying])
        dcs.append(dc[varying])
        pwl.extend(tables[j] for j in varying)
        rows.append(p_rows[varying])
        signs.append(p_signs[varying])
    ns = sum(k.size for k in kinds)
    pwl_start = np.concatenate([[0], np.cumsum([t.shape[1] for t in pwl])]).astype(np.int64)
    real = np.zeros(slots.REAL_SLOTS)
    real[slots.RELTOL] = options.reltol
    real[slots.ABSTOL] = options.abstol
    real[slots.VNTOL] = options.vntol
    real[slots.CHGTOL] = options.chgtol
    real[slots.TRTOL] = options.trtol
    real[slots.ERROR_ORDER1], real[slots.ERROR_ORDER2] = METHODS[options.method].error_constants
    real[slots.FIXED_STEP] = options.fixed_step or 0.0
    real[slots.MAX_STEP] = max_step
    real[slots.MIN_STEP] = min_step
    real[slots.TSTOP] = tstop
    real[slots.CHORD] = WIDE_CHORD_TOLERANCE if n >= WIDE_CHORD_FROM else CHORD_TOLERANCE
    ints = np.zeros(slots.PLAN_INT_SLOTS, dtype=np.int64)
    ints[slots.METHOD] = slots.TRAP if options.method == "trap" else slots.GEAR
    ints[slots.MAXORD] = options.maxord
    ints[slots.ITL4] = options.transient_iterations
    ints[slots.MAX_STEPS] = options.max_steps
    ints[slots.UIC] = int(uic)
    plan = KernelPlan(
        G=_dense(system, "G") if dense else np.zeros((0, 0)),
        M=_dense(system, "M") if dense else np.zeros((0, 0)),
        U=U.toarray() if dense else np.zeros((0, 0)),
        VT=np.ascontiguousarray(V.toarray().T) if dense else np.zeros((0, 0)),
        **_csr("VT", V),
        **_csr("UT", U),
        port_p=port_p,
        port_n=port_n,
        jp=np.ascontiguousarray(jp),
        cp=cp,
        jslot=jslot,
        has_charge=has_charge,
        charged=(cp[:, diode_kernel.CJO] != 0) | (cp[:, diode_kernel.TT] != 0),
        sw=np.ascontiguousarray(sw),
        approach=np.ascontiguousarray(
            cat(switches, "approach", (0, switch_kernel.APPROACH_COLUMNS))
        ),
        g_switch=np.ascontiguousarray(cat(switches, "g", (0, 2))),
        rhs_const=rhs_const,
        src_kind=np.concatenate(kinds) if kinds else np.zeros(0, dtype=np.int64),
        src_par=np.concatenate(pars) if pars else np.zeros((0, source_kernel.PARAM_COLUMNS)),
        src_dc=np.concatenate(dcs) if dcs else np.zeros(0),
        pwl_start=pwl_start,
        pwl_t=np.concatenate([t[0] for t in pwl]) if pwl else np.zeros(0),
        pwl_v=np.concatenate([t[1] for t in pwl]) if pwl else np.zeros(0),
        src_unit=_unit_columns(n, rows, signs),
        src_rows=np.concatenate(rows) if rows else np.zeros((0, 2), dtype=np.int64),
        src_signs=np.concatenate(signs) if signs else np.zeros((0, 2)),
        lin_slots=lin,
        abs_tol=np.asarray(system.abs_tol, dtype=float),
        breaks=np.asarray(breaks, dtype=float),
        real=real,
        ints=ints,
        terms=terminal_plan(parts),
    )
    assert ns == plan.src_kind.size
    return plan, {"junctions": junctions, "switches": switches, "terminals": parts}


def device_states(families: dict) -> dict:
    """The junctions' linearization (vd, cd, gd, ieq, vd_accepted; shape (md,)) and the
    switches' states (state, accepted; bool, shape (ms,)) at t = 0, from build_plan's
    ``families``: what both kernels start from."""

    def cat(items, pick):
        arrays = [np.asarray(pick(p), dtype=float) for p in items]
        return np.concatenate(arrays) if arrays else np.zeros(0)

    junctions, switches = families["junctions"], families["switches"]
    vd, cd, gd = (cat(junctions, lambda p, i=i: p["state"][i]).copy() for i in range(3))
    return {
        "vd": vd,
        "cd": cd,
        "gd": gd,
        "ieq": cd - gd * vd,
        "vd_accepted": cat(junctions, lambda p: p["vd_accepted"]).copy(),
        "state": cat(switches, lambda p: p["state"]).astype(bool),
        "accepted": cat(switches, lambda p: p["accepted"]).astype(bool),
    }


def start_floats() -> np.ndarray:
    """The loop's float state at t = 0 (slots.py): t = 0, h set by the runner, no a0 yet."""
    fs = np.zeros(slots.FLOAT_SLOTS)
    fs[slots.LAST_A0] = np.nan
    return fs


def start_counters() -> np.ndarray:
    """The loop's integer state at t = 0 (slots.py): order 1, at a breakpoint, first step,
    one history point, one output point, no junction response yet, no pause."""
    ints = np.zeros(slots.INT_SLOTS, dtype=np.int64)
    ints[slots.ORDER] = 1
    ints[slots.AT_BREAK] = 1  # t = 0
    ints[slots.FIRST] = 1
    ints[slots.NHIST] = 1
    ints[slots.COUNT] = 1  # the output row of t = 0
    ints[slots.JUNCTION_VERSION] = -1
    ints[slots.PAUSE_ATTEMPTS] = np.iinfo(np.int64).max  # until the caller sets one
    ints[slots.MEASURED_VERSION] = 1  # the start's factorization is version 1
    ints[slots.NEW_H_MATRIX] = 1
    ints[slots.Y_VERSION] = -1
    return ints


def initial_state(
    plan: KernelPlan, families: dict, x0: np.ndarray, q0: np.ndarray, capacity: int, lu
) -> KernelState:
    """The MNA loop's state at t = 0 from the start solution, the families' states and the
    first pivot order ``lu`` (sparse_order.analyse)."""
    n, nq = x0.size, q0.size
    hx = np.zeros((4, n))
    hx[0] = x0
    hq = np.zeros((4, nq))
    hq[0] = q0
    out_x = np.zeros((capacity, n))
    out_x[0] = x0
    return KernelState(
        fs=start_floats(),
        ints=start_counters(),
        ht=np.zeros(4),
        hx=hx,
        hq=hq,
        hi=np.zeros((2, nq)),
        x_prev_ext=np.append(x0, 0.0),
        **device_states(families),
        lu=lu,
        out_t=np.zeros(capacity),
        out_x=out_x,
        fail_x=np.zeros(n),
        fail_prev=np.zeros(n),
        terms=terminal_state(families["terminals"], plan.terms),
    )
