"""Batched speed sweep against one ngspice process per variant (2 at a time).

Throughput ratio = ngspice's wall time for all variants / ours for all variants (simulation
only; the shared translation is timed separately). Each variant's batched result is checked
against its own single builtin run (a few variants) and its peak |y| against ngspice's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from bench_common import table

from circuitsim.compare.mapping import map_waveforms, resample
from circuitsim.compare.sweep import parse_values, run_sweep, sweep_circuits
from circuitsim.mechanics import critical_speed, load_model
from circuitsim.solver import simulate
from circuitsim.synthesis.options import SynthesisOptions


def run(folder: Path, quick: bool, log) -> dict:
    values = parse_values("40:70:5" if quick else "40:70:0.5")
    t_stop = 1.0 if quick else 5.0
    model = load_model()
    systems = [
        model.system(parameters={"V": float(v), "f": 3.0, "a": 0.040}, nonlinear={"flange": True})
        for v in values
    ]
    options = SynthesisOptions(opamp="ideal", t_stop=t_stop)
    checked = sorted({0, len(values) // 2, len(values) - 1})

    def bar(fraction, message):
        if fraction >= 1.0 or int(fraction * 100) % 25 == 0:
            log(f"    {100 * fraction:5.1f}% {message}")

    log(f"  builtin batch: {len(values)} variants, {t_stop:g} s")
    ours = run_sweep(systems, values, "V", "m/s", "builtin", options, progress=bar, keep=checked)
    log(f"  ngspice: {len(values)} processes, 2 at a time")
    theirs = run_sweep(systems, values, "V", "m/s", "ngspice", options, workers=2, keep=checked)
    ours.critical, _ = critical_speed(model)
    singles = []
    circuits = sweep_circuits(systems, options)
    for k in checked:
        waves = simulate(circuits.circuits[k])
        single = map_waveforms(waves, circuits.scale_map, ["y"])["y"]
        grid = np.linspace(0.0, t_stop, 20_001)
        a, b = resample(ours.traces[k], grid), resample(single, grid)
        c = resample(theirs.traces[k], grid)
        singles.append(
            {
                "V": float(values[k]),
                "batch_vs_single_max_dev_over_range": float(np.max(np.abs(a - b)) / np.ptp(b)),
                "batch_vs_ngspice_max_dev_over_range": float(np.max(np.abs(a - c)) / np.ptp(c)),
                "single_s": waves.stats.get("wall_time_s"),
                "single_points": len(waves.time),
            }
        )
    rel = lambda x, y: float(np.max(np.abs(x - y) / np.maximum(np.abs(y), 1e-12)))  # noqa: E731
    data = {
        "values": values,
        "t_stop": t_stop,
        "variants": len(values),
        "changed": ours.changed,
        "builtin": {"timings": ours.timings, "stats": ours.stats},
        "ngspice": {"timings": theirs.timings, "stats": theirs.stats},
        "throughput_ratio": theirs.timings["simulation"] / ours.timings["simulation"],
        "peak_late_max_rel_diff": rel(ours.peak_late, theirs.peak_late),
        "peak_all_max_rel_diff": rel(ours.peak_all, theirs.peak_all),
        "single_checks": singles,
        "critical_speed": ours.critical,
    }
    from circuitsim.compare.sweep import save_sweep

    save_sweep(ours, folder, "sweep_builtin")
    theirs.critical = ours.critical
    save_sweep(theirs, folder, "sweep_ngspice")
    return data


def report(data: dict) -> str:
    b, n = data["builtin"], data["ngspice"]
    lines = [
        f"Speed sweep: {data['variants']} variants "
        f"(V = {data['values'][0]:g}..{data['values'][-1]:g} m/s), {data['t_stop']:g} s each, "
        "ideal op-amps, flange on; changed between variants: "
        f"{', '.join(data['changed'])}",
        table(
            ["engine", "simulation (s)", "per variant (s)", "shared translation (s)", "notes"],
            [
                [
                    "builtin, one batched run",
                    b["timings"]["simulation"],
                    b["timings"]["simulation"] / data["variants"],
                    b["timings"]["synthesis"],
                    f"{b['stats'].get('accepted')} shared steps, "
                    f"{b['stats'].get('newton_iterations')} Newton iterations",
                ],
                [
                    "ngspice, one process per variant, 2 at a time",
                    n["timings"]["simulation"],
                    n["timings"]["simulation"] / data["variants"],
                    n["timings"]["synthesis"],
                    f"{n['stats'].get('time_points')} time points in all",
                ],
            ],
        ),
        f"throughput ratio (ngspice time / batched time): {data['throughput_ratio']:.3g}"
        " (target >= 20)",
        f"peak |y| batched vs ngspice, max relative difference: last second "
        f"{data['peak_late_max_rel_diff']:.3g}, whole run {data['peak_all_max_rel_diff']:.3g}",
        table(
            ["V (m/s)", "batch vs single builtin", "batch vs ngspice", "single run (s)"],
            [
                [
                    s["V"],
                    s["batch_vs_single_max_dev_over_range"],
                    s["batch_vs_ngspice_max_dev_over_range"],
                    s["single_s"],
                ]
                for s in data["single_checks"]
            ],
        ),
        "(max |difference| of y over the run / range of y)",
    ]
    return "\n".join(lines)
