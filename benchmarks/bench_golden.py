"""The solver's golden netlists (tests/solver/golden): time against ngspice, max deviation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from bench_common import best_of, simulate_subprocess, table

from circuitsim.interop.ngspice import run_ngspice
from circuitsim.netlist.reader import read_netlist
from circuitsim.solver import simulate

GOLDEN = Path(__file__).resolve().parent.parent / "tests" / "solver" / "golden"


def deviation(ours, theirs, kinds=("v(", "i(")) -> tuple[float, str]:
    """Largest max|ours - ngspice| / range(ngspice) over common signals, on ngspice's times."""
    worst, name = 0.0, ""
    for signal in theirs.names:
        if signal not in ours or not signal.startswith(kinds):
            continue
        reference = theirs[signal]
        span = float(np.ptp(reference))
        # a signal that stays within the engines' absolute tolerances (a control source's
        # current of 1e-15 A) has no meaningful range to compare against
        if span < (1e-9 if signal.startswith("i(") else 1e-6):
            continue
        value = np.interp(theirs.time, ours.time, ours[signal])
        d = float(np.max(np.abs(value - reference))) / span
        if d > worst:
            worst, name = d, signal
    return worst, name


def run(folder: Path, quick: bool, log) -> dict:
    """Each golden netlist at its own options (they set reltol 1e-6)."""
    rows = []
    for path in sorted(GOLDEN.glob("*.cir")):
        row: dict = {"netlist": path.name}
        theirs, t_ng = best_of(run_ngspice, path)
        ours, t_ours = best_of(lambda p=path: simulate(read_netlist(p)))
        process, error = simulate_subprocess(path)
        row.update(ngspice_s=t_ng, builtin_s=t_ours, builtin_process_s=process)
        if isinstance(theirs, Exception):
            row["error"] = f"ngspice: {theirs}"
        elif isinstance(ours, Exception):
            row["error"] = f"builtin: {type(ours).__name__}: {ours}"
        else:
            row["ngspice_s"] = theirs.stats.get("wall_time_s", t_ng)
            row["ratio"] = t_ours / row["ngspice_s"]
            row["ratio_process"] = process / row["ngspice_s"]
            row["max_deviation"], row["worst_signal"] = deviation(ours, theirs)
            row["max_deviation_v"], _ = deviation(ours, theirs, ("v(",))
            row["points_ours"], row["points_ngspice"] = len(ours.time), len(theirs.time)
        if error:
            row["process_error"] = error
        log(
            f"  {path.name}: ours {t_ours:.3g} s, ngspice {row['ngspice_s']:.3g} s"
            + (f", FAILED {row['error']}" if "error" in row else "")
        )
        rows.append(row)
    return {"rows": rows}


def report(data: dict) -> str:
    rows = [
        [
            r["netlist"],
            r.get("ngspice_s"),
            r.get("builtin_s"),
            r.get("builtin_process_s"),
            r.get("ratio"),
            r.get("ratio_process"),
            r.get("max_deviation_v"),
            r.get("max_deviation"),
            r.get("worst_signal", ""),
            r.get("error", r.get("process_error", "")),
        ]
        for r in data["rows"]
    ]
    headers = [
        "netlist",
        "ngspice (s)",
        "ours in-process (s)",
        "ours process (s)",
        "ratio",
        "ratio (process)",
        "max dev / range, v()",
        "max dev / range, all",
        "worst signal (all)",
        "failure",
    ]
    return "Golden netlists (tests/solver/golden, their own .options)\n" + table(headers, rows)
