"""Where the time of one builtin wheelset run goes (ideal and TL074 op-amps).

The ports kernel (what ``kernel="auto"`` runs on both circuits) by ablation: bench_ports.py.

Compiled code cannot be seen by cProfile, so the MNA kernel (``kernel="compiled"``) is taken
apart by hand: the fixed costs (parsing, assembly, operating point, plan, first pivot order)
are timed around their calls, and the kernel's pieces are timed one by one on the run's own
matrices (each piece called 20 000 times in a compiled loop). Multiplied by how often a run
calls them, they should add up to the kernel's measured time. The reference (python) loop is
profiled with cProfile as before.
"""

from __future__ import annotations

import cProfile
import io
import pstats
import time
from pathlib import Path

import bench_ports
import numpy as np
from bench_common import table
from bench_wheelset import SCENARIO, T_STOP
from numba import njit

from circuitsim.mechanics import load_model
from circuitsim.netlist.reader import read_netlist
from circuitsim.netlist.writer import save_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.compiled import mna_steps as tr
from circuitsim.solver.compiled import newton as nw
from circuitsim.solver.compiled import plan as kp
from circuitsim.solver.compiled import run_compiled
from circuitsim.solver.compiled.sparse_lu import assemble, lu_solve, refactor
from circuitsim.solver.compiled.sparse_order import analyse
from circuitsim.solver.dc import operating_point_solution
from circuitsim.solver.devices.diode_kernel import linearize_junction
from circuitsim.solver.engine import build_system
from circuitsim.solver.threads import single_threaded_blas
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.translator import synthesize

TOP = 15
CALLS = 20_000


@njit
def _time_sources(plan, t, k):
    total = 0.0
    rhs, values = np.empty(plan.rhs_const.size), np.empty(plan.src_kind.size)
    for i in range(k):
        tr.source_rhs(
            t + i * 1e-6,
            plan.rhs_const,
            plan.src_kind,
            plan.src_par,
            plan.src_dc,
            plan.pwl_start,
            plan.pwl_t,
            plan.pwl_v,
            plan.src_rows,
            plan.src_signs,
            rhs,
            values,
        )
        total += rhs[0]
    return total


@njit
def _time_junctions(plan, st, x, a0, k):
    """Junction evaluation as the loops do it (linearize_junction), one junction at a time."""
    x_ext = np.empty(x.size + 1)
    nw.extend(x, x_ext)
    total = 0.0
    for _ in range(k):
        for j in range(plan.jp.shape[0]):
            v = x_ext[plan.port_p[j]] - x_ext[plan.port_n[j]]
            _, _, cd, gd, _, _ = linearize_junction(
                plan.jp, plan.cp, j, v, v, plan.has_charge and plan.charged[j], a0, 0.0
            )
            total += cd - gd * v
    return total


@njit
def _time_assemble(lu, a0, gd, g_sw, k):
    for _ in range(k):
        assemble(lu.a_val, lu.g_val, lu.m_val, a0, lu.port_pos, gd, g_sw)
    return lu.a_val[0]


@njit
def _time_refactor(lu, k):
    bad = 0
    for _ in range(k):
        bad += refactor(lu.a_ptr, lu.a_row, lu.a_val, lu.l_ptr, lu.l_row, lu.l_val, lu.u_ptr,
                        lu.u_row, lu.u_val, lu.work, lu.redo, True) >= 0  # fmt: skip
    return bad


@njit
def _time_lu_solve(lu, b, x, k):
    for _ in range(k):
        lu_solve(lu.l_ptr, lu.l_row, lu.l_val, lu.u_ptr, lu.u_row, lu.u_val, lu.row_to,
                 lu.col_of, b, lu.work, x)  # fmt: skip
    return x[0]


def _per_call(function, *args) -> float:
    function(*args, 1)
    started = time.perf_counter()
    function(*args, CALLS)
    return (time.perf_counter() - started) / CALLS


def kernel_breakdown(path: Path) -> dict:
    """Fixed costs and per-call costs of the kernel's pieces for the netlist at ``path``."""
    times = {}
    started = time.perf_counter()
    circuit = read_netlist(path)
    times["parse"] = time.perf_counter() - started
    started = time.perf_counter()
    system = build_system(circuit, None)
    times["assemble"] = time.perf_counter() - started
    tran = circuit.transient
    with single_threaded_blas():
        started = time.perf_counter()
        x, ctx = operating_point_solution(system, dc_op=False, clamp_ic=True, stats={})
        times["operating point"] = time.perf_counter() - started
        max_step = tran.tmax
        started = time.perf_counter()
        plan, families = kp.build_plan(
            system, np.array([tran.tstop]), tran.tstop, max_step, 1e-11 * max_step
        )
        devices = kp.device_states(families)
        times["plan"] = time.perf_counter() - started
        a0 = 2.0 / max_step
        g_sw = np.where(devices["state"], plan.g_switch[:, 0], plan.g_switch[:, 1])
        started = time.perf_counter()
        lu = analyse(plan.G, plan.M, plan.port_p, plan.port_n,
                     np.concatenate([devices["gd"], g_sw]), a0)  # fmt: skip
        times["pivot order (SuperLU, Python)"] = time.perf_counter() - started
        st = kp.initial_state(plan, families, x, ctx.q.copy(), 1000, lu)
        rhs0, values = np.empty(plan.rhs_const.size), np.empty(plan.src_kind.size)
        tr.source_rhs(
            0.0,
            plan.rhs_const,
            plan.src_kind,
            plan.src_par,
            plan.src_dc,
            plan.pwl_start,
            plan.pwl_t,
            plan.pwl_v,
            plan.src_rows,
            plan.src_signs,
            rhs0,
            values,
        )
        pieces = {
            "sources (per attempt)": _per_call(_time_sources, plan, 0.0),
            "junction evaluation (per Newton iteration)": _per_call(
                _time_junctions, plan, st, x, a0
            ),
            "assembly into the sparse pattern (per Newton iteration)": _per_call(
                _time_assemble, lu, a0, st.gd, g_sw
            ),
            "numeric LU refactor (per Newton iteration)": _per_call(_time_refactor, lu),
            "triangular solves (per Newton iteration)": _per_call(
                _time_lu_solve, lu, rhs0, np.empty(x.size)
            ),
        }
        system = build_system(circuit, None)
        stats: dict = {}
        started = time.perf_counter()
        run_compiled(system, tran.tstep, tran.tstop, tran.tstart, tran.tmax, tran.uic, stats=stats)
        total = time.perf_counter() - started
    return {
        "unknowns": int(x.size),
        "junctions": int(plan.jp.shape[0]),
        "lu_entries": int(lu.a_row.size + lu.l_ptr[-1] + lu.u_ptr[-1]),
        "fixed_s": times,
        "piece_s": pieces,
        "run_compiled_s": total,
        "stats": {k: v for k, v in stats.items() if isinstance(v, int | float | str)},
        "factorizations": int(system.factorizations),
    }


def run(folder: Path, quick: bool, log) -> dict:
    folder.mkdir(parents=True, exist_ok=True)
    model = load_model()
    system = model.system(parameters=SCENARIO, nonlinear={"flange": True})
    t_stop = 1.0 if quick else T_STOP
    out: dict = {"t_stop": t_stop, "kernel": {}, "ports": {}}
    for opamp in ("ideal", "tl074"):
        circuit = synthesize(
            system, SynthesisOptions(series="exact", t_stop=t_stop, opamp=opamp)
        ).circuit
        path = folder / f"wheelset_{opamp}.cir"
        save_netlist(circuit, path, "ngspice")
        simulate(read_netlist(path))  # load the compiled code before timing
        out["kernel"][opamp] = kernel_breakdown(path)
        log(f"  {opamp}: kernel {out['kernel'][opamp]['run_compiled_s']:.3g} s")
        log(f"  {opamp}: ports kernel ablation")
        out["ports"][opamp] = bench_ports.ablation(path, log)
    circuit = read_netlist(folder / "wheelset_ideal.cir")
    options = SimulationOptions.from_circuit(circuit, kernel="python")
    profile = cProfile.Profile()
    profile.enable()
    waves = simulate(circuit, options)
    profile.disable()
    text = io.StringIO()
    stats = pstats.Stats(profile, stream=text)
    stats.sort_stats("tottime").print_stats(TOP)
    listing = text.getvalue()
    out["reference_total_s"] = stats.total_tt
    out["reference_stats"] = {k: v for k, v in waves.stats.items() if isinstance(v, int | float)}
    out["reference_top"] = listing[listing.index("   ncalls") :] if "   ncalls" in listing else ""
    return out


def report(data: dict) -> str:
    parts = []
    rows = []
    for opamp, ablation in data.get("ports", {}).items():
        rows += bench_ports.report(f"{opamp} ({ablation['unknowns']} unknowns)", ablation)
    if rows:
        parts.append(
            f"Ports kernel (kernel=auto), wheelset 0-{data['t_stop']:g} s, kernel time only "
            "(best of 3), by ablation: each piece switched off in turn; its cost per step is "
            "the difference to the intact kernel recording v(y)"
        )
        parts.append(
            table(
                ["run", "s", "steps", "Newton iterations", "us per step", "piece, us per step"],
                rows,
            )
        )
    for opamp, k in data["kernel"].items():
        s = k["stats"]
        steps = s["accepted"] + s["rejected"]
        iterations = s["newton_iterations"]
        piece = k["piece_s"]
        # how often each piece runs: per attempt, then per Newton iteration
        counts = [steps, iterations, iterations, iterations, iterations]
        rows = [
            [name, f"{seconds * 1e6:.3g}", count, f"{seconds * count:.3g}"]
            for (name, seconds), count in zip(piece.items(), counts, strict=True)
        ]
        estimate = sum(
            seconds * count for seconds, count in zip(piece.values(), counts, strict=True)
        )
        fixed = k["fixed_s"]
        parts.append(
            f"MNA kernel (kernel=compiled), wheelset ({opamp} op-amps), 0-{data['t_stop']:g} s: "
            f"{k['unknowns']} unknowns, {k['junctions']} junctions, {k['lu_entries']} "
            f"entries of A, L and U; {s['accepted']} steps, {s['rejected']} rejected, {iterations} "
            f"Newton iterations, {k['factorizations']} factorizations"
        )
        parts.append(
            "fixed costs (s): "
            + ", ".join(f"{name} {seconds:.3g}" for name, seconds in fixed.items())
        )
        parts.append(table(["piece", "us per call", "calls in the run", "s in the run"], rows))
        parts.append(
            f"sum of the pieces {estimate:.3g} s; run_compiled measured {k['run_compiled_s']:.3g}"
            " s (operating point and plan included; the rest is the loop's own bookkeeping:"
            " truncation error, history, output)"
        )
    r = data["reference_stats"]
    parts.append(
        f"Reference (python) loop, ideal op-amps, under cProfile: {data['reference_total_s']:.3g}"
        f" s, {r.get('accepted')} steps, {r.get('newton_iterations')} Newton iterations "
        f"(top {TOP} by own time)\n" + data["reference_top"].rstrip()
    )
    return "\n\n".join(parts)
