"""The multi-terminal devices of the compiled MNA kernel: their plan and their state.

JFETs, BJTs and nonlinear POLY sources describe themselves in ``kernel_data()`` as
``{"kind": "terminals", ...}`` (keys below); :func:`terminal_plan` gathers all of them into
one :class:`TerminalPlan` (constant) and :func:`terminal_state` into one
:class:`TerminalState` (what Newton changes), the kernel's terminal form of
devices/terminals.py: element k has ``nterm[k]`` terminal rows and ``nctrl[k]`` controlling
voltages, and at each iteration its kernel twin (devices/jfet_kernel.py, bjt_kernel.py,
poly_kernel.py) writes the terminal currents ``cur`` and their slopes ``slope`` in the
controls at the linearization point ``vlin``. Its matrix entries -- for each terminal t and
control c, +slope at (row t, column c+) and -slope at (row t, column c-), then the four
entries of a modulated base resistance -- are the sparse LU's ``extra`` entries, from
``entry[k]`` on, in that order. Nothing here imports numba.

Keys of a family's terminal ``kernel_data``: ``model`` (one of MODELS), ``rows`` (m, T)
terminal rows, ``controls`` (m, C, 2) + and - node of each control (-1 ground), ``params``
(m, P) the model's columns, ``slots`` (m, 2) charge slots or None, ``tol`` the current
check's absolute tolerance, ``v_last`` (m, C) the limiting's last evaluation, ``slope``
(m, T, C) the last linearization's slopes or None (both for the first pivot order), for a
BJT ``rb`` (m,) bool (a modulated base resistance) and ``rb_g`` (m,) its start value, and for
POLY ``terms`` (owner, coefficient, power) of its term table.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

# kinds of element (poly_kernel.py's two outputs first)
POLY_CURRENT, POLY_VOLTAGE, JFET, BJT = 0, 1, 2, 3
MODELS = {"poly_current": POLY_CURRENT, "poly_voltage": POLY_VOLTAGE, "jfet": JFET, "bjt": BJT}
MAX_TERMINALS = 4  # rows per element: a BJT's collector', base', emitter' and outer base
RB_TERMINAL = 3  # the outer base node's column of ``rows`` (modulated RB)


class TerminalPlan(NamedTuple):
    """Constant data of the nd multi-terminal elements (C: most controls of any element)."""

    kind: np.ndarray  # (nd,) int64 POLY_CURRENT, POLY_VOLTAGE, JFET, BJT
    rows: np.ndarray  # (nd, MAX_TERMINALS) int64 terminal rows (-1: ground or none)
    nterm: np.ndarray  # (nd,) int64 terminals with currents
    ctrl: np.ndarray  # (nd, C, 2) int64 + and - node of each control (-1 ground)
    nctrl: np.ndarray  # (nd,) int64
    par: np.ndarray  # (nd, P) the model's parameters (jfet_kernel.PARAMS, bjt_kernel.PARAMS)
    slot: np.ndarray  # (nd, 2) int64 charge slots (-1: no charge)
    tol: np.ndarray  # (nd,) absolute tolerance of the current check (abstol, vntol)
    entry: np.ndarray  # (nd,) int64 first extra entry of each element
    rb: np.ndarray  # (nd,) bool: a modulated base resistance (four more entries)
    term_ptr: np.ndarray  # (nd + 1,) int64 POLY terms of element k: term_ptr[k]:term_ptr[k+1]
    term_coef: np.ndarray  # (nt,)
    term_pow: np.ndarray  # (nt, C) int64 exponents


class TerminalState(NamedTuple):
    """What the kernel's Newton changes (shapes as TerminalPlan's)."""

    v_last: np.ndarray  # (nd, C) the last evaluation's controls (limiting; n-type frame)
    vlin: np.ndarray  # (nd, C) controls of the linearization, circuit's frame, V
    cur: np.ndarray  # (nd, MAX_TERMINALS) currents into the element's terminals, A
    slope: np.ndarray  # (nd, MAX_TERMINALS, C) their slopes in the controls, S
    rb_g: np.ndarray  # (nd,) modulated base conductance at the present q_b, S


def _parts(parts: list[dict]) -> list[dict]:
    return [p for p in parts if p["kind"] == "terminals"]


def terminal_plan(parts: list[dict]) -> TerminalPlan:
    """The plan of every ``"terminals"`` part of the families' ``kernel_data``."""
    parts = _parts(parts)
    sizes = [len(p["rows"]) for p in parts]
    nd = sum(sizes)
    n_ctrl = max([np.shape(p["controls"])[1] for p in parts], default=0)
    n_par = max([np.shape(p["params"])[1] for p in parts], default=0)
    rows = -np.ones((nd, MAX_TERMINALS), dtype=np.int64)
    ctrl = -np.ones((nd, n_ctrl, 2), dtype=np.int64)
    kind, nterm, nctrl = (np.zeros(nd, dtype=np.int64) for _ in range(3))
    par = np.zeros((nd, n_par))
    slot = -np.ones((nd, 2), dtype=np.int64)
    tol = np.zeros(nd)
    rb = np.zeros(nd, dtype=bool)
    counts, coefs, powers = np.zeros(nd, dtype=np.int64), [], []
    start = 0
    for p, m in zip(parts, sizes, strict=True):
        here = slice(start, start + m)
        r = np.asarray(p["rows"], dtype=np.int64)
        c = np.asarray(p["controls"], dtype=np.int64)
        rows[here, : r.shape[1]] = r
        ctrl[here, : c.shape[1]] = c
        kind[here] = MODELS[p["model"]]
        nterm[here] = min(r.shape[1], 3)
        nctrl[here] = c.shape[1]
        params = np.asarray(p["params"], dtype=float)
        par[here, : params.shape[1]] = params
        if p["slots"] is not None:
            slot[here] = p["slots"]
        tol[here] = p["tol"]
        rb[here] = p.get("rb", np.zeros(m, dtype=bool))
        if "terms" in p:
            owner, coefficient, power = p["terms"]
            counts[here] = np.bincount(owner, minlength=m)
            coefs.append(np.asarray(coefficient, dtype=float))
            padded = np.zeros((len(owner), n_ctrl), dtype=np.int64)
            padded[:, : np.shape(power)[1]] = power
            powers.append(padded)
        start += m
    entries = 2 * nterm * nctrl + 4 * rb
    return TerminalPlan(
        kind=kind,
        rows=rows,
        nterm=nterm,
        ctrl=ctrl,
        nctrl=nctrl,
        par=par,
        slot=slot,
        tol=tol,
        entry=np.concatenate([[0], np.cumsum(entries)[:-1]]).astype(np.int64)[:nd],
        rb=rb,
        term_ptr=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        term_coef=np.concatenate(coefs) if coefs else np.zeros(0),
        term_pow=np.concatenate(powers) if powers else np.zeros((0, n_ctrl), dtype=np.int64),
    )


def terminal_state(parts: list[dict], tp: TerminalPlan) -> TerminalState:
    """The state at t = 0: the families' last evaluation (after the operating point)."""
    nd, n_ctrl = tp.ctrl.shape[:2]
    v_last = np.zeros((nd, n_ctrl))
    slope = np.zeros((nd, MAX_TERMINALS, n_ctrl))
    rb_g = np.zeros(nd)
    start = 0
    for p in _parts(parts):
        m = len(p["rows"])
        v = np.asarray(p["v_last"], dtype=float)
        v_last[start : start + m, : v.shape[1]] = v
        if p["slope"] is not None:
            s = np.asarray(p["slope"], dtype=float)
            slope[start : start + m, : s.shape[1], : s.shape[2]] = s
        if "rb_g" in p:
            rb_g[start : start + m] = p["rb_g"]
        start += m
    return TerminalState(
        v_last=v_last,
        vlin=np.zeros((nd, n_ctrl)),
        cur=np.zeros((nd, MAX_TERMINALS)),
        slope=slope,
        rb_g=rb_g,
    )


def entry_pattern(tp: TerminalPlan) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) of every extra entry, in the order of ``entry`` (-1: ground)."""
    rows, cols = [], []
    for k in range(tp.kind.size):
        for t in range(tp.nterm[k]):
            for c in range(tp.nctrl[k]):
                rows += [tp.rows[k, t]] * 2
                cols += [tp.ctrl[k, c, 0], tp.ctrl[k, c, 1]]
        if tp.rb[k]:
            outer, inner = tp.rows[k, RB_TERMINAL], tp.rows[k, 1]
            rows += [outer, inner, outer, inner]
            cols += [outer, inner, inner, outer]
    return np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64)


def entry_values(tp: TerminalPlan, ts: TerminalState) -> np.ndarray:
    """The extra entries' present values (what mna_terminals.stamp_terminals adds)."""
    values = []
    for k in range(tp.kind.size):
        for t in range(tp.nterm[k]):
            for c in range(tp.nctrl[k]):
                values += [ts.slope[k, t, c], -ts.slope[k, t, c]]
        if tp.rb[k]:
            g = ts.rb_g[k]
            values += [g, g, -g, -g]
    return np.array(values, dtype=float)
