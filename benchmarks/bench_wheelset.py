"""Work-precision of the wheelset circuit: ngspice and our solver at several tolerances.

The circuit is the generated wheelset netlist (flange on, V = 55 m/s, f = 3 Hz, a = 0.040 m,
0-5 s) with exact resistor values, so that what separates a run from the ODE is the engine's
time discretization (plus the op-amps' finite gain), not E96 rounding. Accuracy is the %NRMSD
of y (mapped through the scale file) against the direct ODE solution at rtol 1e-11.
"""

from __future__ import annotations

import copy
from dataclasses import replace
from pathlib import Path

import numpy as np
from bench_common import best_of, simulate_subprocess, table

from circuitsim.compare.mapping import map_waveforms, resample
from circuitsim.compare.signals import nrmsd_percent
from circuitsim.interop.ngspice import run_ngspice
from circuitsim.mechanics import load_model, solve
from circuitsim.netlist.reader import read_netlist
from circuitsim.netlist.writer import save_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.options import SynthesisOptions

SCENARIO = {"V": 55.0, "f": 3.0, "a": 0.040}
T_STOP = 5.0
MATCHED = 0.1  # %NRMSD that counts as "matched accuracy"
# our engine's rows: the default ("builtin": kernel=auto, which runs the ports kernel on both
# circuits), the full compiled kernel, and the reference loop
KERNELS = {"builtin": "auto", "compiled": "compiled", "reference": "python"}
SPOT_CHECKS = ("compiled", "reference")  # run at reltol 1e-3 and two TMAX only


def reference(system) -> tuple[np.ndarray, np.ndarray]:
    """Dense grid over [0, 5] s and y on it from the direct solution (rtol 1e-11)."""
    result = solve(system, t_span=(0.0, T_STOP), rtol=1e-11, atol=1e-14)
    grid = np.linspace(0.0, T_STOP, 50_001)
    return grid, result.sol(grid)[0]


def variant(circuit, reltol: float, tmax: float, folder: Path, label: str) -> Path:
    """The netlist with ``.options reltol`` and ``.tran`` TMAX set, written for both engines."""
    changed = copy.deepcopy(circuit)
    changed.options = dict(changed.options, reltol=reltol)
    tran = changed.transient
    changed.analyses = [
        replace(tran, tmax=tmax, tstep=min(tran.tstep, tmax)) if a is tran else a
        for a in changed.analyses
    ]
    path = folder / f"{label}_reltol{reltol:g}_tmax{tmax:g}.cir"
    save_netlist(changed, path, "ngspice")
    return path


def warm_up(circuit) -> None:
    """One short run, so that the compiled kernel is loaded (numba's on-disk cache) before
    anything is timed; the whole-process column shows that cost."""
    short = copy.deepcopy(circuit)
    tran = short.transient
    short.analyses = [
        replace(tran, tstop=tran.tstop / 50) if a is tran else a for a in short.analyses
    ]
    simulate(short)


def ours(path: Path, kernel: str):
    """Our engine on the netlist at ``path`` (parsing included), with the given kernel."""
    circuit = read_netlist(path)
    return simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=kernel))


def accuracy(waves, scale_map, grid, y_ref) -> float:
    trace = map_waveforms(waves, scale_map, ["y"])["y"]
    return nrmsd_percent(y_ref, resample(trace, grid))


def run(folder: Path, quick: bool, log) -> dict:
    """Every engine x tolerance setting for the ideal and the TL074 circuit."""
    folder.mkdir(parents=True, exist_ok=True)
    model = load_model()
    system = model.system(parameters=SCENARIO, nonlinear={"flange": True})
    grid, y_ref = reference(system)
    reltols_ng = (1e-3, 1e-4, 1e-5, 1e-6)
    reltols_ours = reltols_ng if not quick else (1e-3,)
    reltols_reference = (1e-3,)
    opamps = ("ideal", "tl074")
    out: dict = {"cases": {}, "matched_nrmsd_percent": MATCHED}
    for opamp in opamps:
        generated = generate(
            system,
            folder / f"wheelset_{opamp}.cir",
            SynthesisOptions(opamp=opamp, series="exact", t_stop=T_STOP),
        )
        circuit, scale_map = generated.synthesis.circuit, generated.synthesis.scale_map
        tmax0 = circuit.transient.tmax
        tmaxes = (tmax0, 4 * tmax0, 8 * tmax0, 16 * tmax0) if not quick else (tmax0,)
        rows = []
        warm_up(circuit)
        engines = (
            ("ngspice", reltols_ng),
            ("builtin", reltols_ours),
            ("compiled", reltols_reference),
            ("reference", reltols_reference),
        )
        for engine, reltols in engines:
            for reltol in reltols:
                for tmax in tmaxes:
                    if engine in SPOT_CHECKS and tmax not in (tmax0, 8 * tmax0):
                        continue
                    path = variant(circuit, reltol, tmax, folder, f"wheelset_{opamp}")
                    row = {"engine": engine, "reltol": reltol, "tmax": tmax, "netlist": path.name}
                    if engine == "ngspice":
                        waves, seconds = best_of(run_ngspice, path, ["v(y)"])
                    else:
                        waves, seconds = best_of(ours, path, KERNELS[engine])
                    if isinstance(waves, Exception):
                        row.update(error=f"{type(waves).__name__}: {waves}", wall_s=seconds)
                        log(f"  {opamp} {engine} reltol={reltol:g} tmax={tmax:g}: FAILED {waves}")
                    else:
                        row.update(
                            wall_s=seconds,
                            solver_s=waves.stats.get("wall_time_s", seconds),
                            points=len(waves.time),
                            nrmsd_percent=accuracy(waves, scale_map, grid, y_ref),
                            newton_iterations=waves.stats.get("newton_iterations"),
                            kernel=waves.stats.get("kernel", "ngspice"),
                        )
                        log(
                            f"  {opamp} {engine} reltol={reltol:g} tmax={tmax:g}: "
                            f"{row['wall_s']:.3g} s, {row['nrmsd_percent']:.3g} %NRMSD"
                        )
                    rows.append(row)
        # whole-process time of ours at the netlist's own settings (default reltol)
        path = variant(circuit, 1e-3, tmax0, folder, f"wheelset_{opamp}")
        seconds, error = simulate_subprocess(path, "v(y)")
        out["cases"][opamp] = {
            "tmax_default": tmax0,
            "rows": rows,
            "builtin_process_s": seconds,
            "builtin_process_error": error,
            "summary": summarize(rows),
        }
    return out


def summarize(rows: list[dict]) -> dict:
    """Fastest run of each engine with %NRMSD <= MATCHED, and the ratio ours/ngspice."""
    best = {}
    for engine in ("ngspice", "builtin", *SPOT_CHECKS):
        good = [
            r
            for r in rows
            if r["engine"] == engine and "error" not in r and r["nrmsd_percent"] <= MATCHED
        ]
        best[engine] = min(good, key=lambda r: r["wall_s"]) if good else None
    ratio = ratio_reference = ratio_compiled = None
    if best["ngspice"] and best["builtin"]:
        ratio = best["builtin"]["wall_s"] / best["ngspice"]["wall_s"]
    if best["ngspice"] and best["reference"]:
        ratio_reference = best["reference"]["wall_s"] / best["ngspice"]["wall_s"]
    if best["ngspice"] and best["compiled"]:
        ratio_compiled = best["compiled"]["wall_s"] / best["ngspice"]["wall_s"]
    default = {
        e: next(
            (r for r in rows if r["engine"] == e and r["reltol"] == 1e-3 and "error" not in r),
            None,
        )
        for e in ("ngspice", "builtin")
    }
    ratio_default = None
    if default["ngspice"] and default["builtin"]:
        ratio_default = default["builtin"]["wall_s"] / default["ngspice"]["wall_s"]
    return {
        "best": best,
        "ratio_matched": ratio,
        "ratio_matched_reference": ratio_reference,
        "ratio_matched_compiled": ratio_compiled,
        "ratio_default_options": ratio_default,
    }


def report(data: dict) -> str:
    """Text tables of the work-precision runs."""
    parts = []
    for opamp, case in data["cases"].items():
        rows = [
            [
                _label(r),
                f"{r['reltol']:g}",
                f"{r['tmax'] * 1e6:.4g}",
                r.get("points"),
                r.get("wall_s"),
                r.get("solver_s"),
                r.get("nrmsd_percent"),
                r.get("error", ""),
            ]
            for r in case["rows"]
        ]
        parts.append(f"Wheelset ({opamp} op-amps), flange on, V = 55 m/s, 3 Hz, 0-5 s")
        parts.append(
            table(
                [
                    "engine",
                    "reltol",
                    "tmax (us)",
                    "points",
                    "wall (s)",
                    "solver (s)",
                    "%NRMSD y",
                    "failure",
                ],
                rows,
            )
        )
        s = case["summary"]
        best = s["best"]
        lines = [
            f"ours as a whole process (python -m circuitsim simulate, default options): "
            f"{case['builtin_process_s']:.3g} s"
            + (
                f" FAILED: {case['builtin_process_error']}" if case["builtin_process_error"] else ""
            ),
        ]
        for engine in ("ngspice", "builtin", *SPOT_CHECKS):
            b = best[engine]
            lines.append(
                f"fastest {engine} run with %NRMSD <= {data['matched_nrmsd_percent']}: "
                + (
                    f"reltol {b['reltol']:g}, tmax {b['tmax'] * 1e6:.4g} us, {b['wall_s']:.3g} s"
                    if b
                    else "none"
                )
            )
        ratio = s["ratio_matched"]
        lines.append(
            "time ratio ours/ngspice at matched accuracy: "
            + (f"{ratio:.3g}" if ratio is not None else "n/a (one engine never reached it)")
        )
        if s.get("ratio_matched_compiled") is not None:
            lines.append(
                f"the same for the full compiled kernel: {s['ratio_matched_compiled']:.3g}"
            )
        if s.get("ratio_matched_reference") is not None:
            lines.append(
                f"the same for the reference (python) loop: {s['ratio_matched_reference']:.3g}"
            )
        if s["ratio_default_options"] is not None:
            lines.append(
                f"time ratio ours/ngspice at default options (reltol 1e-3, netlist tmax): "
                f"{s['ratio_default_options']:.3g}"
            )
        parts.append("\n".join(lines))
    return "\n\n".join(parts)


def _label(row: dict) -> str:
    """Engine, and for ours the kernel that ran."""
    kernel = row.get("kernel")
    return row["engine"] + (f" ({kernel})" if kernel not in (None, "ngspice") else "")
