"""Which compiled kernel is faster where: the measurements behind ``kernel="auto"``.

The scaling benchmark's circuits (chains of N masses with a dead-zone contact on each, and the
wheelset; ideal and TL074 op-amps; bench_scaling.py) run in-process on the ports kernel and on
the MNA kernel, interleaved, each the best of ``--repeat`` rounds (at least 2) of CPU time
(user + system of this process: a loaded machine disturbs it far less than wall time). The
table says which kernel ``auto`` chose (circuitsim.solver.compiled.runner.auto_kernel, from the
number of junctions with charge) and which one was faster, so a wrong choice shows as a row
where they differ. With ``bench_scaling.FAMILY = "lattice"`` (``run.py --family lattice``) the
cases are the lattices of :mod:`circuitsim.mechanics.lattice` instead (no wheelset).
"""

from __future__ import annotations

import time
from pathlib import Path

import bench_scaling
from bench_common import REPEAT, table
from bench_scaling import family_case, wheelset_case

from circuitsim.netlist.reader import read_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.compiled.runner import auto_kernel, switching_junctions
from circuitsim.solver.compiled.warmup import warm_up
from circuitsim.solver.engine import build_system

SIZES = {"ideal": (1, 2, 4, 8), "tl074": (1, 2, 4)}
QUICK_SIZES = {"ideal": (1, 4), "tl074": (1,)}
LATTICE_SIZES = {"ideal": (1, 2, 4, 8, 16, 32), "tl074": (1, 2, 4, 8)}
KERNELS = ("ports", "compiled")


def cpu_seconds(circuit, kernel: str) -> tuple[float, dict]:
    """CPU seconds of one ``simulate()`` on ``kernel``, and its stats."""
    options = SimulationOptions.from_circuit(circuit, kernel=kernel)
    started = time.process_time()
    waves = simulate(circuit, options)
    return time.process_time() - started, waves.stats


def measure(case: dict, log) -> dict:
    """Both kernels on one case, interleaved rounds; the best CPU time of each."""
    circuit = read_netlist(case["netlist"])
    system = build_system(circuit, SimulationOptions.from_circuit(circuit))
    row = {"label": case["label"], "opamp": case["opamp"], "auto": auto_kernel(system),
           "charged_junctions": switching_junctions(system)}  # fmt: skip
    best = {kernel: None for kernel in KERNELS}
    for _ in range(max(2, REPEAT[0])):
        for kernel in KERNELS:
            seconds, stats = cpu_seconds(circuit, kernel)
            if best[kernel] is None or seconds < best[kernel]:
                best[kernel] = seconds
            row[f"{kernel}_steps"] = stats.get("accepted")
    row.update({f"{kernel}_cpu_s": best[kernel] for kernel in KERNELS})
    row["faster"] = min(KERNELS, key=lambda k: best[k])
    row["ports_over_compiled"] = best["ports"] / best["compiled"]
    log(
        f"  {row['label']} ({row['opamp']}): ports {best['ports']:.3g} s, compiled "
        f"{best['compiled']:.3g} s CPU; auto chose {row['auto']}"
    )
    return row


def run(folder: Path, quick: bool, log) -> dict:
    """Every case on both kernels."""
    folder.mkdir(parents=True, exist_ok=True)
    log(f"  kernels ready in {warm_up(('ports', 'compiled')):.3g} s")
    cases = []
    family = bench_scaling.FAMILY
    chosen = QUICK_SIZES if quick else SIZES if family == "chain" else LATTICE_SIZES
    for opamp, sizes in chosen.items():
        for masses in sizes:
            cases.append(measure(family_case(masses, opamp, folder, family), log))
        if family == "chain":
            cases.append(measure(wheelset_case(opamp, folder), log))
    return {"repeat": max(2, REPEAT[0]), "cases": cases}


def report(data: dict) -> str:
    """The table: CPU time on each kernel, auto's choice, the faster one."""
    headers = ["case", "op-amps", "charged junctions", "ports CPU (s)", "compiled CPU (s)",
               "ports / compiled", "auto chose", "faster"]  # fmt: skip
    rows = [
        [c["label"], c["opamp"], c["charged_junctions"], c["ports_cpu_s"], c["compiled_cpu_s"],
         c["ports_over_compiled"], c["auto"], c["faster"]]
        for c in data["cases"]
    ]  # fmt: skip
    title = (
        f"Kernel choice: CPU time of simulate() on each compiled kernel, best of "
        f"{data['repeat']} interleaved rounds; 'auto chose': runner.auto_kernel"
    )
    return title + "\n" + table(headers, rows)
