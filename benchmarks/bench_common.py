"""Shared helpers of the benchmark harness: timing, subprocess runs, tables, machine facts."""

from __future__ import annotations

import json
import math
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from circuitsim.atomic import write_text_atomic


def wall(function, *args, **kwargs):
    """(result, seconds) of one call; the exception instead of the result if it raised."""
    started = time.perf_counter()
    try:
        result = function(*args, **kwargs)
    except Exception as exc:  # noqa: BLE001 - a failing engine is a result to report
        result = exc
    return result, time.perf_counter() - started


REPEAT = [1]  # best of this many runs (set by run.py --repeat); the machine is shared


def best_of(function, *args, **kwargs):
    """(result, seconds): the fastest of REPEAT[0] calls (a failure is returned at once)."""
    best = None
    for _ in range(max(1, REPEAT[0])):
        result, seconds = wall(function, *args, **kwargs)
        if isinstance(result, Exception):
            return result, seconds
        if best is None or seconds < best[1]:
            best = (result, seconds)
    return best


def simulate_subprocess(netlist: Path, probe: str | None = None) -> tuple[float, str | None]:
    """Wall seconds of a whole ``python -m circuitsim simulate`` process, and its error."""
    with tempfile.TemporaryDirectory(prefix="circuitsim-bench-") as folder:
        command = [sys.executable, "-m", "circuitsim", "simulate", str(netlist)]
        command += ["--csv", str(Path(folder) / "out.csv")]
        if probe:
            command += ["--probe", probe]
        started = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True)
        seconds = time.perf_counter() - started
    error = None if done.returncode == 0 else (done.stderr.strip().splitlines() or ["?"])[-1]
    return seconds, error


def compile_bytecode() -> str:
    """Write circuitsim's bytecode (``__pycache__``), as ``pip install`` does, so that
    whole-process timings measure a process that loads it. Python writes it itself at a
    module's first import, unless PYTHONDONTWRITEBYTECODE is set, as it is on the 2-core VMs
    these figures come from: there every ``simulate`` process compiled all our modules from
    source (0.28 against 0.17 s for the ideal chain of 4, docs/performance.md section 6).
    Returns what was done, for machine.json."""
    import compileall
    import os

    import circuitsim

    package = Path(circuitsim.__file__).resolve().parent
    if not compileall.compile_dir(str(package), quiet=1):
        raise RuntimeError(f"compileall failed on {package}")
    flag = os.environ.get("PYTHONDONTWRITEBYTECODE")
    return f"compiled by compileall ({package}); PYTHONDONTWRITEBYTECODE={flag!r}"


def machine() -> dict:
    """nproc, CPU model, Python, numpy, scipy, numba and ngspice versions."""
    import numba
    import scipy

    cpu = "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    ngspice = "not installed"
    if shutil.which("ngspice"):
        done = subprocess.run(["ngspice", "-v"], capture_output=True, text=True)
        lines = [ln for ln in (done.stdout + done.stderr).splitlines() if "ngspice" in ln.lower()]
        ngspice = lines[0].strip(" *") if lines else "?"
    load = "?"
    try:
        load = Path("/proc/loadavg").read_text().split()[:3]
    except OSError:
        pass
    import os

    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"],
        capture_output=True,
        text=True,
        cwd=Path(__file__).parent,
    ).stdout.strip()
    return {
        "commit": commit or "?",
        "nproc": os.cpu_count(),
        "cpu": cpu,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "ngspice": ngspice,
        "load_average": load,
    }


def fmt(value, spec: str = ".3g") -> str:
    """A table cell: numbers formatted, None/NaN as '-', strings as they are."""
    if value is None:
        return "-"
    if isinstance(value, str):
        return value
    if isinstance(value, float) and math.isnan(value):
        return "-"
    return format(value, spec)


def table(headers: list[str], rows: list[list]) -> str:
    """A plain-text table (also valid markdown)."""
    cells = [[fmt(c) for c in row] for row in rows]
    widths = [
        max(len(h), *(len(r[i]) for r in cells)) if cells else len(h) for i, h in enumerate(headers)
    ]

    def line(items):
        return "| " + " | ".join(s.ljust(w) for s, w in zip(items, widths, strict=True)) + " |"

    rule = "|" + "|".join("-" * (w + 2) for w in widths) + "|"
    return "\n".join([line(headers), rule, *(line(r) for r in cells)])


def save(folder: Path, name: str, data: dict, markdown: str) -> None:
    """Write ``name.json`` and ``name.md`` into ``folder`` atomically."""
    folder.mkdir(parents=True, exist_ok=True)
    write_text_atomic(folder / f"{name}.json", json.dumps(data, indent=2, default=_plain) + "\n")
    write_text_atomic(folder / f"{name}.md", markdown + "\n")


def _plain(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    return str(value)
