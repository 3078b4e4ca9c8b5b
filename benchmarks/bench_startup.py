"""Whole-process start-up: ``circuitsim simulate`` of the wheelset against ``ngspice -b``.

    python benchmarks/bench_startup.py [--repeat N] [--no-ngspice]
    python benchmarks/bench_startup.py --against DIR [--repeat N]
    python benchmarks/run.py --parts startup [--repeat N]

Four tables, every figure the median of ``--repeat`` fresh processes (CPU = user + system time
of the process, from ``os.wait4``; on a shared machine CPU is the steadier figure, wall time
includes waiting for a core):

1. whole processes on the same netlists: ``python -m circuitsim simulate FILE --csv OUT``
   against ``ngspice -b -r OUT.raw FILE`` (its binary rawfile: ngspice's output);
2. where our process's time goes: interpreter start, imports, reading the netlist, the first
   run's extra (numba loading the cached machine code, first calls), the solve, the CSV, the
   interpreter's shutdown (ended as ``circuitsim.cli.run`` ends it: ``gc.freeze()`` first);
3. the floor any process of this design pays before it does work: the interpreter, numpy (and
   the submodules of numpy that scipy.sparse's array-API layer imports),
   scipy.sparse and scipy.linalg (MnaSystem's matrices, LAPACK), numba, and loading one small
   cached kernel (numba's runtime); then the same kernel from the start-up library instead
   (solver/jit.py: no numba). The processes of tables 2 and 3 start OpenBLAS on one thread,
   as ``circuitsim.cli.run`` starts a process (``cli.blas_threads``);
4. peak memory (GNU time's ``%M``, see :func:`run_process`) of a 50 s TL074 run, every signal
   against ``--probe``.

Every process runs this checkout (PYTHONPATH) with Python's bytecode cache on, in a folder of
its own (PYTHONPYCACHEPREFIX, warmed by an untimed run first), as an installed package has it;
one row shows the ideal wheelset without it (a copy of the package without ``__pycache__``,
PYTHONDONTWRITEBYTECODE=1: every module of ours compiled from source at each start). The numba
kernels must be in the user cache (an untimed run first makes sure).

``--against DIR``: instead, whole ``simulate`` processes of this checkout and of the checkout in
DIR (an earlier commit, e.g. ``git archive REV | tar -x -C DIR``), interleaved one by one so
that both see the same load; the machine's load average is printed before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))

from bench_common import table  # noqa: E402

NETLISTS = {
    "ideal": REPO / "netlists" / "wheelset_flange_ideal_ngspice.cir",
    "tl074": REPO / "netlists" / "wheelset_flange_tl074_ngspice.cir",
}
REPEAT = [5]
MEMORY_TSTOP = 50.0  # s: the long TL074 run of the memory table
MEMORY_PROBES = ["v(y)", "v(psi)", "v(y_dot)", "v(psi_dot)"]  # the scale file's four states

# Run in a fresh process: the phases of `circuitsim simulate FILE --csv OUT`, as CPU seconds.
PHASES = r"""
import resource, sys, json
def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime
marks = [("interpreter", cpu())]
import circuitsim.cli, circuitsim.cli.netlist_verbs
from circuitsim.netlist.reader import read_netlist
from circuitsim.solver import SimulationOptions, simulate
import circuitsim.solver.compiled.runner, circuitsim.solver.compiled.time_loop
import circuitsim.solver.float_text
marks.append(("imports", cpu()))
circuit = read_netlist(sys.argv[1])
marks.append(("read netlist", cpu()))
waves = simulate(circuit, SimulationOptions.from_circuit(circuit))
marks.append(("first run", cpu()))
waves = simulate(circuit, SimulationOptions.from_circuit(circuit))
marks.append(("solve", cpu()))
waves.to_csv(sys.argv[2])
marks.append(("first CSV", cpu()))
waves.to_csv(sys.argv[2])
marks.append(("write CSV", cpu()))
print(json.dumps(marks), flush=True)
import gc
gc.freeze()  # as circuitsim.cli.run ends a process: the shutdown's collections skip all
"""

# The floor: what a process pays before it does any work (progressively more imported),
# each ended as circuitsim.cli.run ends a process.
END = "import gc\ngc.freeze()"
FLOOR = {
    "interpreter (python -c pass)": "pass",
    "+ numpy": "import numpy",
    "+ numpy's lazy submodules (f2py, testing, ma, polynomial, random)": (
        "import numpy, numpy.f2py, numpy.testing, numpy.ma, numpy.polynomial, numpy.random"
    ),  # what scipy.sparse's array-API layer imports (it getattr's every name of numpy)
    "+ scipy.sparse, scipy.linalg": "import numpy, scipy.sparse, scipy.linalg",
    "+ numba": "import numpy, scipy.sparse, scipy.linalg, numba",
    "+ one small cached kernel loaded by numba (float_text)": (
        "import os, numpy, scipy.sparse, scipy.linalg\n"
        "os.environ['CIRCUITSIM_NO_STARTUP_LIBRARY'] = '1'\n"
        "from circuitsim.solver.float_text import table_text\n"
        "table_text(numpy.zeros((1, 1)))"
    ),
    "numpy, scipy.sparse, scipy.linalg, the same kernel from the start-up library (no numba)": (
        "import os, numpy, scipy.sparse, scipy.linalg\n"
        "os.environ['CIRCUITSIM_NO_STARTUP_LIBRARY'] = '0'\n"
        "from circuitsim.solver.float_text import table_text\n"
        "table_text(numpy.zeros((1, 1)))\n"
        "import sys\n"
        "assert 'numba' not in sys.modules, 'no start-up library: run a simulate first'"
    ),
}


def run_process(command: list[str], env: dict, cwd: Path | None = None) -> dict:
    """One process to its end: CPU (user + system), wall, peak RSS (MB; None without GNU
    time), exit code, output.

    The peak is GNU time's (``%M``) of the command it starts: ``os.wait4``'s ``ru_maxrss``
    of a child of this process starts from this process's own RSS at the fork (about 146 MB
    here, whatever the child does), so a small process cannot show its peak that way. CPU is
    wait4's of the GNU time process, which counts the command it waited for (and GNU time's
    own, about a millisecond)."""
    import time

    gnu_time = shutil.which("time")
    with tempfile.TemporaryFile() as out, tempfile.TemporaryDirectory() as folder:
        peak_file = Path(folder) / "peak_kb"
        wrapped = [gnu_time, "-f", "%M", "-o", str(peak_file), *command] if gnu_time else command
        started = time.perf_counter()
        process = subprocess.Popen(
            wrapped, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env,
            cwd=cwd,
        )  # fmt: skip
        _, status, usage = os.wait4(process.pid, 0)
        wall = time.perf_counter() - started
        process.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        text = out.read().decode(errors="replace")
        peak = _peak_mb(peak_file) if gnu_time else None
    return {
        "cpu_s": usage.ru_utime + usage.ru_stime,
        "wall_s": wall,
        "peak_mb": peak,
        "code": process.returncode,
        "output": text,
    }


def _peak_mb(path: Path) -> float | None:
    """GNU time's ``%M`` (KB) from its output file, in MB (None if it wrote none)."""
    try:
        lines = path.read_text().split()
    except OSError:
        return None
    return int(lines[-1]) / 1024 if lines and lines[-1].isdigit() else None


def environment(pycache: Path | None, checkout: Path = REPO) -> dict:
    """``checkout`` (default this one) first on the path; the bytecode cache in ``pycache``
    (None: none written, and read only where it exists beside the sources)."""
    env = dict(os.environ)
    path = [str(checkout), env.get("PYTHONPATH", "")]
    env["PYTHONPATH"] = os.pathsep.join(path).rstrip(os.pathsep)
    if pycache is None:
        env["PYTHONDONTWRITEBYTECODE"] = "1"
        env.pop("PYTHONPYCACHEPREFIX", None)
    else:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(pycache)
    return env


def as_cli(env: dict) -> dict:
    """``env`` as ``circuitsim.cli.run`` sets it for its process: OpenBLAS on one thread
    unless the environment says otherwise (cli.blas_threads), for the processes that
    measure parts of a simulate process without its entry point."""
    return {"OPENBLAS_NUM_THREADS": "1", **env}


def median_of(runs: list[dict], key: str) -> float | None:
    """The median of ``key`` over ``runs``; None when a run has none (no GNU time: peaks)."""
    values = [r[key] for r in runs]
    return None if any(v is None for v in values) else statistics.median(values)


def repeated(command: list[str], env: dict, what: str, cwd: Path | None = None) -> dict:
    """REPEAT[0] runs of ``command`` (in ``cwd``) after an untimed one: medians, and the
    spread of CPU."""
    first = run_process(command, env, cwd)
    if first["code"] != 0:
        raise RuntimeError(f"{what} failed: {first['output'].strip()[-400:]}")
    runs = [run_process(command, env, cwd) for _ in range(max(1, REPEAT[0]))]
    cpus = [r["cpu_s"] for r in runs]
    return {
        "cpu_s": median_of(runs, "cpu_s"),
        "wall_s": median_of(runs, "wall_s"),
        "cpu_min_s": min(cpus),
        "cpu_max_s": max(cpus),
        "peak_mb": median_of(runs, "peak_mb"),
    }


def whole_processes(folder: Path, env: dict, log, with_ngspice: bool) -> dict:
    """Table 1: ours and ngspice as whole processes on each netlist."""
    rows = {}
    for name, netlist in NETLISTS.items():
        log(f"  whole process: {name}")
        csv = folder / f"{name}.csv"
        ours = [sys.executable, "-m", "circuitsim", "simulate", str(netlist), "--csv", str(csv)]
        row = {"ours": repeated(ours, env, f"simulate {name}")}
        if with_ngspice and shutil.which("ngspice"):
            raw = folder / f"{name}.raw"
            ngspice = [shutil.which("ngspice"), "-b", "-r", str(raw), str(netlist)]
            row["ngspice"] = repeated(ngspice, env, f"ngspice {name}")
        rows[name] = row
    log("  whole process: ideal, our modules without bytecode")
    # a copy of the package without its __pycache__ (run.py compiles it), run from its folder:
    # numpy's and the standard library's bytecode stays, ours is compiled at every start
    source = folder / "source-only"
    shutil.rmtree(source, ignore_errors=True)
    shutil.copytree(REPO / "circuitsim", source / "circuitsim",
                    ignore=shutil.ignore_patterns("__pycache__"))  # fmt: skip
    plain = [sys.executable, "-m", "circuitsim", "simulate", str(NETLISTS["ideal"])]
    rows["ideal, no .pyc"] = {
        "ours": repeated([*plain, "--csv", str(folder / "plain.csv")],
                         environment(None, source), "plain", cwd=source)  # fmt: skip
    }
    return rows


def phases(folder: Path, env: dict, log) -> dict:
    """Table 2: the phases of a simulate process, median CPU seconds of each."""
    out = {}
    for name, netlist in NETLISTS.items():
        log(f"  phases: {name}")
        command = [sys.executable, "-c", PHASES, str(netlist), str(folder / f"phases-{name}.csv")]
        samples = []
        for _ in range(max(1, REPEAT[0]) + 1):
            done = run_process(command, as_cli(env))
            if done["code"] != 0:
                raise RuntimeError(f"phases {name} failed: {done['output'].strip()[-400:]}")
            marks = json.loads(done["output"].strip().splitlines()[-1])
            cpu = dict(marks)
            samples.append(
                {
                    "interpreter": cpu["interpreter"],
                    "imports": cpu["imports"] - cpu["interpreter"],
                    "read netlist": cpu["read netlist"] - cpu["imports"],
                    # the first run's and first CSV's extra over the second: loading machine code
                    "cache load, first calls": (cpu["first run"] - cpu["read netlist"])
                    - (cpu["solve"] - cpu["first run"])
                    + (cpu["first CSV"] - cpu["solve"])
                    - (cpu["write CSV"] - cpu["first CSV"]),
                    "solve": cpu["solve"] - cpu["first run"],
                    "write CSV": cpu["write CSV"] - cpu["first CSV"],
                    # the process's CPU (wait4) after its last mark: the interpreter's shutdown
                    "interpreter exit": done["cpu_s"] - cpu["write CSV"],
                }
            )
        samples = samples[1:]  # the first one warmed the caches
        out[name] = {key: statistics.median(s[key] for s in samples) for key in samples[0]}
        out[name]["sum"] = sum(out[name].values())
    return out


def floor(env: dict, log) -> dict:
    """Table 3: the cost of start-up before any work, step by step (each process ended as
    ``circuitsim.cli.run`` ends one: ``gc.freeze()``, then the interpreter's shutdown)."""
    log("  floor")
    return {
        label: repeated([sys.executable, "-c", f"{code}\n{END}"], as_cli(env), label)
        for label, code in FLOOR.items()
    }


def memory(folder: Path, env: dict, log) -> dict:
    """Table 4: peak RSS of a long TL074 run, every signal and the four states probed."""
    text = NETLISTS["tl074"].read_text()
    deck = folder / "tl074_50s.cir"
    deck.write_text(re.sub(r"(?m)^\.tran 270u 5 ", f".tran 270u {MEMORY_TSTOP:g} ", text))
    rows = {}
    for label, extra in (
        ("every signal", []),
        ("--probe " + " ".join(MEMORY_PROBES), ["--probe", *MEMORY_PROBES]),
    ):
        log(f"  memory: {label}")
        command = [sys.executable, "-m", "circuitsim", "simulate", str(deck)]
        command += ["--csv", str(folder / "memory.csv"), *extra]
        done = run_process(command, env)
        if done["code"] != 0:
            raise RuntimeError(f"memory run failed: {done['output'].strip()[-400:]}")
        points = re.search(r"(\d+) time point", done["output"])
        rows[label] = {
            "peak_mb": done["peak_mb"],
            "cpu_s": done["cpu_s"],
            "points": int(points.group(1)) if points else None,
            "csv_mb": (folder / "memory.csv").stat().st_size / 1e6,
        }
        (folder / "memory.csv").unlink()
    return rows


def run(folder: Path, quick: bool, log, with_ngspice: bool = True) -> dict:
    """Every table's figures (``quick``: the memory table left out)."""
    folder.mkdir(parents=True, exist_ok=True)
    env = environment(folder / "pycache")
    data = {
        "repeat": REPEAT[0],
        "whole": whole_processes(folder, env, log, with_ngspice),
        "phases": phases(folder, env, log),
        "floor": floor(env, log),
    }
    if not quick:
        data["memory"] = memory(folder, env, log)
    return data


def report(data: dict) -> str:
    """The tables as text."""
    parts = [f"Whole processes, median of {data['repeat']} (CPU = user + system)"]
    rows = []
    for name, row in data["whole"].items():
        ours, ngspice = row["ours"], row.get("ngspice")
        rows.append(
            [
                name,
                ours["cpu_s"],
                f"{ours['cpu_min_s']:.3g}-{ours['cpu_max_s']:.3g}",
                ours["wall_s"],
                ngspice["cpu_s"] if ngspice else None,
                ngspice["wall_s"] if ngspice else None,
                ours["cpu_s"] / ngspice["cpu_s"] if ngspice else None,
                ours["peak_mb"],
            ]
        )
    headers = ["netlist", "ours CPU (s)", "range", "ours wall (s)", "ngspice CPU (s)"]
    headers += ["ngspice wall (s)", "CPU ratio", "ours peak (MB)"]
    parts.append(table(headers, rows))
    parts.append("Where a simulate process's CPU time goes (s, median)")
    names = list(data["phases"])
    keys = list(data["phases"][names[0]])
    parts.append(
        table(["phase", *names], [[k, *(data["phases"][n][k] for n in names)] for k in keys])
    )
    parts.append("The floor: start-up before any work (CPU s, median)")
    parts.append(
        table(
            ["process", "CPU (s)", "wall (s)", "peak (MB)"],
            [[k, v["cpu_s"], v["wall_s"], v["peak_mb"]] for k, v in data["floor"].items()],
        )
    )
    if "memory" in data:
        parts.append(f"Peak memory of a {MEMORY_TSTOP:g} s TL074 wheelset run (one process each)")
        parts.append(
            table(
                ["recorded", "time points", "peak RSS (MB)", "CSV (MB)", "CPU (s)"],
                [
                    [k, v["points"], v["peak_mb"], v["csv_mb"], v["cpu_s"]]
                    for k, v in data["memory"].items()
                ],
            )
        )
    return "\n\n".join(parts)


def against(other: Path, folder: Path, log) -> str:
    """Whole simulate processes of this checkout and of ``other`` on each netlist,
    interleaved (REPEAT[0] pairs after an untimed one each): a table of median CPU."""
    folder.mkdir(parents=True, exist_ok=True)
    checkouts = {"this": REPO, "other": other.resolve()}
    envs = {k: environment(folder / f"pycache-{k}", path) for k, path in checkouts.items()}
    load_before = os.getloadavg()
    rows = []
    for name, netlist in NETLISTS.items():
        log(f"  {name}: this and {other}, interleaved")
        command = [sys.executable, "-m", "circuitsim", "simulate", str(netlist)]
        command += ["--csv", str(folder / f"{name}.csv")]
        samples: dict[str, list[dict]] = {k: [] for k in checkouts}
        for turn in range(max(1, REPEAT[0]) + 1):
            for key in checkouts:
                done = run_process(command, envs[key], cwd=folder)
                if done["code"] != 0:
                    raise RuntimeError(f"{key} {name} failed: {done['output'].strip()[-400:]}")
                if turn:  # the first of each warmed the bytecode and kernel caches
                    samples[key].append(done)
        this, that = (median_of(samples[k], "cpu_s") for k in checkouts)
        spread = {k: [r["cpu_s"] for r in v] for k, v in samples.items()}
        rows.append(
            [
                name,
                this,
                f"{min(spread['this']):.3g}-{max(spread['this']):.3g}",
                that,
                f"{min(spread['other']):.3g}-{max(spread['other']):.3g}",
                this - that,
                median_of(samples["this"], "wall_s"),
                median_of(samples["other"], "wall_s"),
            ]
        )
    load_after = os.getloadavg()
    headers = ["netlist", "this CPU (s)", "range", "other CPU (s)", "range", "this - other"]
    headers += ["this wall (s)", "other wall (s)"]
    return "\n\n".join(
        [
            f"simulate --csv, this checkout against {other}, median of {REPEAT[0]} interleaved "
            f"pairs (CPU = user + system); load average {load_before[0]:.1f} before, "
            f"{load_after[0]:.1f} after ({os.cpu_count()} cores)",
            table(headers, rows),
        ]
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=REPEAT[0], help="processes per figure")
    parser.add_argument("--quick", action="store_true", help="without the memory table")
    parser.add_argument("--no-ngspice", action="store_true", help="ours only")
    parser.add_argument(
        "--against", type=Path, metavar="DIR", help="interleaved with the checkout in DIR"
    )
    args = parser.parse_args(argv)
    REPEAT[0] = args.repeat
    if args.against is not None:
        with tempfile.TemporaryDirectory(prefix="circuitsim-against-") as folder:
            print(against(args.against, Path(folder), lambda m: print(m, file=sys.stderr)))
        return 0
    with tempfile.TemporaryDirectory(prefix="circuitsim-startup-") as folder:
        data = run(
            Path(folder), args.quick, lambda m: print(m, file=sys.stderr), not args.no_ngspice
        )
    print(report(data))
    return 0


if __name__ == "__main__":
    sys.exit(main())
