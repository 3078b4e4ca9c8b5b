"""Speed sweep: builtin (each variant its own ports-kernel run, ``jobs`` threads) against one
ngspice process per variant, both ``jobs`` (the CPU count) at a time.

Throughput ratio = ngspice's wall time for all variants / ours for all variants (simulation
only; the shared translation is timed separately), each the best of ``run.py --repeat`` runs
(the machine is shared). numba's disk cache is warmed first in a separate process (the kernel's
one-off compilation, if the cache was stale, is timed there); run_sweep then loads the kernels
before it times the simulation. Each checked variant's sweep
trace is compared with simulating its Circuit alone here and with simulating its written
netlist; its peak |y| with ngspice's.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from bench_common import REPEAT, machine, table

from circuitsim.compare.mapping import map_waveforms, resample
from circuitsim.compare.sweep import run_sweep, sweep_circuits
from circuitsim.compare.sweep_plot import save_sweep
from circuitsim.compare.values import parse_values
from circuitsim.mechanics import critical_speed, load_model
from circuitsim.netlist.reader import parse_netlist
from circuitsim.netlist.writer import write_netlist
from circuitsim.solver import simulate
from circuitsim.synthesis.options import SynthesisOptions

_WARM_UP = (
    "from circuitsim.netlist.reader import parse_netlist\n"
    "from circuitsim.solver import simulate\n"
    "simulate(parse_netlist('* rc\\nR1 a 0 1k\\nC1 a 0 1u ic=1\\n.tran 1u 1m uic\\n.end\\n'))\n"
)


def _peaks(trace, window: float) -> tuple[float, float]:
    t, y = trace
    return float(np.max(np.abs(y[t >= t[-1] - window]))), float(np.max(np.abs(y)))


def _fastest(*args, **kwargs):
    """The run_sweep result of least simulation time of ``REPEAT[0]`` runs, and all times."""
    runs = [run_sweep(*args, **kwargs) for _ in range(max(1, REPEAT[0]))]
    times = [r.timings["simulation"] for r in runs]
    return runs[int(np.argmin(times))], times


def _commands(spec: str, t_stop: float, folder: Path, log) -> dict:
    """Wall time (s) of the whole ``circuitsim sweep`` command per engine, as a user runs it
    (a new process: start-up, imports, translation, kernels, simulation, CSV and plot): the
    best of ``REPEAT[0]`` runs each, alternating the engines."""
    times: dict[str, list[float]] = {"builtin": [], "ngspice": []}
    for _ in range(max(1, REPEAT[0])):
        for engine, runs in times.items():
            command = [sys.executable, "-m", "circuitsim", "sweep", "--param", "speed"]
            command += ["--values", spec, "--tstop", f"{t_stop:g}", "--engine", engine]
            command += ["--out", str(folder / f"command_{engine}")]
            started = time.perf_counter()
            subprocess.run(command, check=True, capture_output=True)
            runs.append(time.perf_counter() - started)
    log("  whole command: " + "; ".join(f"{k} {min(v):.3g} s" for k, v in times.items()))
    return {"spec": spec, "wall_s": times, "best_s": {k: min(v) for k, v in times.items()}}


def run(folder: Path, quick: bool, log) -> dict:
    spec = "40:70:5" if quick else "40:70:0.5"
    values = parse_values(spec)
    t_stop = 1.0 if quick else 5.0
    jobs = os.cpu_count() or 1
    model = load_model()
    systems = [
        model.system(parameters={"V": float(v), "f": 3.0, "a": 0.040}, nonlinear={"flange": True})
        for v in values
    ]
    options = SynthesisOptions(opamp="ideal", t_stop=t_stop)
    checked = sorted({0, len(values) // 4, len(values) // 2, len(values) - 1})

    def bar(fraction, message):
        if fraction >= 1.0 or int(fraction * 100) % 25 == 0:
            log(f"    {100 * fraction:5.1f}% {message}")

    commit = machine()["commit"]
    dirty = subprocess.run(
        ["git", "status", "--porcelain", "--", "circuitsim"], capture_output=True, text=True
    ).stdout.strip()
    started = time.perf_counter()
    subprocess.run([sys.executable, "-c", _WARM_UP], check=True)
    warm_up = time.perf_counter() - started
    log(f"  kernel cache warm-up (separate process): {warm_up:.3g} s")
    log(f"  builtin: {len(values)} variants, {t_stop:g} s, {jobs} at a time")
    ours, ours_times = _fastest(
        systems, values, "V", "m/s", "builtin", options, workers=jobs, progress=bar, keep=checked
    )
    log("  builtin, 1 at a time (in this process)")
    serial, serial_times = _fastest(systems, values, "V", "m/s", "builtin", options, workers=1)
    log(f"  ngspice: {len(values)} processes, {jobs} at a time")
    theirs, theirs_times = _fastest(
        systems, values, "V", "m/s", "ngspice", options, workers=jobs, progress=bar, keep=checked
    )
    ours.critical, _ = critical_speed(model)
    circuits = sweep_circuits(systems, options)
    singles = []
    for k in checked:
        alone = simulate(circuits.circuits[k])
        single = map_waveforms(alone, circuits.scale_map, ["y"])["y"]
        text = write_netlist(circuits.circuits[k])
        from_text = map_waveforms(simulate(parse_netlist(text)), circuits.scale_map, ["y"])["y"]
        text_peaks = _peaks(from_text, ours.window)
        grid = np.linspace(0.0, t_stop, 20_001)
        a, c = resample(ours.traces[k], grid), resample(theirs.traces[k], grid)
        same = bool(
            len(single[0]) == len(ours.traces[k][0])
            and np.array_equal(single[0], ours.traces[k][0])
            and np.max(np.abs(single[1] - ours.traces[k][1])) <= 1e-12 * np.ptp(single[1])
        )
        singles.append(
            {
                "V": float(values[k]),
                "same_as_single_run": same,
                "peak_late_rel_diff_vs_netlist_run": abs(ours.peak_late[k] / text_peaks[0] - 1),
                "peak_all_rel_diff_vs_netlist_run": abs(ours.peak_all[k] / text_peaks[1] - 1),
                "sweep_vs_ngspice_max_dev_over_range": float(np.max(np.abs(a - c)) / np.ptp(c)),
                "single_s": alone.stats.get("wall_time_s"),
                "single_points": len(alone.time),
            }
        )
    rel = lambda x, y: float(np.max(np.abs(x - y) / np.maximum(np.abs(y), 1e-12)))  # noqa: E731
    data = {
        "values": values,
        "t_stop": t_stop,
        "variants": len(values),
        "jobs": jobs,
        "changed": ours.changed,
        "commit": commit + (" + uncommitted circuitsim changes" if dirty else ""),
        "load_average_after": list(os.getloadavg()),
        "kernel_warm_up_s": warm_up,
        "repeat": max(1, REPEAT[0]),
        "simulation_times_s": {
            "builtin": ours_times,
            "builtin_serial": serial_times,
            "ngspice": theirs_times,
        },
        "builtin": {"timings": ours.timings, "stats": ours.stats},
        "builtin_serial": {"timings": serial.timings, "stats": serial.stats},
        "ngspice": {"timings": theirs.timings, "stats": theirs.stats},
        "throughput_ratio": theirs.timings["simulation"] / ours.timings["simulation"],
        "serial_identical": bool(
            np.array_equal(serial.peak_all, ours.peak_all)
            and np.array_equal(serial.peak_late, ours.peak_late)
        ),
        "peak_late_max_rel_diff": rel(ours.peak_late, theirs.peak_late),
        "peak_all_max_rel_diff": rel(ours.peak_all, theirs.peak_all),
        "single_checks": singles,
        "critical_speed": ours.critical,
    }
    data["tl074"] = _tl074(systems, values, t_stop, jobs, bar, log)
    data["commands"] = _commands(spec, t_stop, folder, log)
    save_sweep(ours, folder, "sweep_builtin")
    theirs.critical = ours.critical
    save_sweep(theirs, folder, "sweep_ngspice")
    return data


def _tl074(systems, values, t_stop, jobs, bar, log) -> dict:
    """The same sweep with the TL074 macromodel (every state node probed: its swing is
    checked), builtin against ngspice, both ``jobs`` at a time."""
    options = SynthesisOptions(opamp="tl074", t_stop=t_stop)
    log(f"  tl074 builtin: {len(values)} variants, {jobs} at a time")
    ours, ours_times = _fastest(
        systems, values, "V", "m/s", "builtin", options, workers=jobs, progress=bar
    )
    log(f"  tl074 ngspice: {len(values)} processes, {jobs} at a time")
    theirs, theirs_times = _fastest(
        systems, values, "V", "m/s", "ngspice", options, workers=jobs, progress=bar
    )
    rel = np.abs(ours.peak_all / theirs.peak_all - 1)
    return {
        "simulation_times_s": {"builtin": ours_times, "ngspice": theirs_times},
        "builtin": {"timings": ours.timings, "stats": ours.stats, "warnings": ours.warnings},
        "ngspice": {"timings": theirs.timings, "stats": theirs.stats},
        "throughput_ratio": theirs.timings["simulation"] / ours.timings["simulation"],
        "peak_all_max_rel_diff": float(np.max(rel)),
    }


def report(data: dict) -> str:
    b, s, n = data["builtin"], data["builtin_serial"], data["ngspice"]
    jobs, count = data["jobs"], data["variants"]

    def row(label, run, notes):
        sim = run["timings"]["simulation"]
        return [label, sim, sim / count, run["timings"]["synthesis"], notes]

    steps = f"{b['stats'].get('accepted')} steps, {b['stats'].get('newton_iterations')} Newton"
    lines = [
        f"Speed sweep: {count} variants "
        f"(V = {data['values'][0]:g}..{data['values'][-1]:g} m/s), {data['t_stop']:g} s each, "
        "ideal op-amps, flange on; changed between variants: "
        f"{', '.join(data['changed'])}; at commit {data['commit']}",
        table(
            ["engine", "simulation (s)", "per variant (s)", "shared translation (s)", "notes"],
            [
                row(
                    f"builtin, one run per variant, {jobs} threads",
                    b,
                    f"{steps} iterations in all; kernel {', '.join(b['stats']['kernels'])}",
                ),
                row(
                    "builtin, one run per variant, 1 thread",
                    s,
                    "peaks identical to the threaded run's"
                    if data["serial_identical"]
                    else "peaks DIFFER from the threaded run's",
                ),
                row(
                    f"ngspice, one process per variant, {jobs} at a time",
                    n,
                    f"{n['stats'].get('time_points')} time points in all",
                ),
            ],
        ),
        f"throughput ratio (ngspice time / builtin time, {jobs} at a time each): "
        f"{data['throughput_ratio']:.3g} (target >= 20)",
        f"simulation times: best of {data['repeat']} runs (all: "
        + "; ".join(
            f"{k} {', '.join(f'{t:.3g}' for t in v)}" for k, v in data["simulation_times_s"].items()
        )
        + " s). Builtin times exclude making the compiled kernels ready (run_sweep does it "
        "before timing: loaded from numba's disk cache, warmed beforehand in a separate "
        f"process, {data['kernel_warm_up_s']:.3g} s; that compiles only if the kernel changed)",
        f"peak |y| builtin vs ngspice, max relative difference: last second "
        f"{data['peak_late_max_rel_diff']:.3g}, whole run {data['peak_all_max_rel_diff']:.3g}",
        table(
            [
                "V (m/s)",
                "same steps as single run, values within 1e-12 of range",
                "peak rel. diff vs netlist run (last s, all)",
                "sweep vs ngspice",
                "single run (s)",
            ],
            [
                [
                    c["V"],
                    "yes" if c["same_as_single_run"] else "NO",
                    f"{c['peak_late_rel_diff_vs_netlist_run']:.3g}, "
                    f"{c['peak_all_rel_diff_vs_netlist_run']:.3g}",
                    c["sweep_vs_ngspice_max_dev_over_range"],
                    c["single_s"],
                ]
                for c in data["single_checks"]
            ],
        ),
        "(single run: simulate() on the variant's Circuit in this process; netlist run: on its "
        "written and re-read netlist; sweep vs ngspice: max |difference| of y / range of y)",
    ]
    c = data.get("commands")
    if c:
        best = c["best_s"]
        lines += [
            "",
            f"The whole command, `circuitsim sweep --param speed --values {c['spec']} --tstop "
            f"{data['t_stop']:g} --engine E` in a new process (start-up, imports, translation, "
            "kernels, simulation, CSV and plot), best of "
            f"{len(c['wall_s']['builtin'])}: builtin {best['builtin']:.3g} s, ngspice "
            f"{best['ngspice']:.3g} s ({best['ngspice'] / best['builtin']:.3g}x; all: "
            + "; ".join(f"{k} {', '.join(f'{x:.3g}' for x in v)}" for k, v in c["wall_s"].items())
            + " s)",
        ]
    t = data.get("tl074")
    if t:
        lines += [
            "",
            "The same sweep with TL074 op-amps (4 state nodes probed, for the swing check):",
            table(
                ["engine", "simulation (s)", "per variant (s)", "notes"],
                [
                    [
                        f"builtin, {jobs} threads",
                        t["builtin"]["timings"]["simulation"],
                        t["builtin"]["timings"]["simulation"] / count,
                        f"{t['builtin']['stats'].get('accepted')} steps in all; "
                        f"{len(t['builtin']['warnings'])} swing warnings",
                    ],
                    [
                        f"ngspice, {jobs} at a time",
                        t["ngspice"]["timings"]["simulation"],
                        t["ngspice"]["timings"]["simulation"] / count,
                        f"{t['ngspice']['stats'].get('time_points')} time points in all",
                    ],
                ],
            ),
            f"throughput ratio: {t['throughput_ratio']:.3g}; peak |y| builtin vs ngspice, max "
            f"relative difference {t['peak_all_max_rel_diff']:.3g}; simulation times: best of "
            f"{data['repeat']} (all: "
            + "; ".join(
                f"{k} {', '.join(f'{x:.3g}' for x in v)}"
                for k, v in t["simulation_times_s"].items()
            )
            + " s)",
        ]
    return "\n".join(lines)
