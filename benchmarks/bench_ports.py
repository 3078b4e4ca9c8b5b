"""Where the ports kernel's time goes, by ablation (part of bench_profile).

A compiled loop cannot be profiled by function, and its pieces are too small to time alone
(a 4 x 4 solve is ~0.1 us): instead the kernel (solver/compiled/time_loop.py, its steps in
port_steps.py and port_newton.py, the step control in step_control.py) is recompiled with one piece
switched off at a time, from patched copies of their source, and run on the same circuit.
The difference in time per step against the intact kernel is that piece's cost per step. A
switched-off piece changes the numbers (and slightly the steps), so the ablated runs are
timing instruments only; every patch must apply (else the part fails).
"""

from __future__ import annotations

import importlib
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import circuitsim.solver.compiled.port_newton as port_newton
import circuitsim.solver.compiled.port_steps as port_steps
import circuitsim.solver.compiled.step_control as step_control
import circuitsim.solver.compiled.time_loop as time_loop
from circuitsim.netlist.reader import read_netlist
from circuitsim.solver.compiled import newton as nw
from circuitsim.solver.compiled.plan import build_plan
from circuitsim.solver.compiled.port_state import initial_port_state
from circuitsim.solver.engine import build_system
from circuitsim.solver.transient import start_transient

# the modules a patch may change: the loop, the kernel's steps and its Newton steps, the step
# control
MODULES = {
    "time_loop": time_loop,
    "port_steps": port_steps,
    "port_newton": port_newton,
    "step_control": step_control,
}
_PIVOT = "        pivot_row = k"  # the elimination's first line, as in port_newton.solve_active
# piece -> [(module, source text, replacement)]
ABLATIONS = {
    "junction charges (depletion + diffusion, per iteration)": [
        ("port_newton", "charged_k = has_charge and charged[k]\n", "charged_k = False\n"),
    ],
    "truncation error (CKTterr over all charges, per step)": [
        ("step_control", "charges = truncation_step(", "charges = _no_truncation("),
        ("step_control", "charges2 = truncation_step(", "charges2 = _no_truncation("),
        (
            "step_control",
            "@njit(cache=False, _nrt=False, forceinline=True)\ndef judge_step(",
            "@njit(inline='always')\ndef _no_truncation(real, order, times, q, qdot, hq, hi, live):"
            "\n    return np.inf\n\n\n@njit(cache=False, _nrt=False, forceinline=True)\n"
            "def judge_step(",
        ),
        ("step_control", "zero_charge_step(real, order, times[0] - times[1])", "np.inf"),
        ("step_control", "zero_charge_step(real, 2, times[0] - times[1])", "np.inf"),
    ],
    "junction solve (active md x md system, per iteration)": [
        ("port_newton", "for k in range(m):\n" + _PIVOT, "for k in range(0):\n" + _PIVOT),
        ("port_newton", "for k in range(m - 1, -1, -1):", "for k in range(0):"),
    ],
}


def _load(folder: Path, name: str, patches) -> object:
    """The loop recompiled from patched copies of its modules (``tag_time_loop`` importing
    ``tag_port_steps``, ``tag_port_newton`` and ``tag_step_control``), uncached; every patch
    must apply once."""
    tag = f"ablated_{abs(hash(name)) % 10**8}"
    texts = {
        short: Path(module.__file__).read_text().replace("cache=True", "cache=False")
        for short, module in MODULES.items()
    }
    for short, old, new in patches:
        if texts[short].count(old) != 1:
            raise RuntimeError(
                f"bench_ports: patch for {name!r} does not apply once in {short}.py: {old!r}"
            )
        texts[short] = texts[short].replace(old, new)
    for short, text in texts.items():
        for other in MODULES:
            text = text.replace(f"circuitsim.solver.compiled.{other} ", f"{tag}_{other} ")
        (folder / f"{tag}_{short}.py").write_text(text)
    return importlib.import_module(f"{tag}_time_loop")


def _timed(module, system, rows, repeat: int = 3) -> tuple[float, int, int]:
    """Best kernel-only time (s) of ``repeat`` runs, accepted steps, Newton iterations; the
    time is NaN when the (ablated) run does not finish."""
    tran = system.circuit.transient
    best, steps, iterations = np.inf, 0, 0
    for _ in range(repeat + 1):  # the first compiles
        stats: dict = {}
        max_step, min_step, breaks, x, ctx0 = start_transient(
            system, tran.tstep, tran.tstop, tran.tstart, tran.tmax, tran.uic, stats
        )
        plan, families = build_plan(system, breaks, tran.tstop, max_step, min_step)
        capacity = int(4 * tran.tstop / max_step) + 1000
        st = initial_port_state(plan, families, x, ctx0.q.copy(), capacity, rows)
        st = st._replace(  # the slots of a return to Python (runner._loop_state's)
            fs=np.concatenate([st.fs, np.full(nw.RESUME_FLOATS, np.nan)]),
            ints=np.concatenate([st.ints, np.zeros(nw.RESUME_INTS, dtype=np.int64)]),
        )
        st.fs[nw.H] = min(tran.tstop / 100, tran.tstep) / 10
        st.fs[nw.SAVED_H] = tran.tstop / 50
        nw.factor_now(plan, st, 2.0 / max_step)
        started = time.perf_counter()
        status = module.run_ports(plan, st, 2 * tran.tstop)
        elapsed = time.perf_counter() - started
        if status != step_control.FINISHED:  # e.g. without the solve Newton may not converge
            return np.nan, int(st.ints[nw.ACCEPTED]), int(st.ints[nw.NEWTON])
        best = min(best, elapsed)
        steps, iterations = int(st.ints[nw.ACCEPTED]), int(st.ints[nw.NEWTON])
    return best, steps, iterations


def ablation(path: Path, log) -> dict:
    """The intact kernel and each ablation on the netlist at ``path``, recording v(y) only
    (as a sweep does) and every unknown (as a single run does)."""
    system = build_system(read_netlist(path), None)
    one = np.array([system.signals["v(y)"]])
    every = np.arange(system.size)
    out: dict = {"unknowns": system.size, "runs": {}}
    with tempfile.TemporaryDirectory(prefix="circuitsim-ablation-") as folder:
        sys.path.insert(0, folder)
        try:
            intact = _load(Path(folder), "intact", [])
            for label, rows in (("intact, v(y) recorded", one), ("intact, all recorded", every)):
                out["runs"][label] = _timed(intact, system, rows)
                log(f"    {label}: {out['runs'][label][0]:.3g} s")
            for name, patches in ABLATIONS.items():
                module = _load(Path(folder), name, patches)
                out["runs"][f"without {name}"] = _timed(module, system, one)
                log(f"    without {name}: {out['runs'][f'without {name}'][0]:.3g} s")
        finally:
            sys.path.remove(folder)
    return out


def report(name: str, data: dict) -> list[list]:
    """Rows: run, seconds, steps, iterations, us per step, difference to intact (us/step)."""
    runs = data["runs"]
    base_s, base_steps, _ = runs["intact, v(y) recorded"]
    base = base_s / base_steps * 1e6
    rows = []
    for label, (seconds, steps, iterations) in runs.items():
        per_step = seconds / steps * 1e6
        diff = "" if label.startswith("intact, v(y)") else f"{base - per_step:+.3g}"
        if not np.isfinite(seconds):
            diff = "n/a: the ablated run did not finish"
        if label.startswith("intact, all"):
            diff = f"{per_step - base:+.3g} (recording all)"
        rows.append([f"{name}: {label}", seconds, steps, iterations, f"{per_step:.3g}", diff])
    return rows
