"""How the engines scale with circuit size: chains of N masses, and the wheelset.

Each case is a generated circuit (exact resistor values, ideal or TL074 op-amps) of a model:
a chain of N = 1, 2, 4 ... 64 masses with a dead-zone contact on each
(:func:`circuitsim.mechanics.chain.chain_model_text`; 4 diodes per mass with ``--nonlinear
abs``), and the wheelset. ``FAMILY = "lattice"`` (``run.py --family lattice``) runs instead a
family the solver was not tuned on: an R x C grid of N masses with a one-sided floor under each
and one-sided bumpers along the rows (:func:`circuitsim.mechanics.lattice.lattice_model_text`),
without the wheelset. Both engines run the same netlist file, side by side in one run:

- in-process: ngspice's own ``Transient analysis time`` (``rusage all``, which also gives
  its step and Newton counts; the netlist is parsed and the operating point solved outside
  it) against our ``simulate()`` on the parsed Circuit (assembly, operating point and
  transient: more than ngspice's figure counts);
- whole process: ``ngspice -b deck`` against ``python -m circuitsim simulate deck --csv``
  (start-up, imports, parsing, compiled-kernel loading, output of the probed states);
- CPU time (user + system), which a loaded machine disturbs far less than wall time: the
  whole ngspice process (its parse and operating point included) against our in-process
  ``simulate()``.

Accuracy is the %NRMSD of each engine's traces of the probed states (x1 and xN, through the
scale file) against the direct ODE solution at rtol 1e-10, the worst of them. The growth
exponent of an engine is the slope of log(time) against log(N) over the chains with N >= 4.
"""

from __future__ import annotations

import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_common import REPEAT, table

from circuitsim.compare.mapping import map_waveforms, resample
from circuitsim.compare.signals import nrmsd_percent
from circuitsim.interop.rawfile import parse_rawfile
from circuitsim.mechanics import load_model, solve
from circuitsim.mechanics.chain import chain_model_text
from circuitsim.mechanics.lattice import lattice_model_text
from circuitsim.netlist.reader import read_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.options import SynthesisOptions

CHAIN_SIZES = (1, 2, 4, 8, 16, 32, 64)
QUICK_SIZES = (1, 4, 8)
T_STOP = 5.0
WHEELSET = {"V": 55.0, "f": 3.0, "a": 0.040}
FIT_FROM = 4  # growth exponents over N >= this
REPO = Path(__file__).resolve().parent.parent
FAMILIES = {"chain": chain_model_text, "lattice": lattice_model_text}  # model text of N masses
FAMILY = "chain"  # which family run() measures (run.py --family)


def family_case(masses: int, opamp: str, folder: Path, family: str = "chain") -> dict:
    """Generate the family's netlist of ``masses`` masses; its ODE reference on a dense grid
    (probed: x1 and xN, the chain's ends or the lattice's opposite corners)."""
    model_file = folder / f"{family}{masses}.toml"
    model_file.write_text(FAMILIES[family](masses, T_STOP))
    model = load_model(model_file)
    system = model.system(nonlinear={group: True for group in model.nonlinear_terms})
    states = sorted({"x1", f"x{masses}"}, key=lambda s: int(s[1:]))
    stem = folder / f"{family}{masses}"
    return _case(f"{family} {masses}", masses, system, states, opamp, stem)


def wheelset_case(opamp: str, folder: Path) -> dict:
    model = load_model()
    system = model.system(parameters=WHEELSET, nonlinear={"flange": True})
    return _case("wheelset", None, system, ["y"], opamp, folder / "wheelset")


def _case(label, masses, system, states, opamp, stem) -> dict:
    started = time.perf_counter()
    path = stem.with_name(f"{stem.name}_{opamp}.cir")
    generated = generate(system, path, SynthesisOptions(opamp=opamp, series="exact", t_stop=T_STOP))
    circuit = generated.synthesis.circuit
    result = solve(system, t_span=(0.0, T_STOP), rtol=1e-10, atol=1e-13)
    grid = np.linspace(0.0, T_STOP, 20_001)
    index = {name: k for k, name in enumerate(system.states)}
    reference = {s: result.sol(grid)[index[s]] for s in states}
    scale = generated.synthesis.scale_map
    probes = sorted({scale.states[s].node for s in states})
    return {
        "label": label,
        "masses": masses,
        "opamp": opamp,
        "netlist": path,
        "circuit": circuit,
        "scale_map": scale,
        "states": states,
        "grid": grid,
        "reference": reference,
        "probes": probes,
        "elements": _counts(circuit),
        "prepare_s": time.perf_counter() - started,
    }


def _counts(circuit) -> dict:
    """Elements of the circuit by SPICE letter (D: diodes, X: macromodel op-amps, E: ideal)."""
    kinds: dict[str, int] = {}
    for element in circuit.elements:
        letter = element.name[0].upper()
        kinds[letter] = kinds.get(letter, 0) + 1
    return kinds


def accuracy(case: dict, waves) -> float:
    """The worst %NRMSD over the case's states against the direct solution."""
    mapped = map_waveforms(waves, case["scale_map"], case["states"])
    return max(
        nrmsd_percent(case["reference"][s], resample(mapped[s], case["grid"]))
        for s in case["states"]
    )


def ngspice_run(netlist: Path) -> dict:
    """ngspice on the netlist: its own transient time (rusage), the whole process, waves."""
    text = netlist.read_text()
    with tempfile.TemporaryDirectory(prefix="circuitsim-bench-") as tmp:
        raw = Path(tmp) / "out.raw"
        body = re.sub(r"(?im)^\.end\s*$", "", text)
        deck = Path(tmp) / "deck.cir"
        deck.write_text(body + f"\n.control\nrun\nrusage all\nwrite {raw}\n.endc\n.end\n")
        started = time.perf_counter()
        children = resource.getrusage(resource.RUSAGE_CHILDREN)
        done = subprocess.run(
            [shutil.which("ngspice") or "ngspice", "-b", str(deck)],
            cwd=str(netlist.parent),
            capture_output=True,
            text=True,
            stdin=subprocess.DEVNULL,
        )
        process = time.perf_counter() - started
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - children.ru_utime) + (after.ru_stime - children.ru_stime)
        found = re.search(r"Transient analysis time\s*=\s*([0-9.eE+-]+)", done.stdout)
        if not found or not raw.exists():
            tail = (done.stdout + done.stderr).strip().splitlines()[-3:]
            return {"error": "ngspice: " + " / ".join(tail), "process_s": process}
        waves = parse_rawfile(raw.read_bytes())
    counts = {
        key: int(float(m.group(1)))
        for key, label in (
            ("steps", "Accepted timepoints"),
            ("rejected", "Rejected timepoints"),
            ("newton", "Transient iterations"),
        )  # fmt: skip
        if (m := re.search(label + r"\s*=\s*([0-9.eE+-]+)", done.stdout))
    }
    return {"solve_s": float(found.group(1)), "process_s": process, "cpu_s": cpu, "waves": waves,
            **counts}  # fmt: skip


def ours_in_process(case: dict) -> dict:
    """simulate() on the parsed netlist (kernel=auto), timed without the parse."""
    circuit = read_netlist(case["netlist"])
    options = SimulationOptions.from_circuit(circuit)
    started, cpu = time.perf_counter(), time.process_time()
    try:
        waves = simulate(circuit, options)
    except Exception as exc:  # noqa: BLE001 - a failing engine is a result to report
        return {"error": f"{type(exc).__name__}: {exc}", "solve_s": time.perf_counter() - started}
    seconds = time.perf_counter() - started
    stats = waves.stats
    return {
        "solve_s": seconds,
        "cpu_s": time.process_time() - cpu,
        "waves": waves,
        "kernel": stats.get("kernel"),
        "steps": stats.get("accepted"),
        "rejected": stats.get("rejected"),
        "newton": stats.get("newton_iterations"),
        "factorizations": stats.get("factorizations"),
        "unknowns": stats.get("unknowns"),
    }


def ours_process(case: dict) -> dict:
    """Wall seconds of ``python -m circuitsim simulate`` writing the probed states' CSV."""
    with tempfile.TemporaryDirectory(prefix="circuitsim-bench-") as tmp:
        command = [sys.executable, "-m", "circuitsim", "simulate", str(case["netlist"])]
        command += ["--csv", str(Path(tmp) / "out.csv")]
        for probe in case["probes"]:
            command += ["--probe", f"v({probe})"]
        started = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True, cwd=str(REPO))
        seconds = time.perf_counter() - started
    error = None if done.returncode == 0 else (done.stderr.strip().splitlines() or ["?"])[-1]
    return {"process_s": seconds, "error": error}


def _best(run, *args) -> dict:
    """The fastest of REPEAT[0] runs (by the in-process time, else the process time)."""
    best = None
    for _ in range(max(1, REPEAT[0])):
        result = run(*args)
        if "error" in result and "waves" not in result:
            return result
        key = result.get("solve_s", result.get("process_s"))
        if best is None or key < best.get("solve_s", best.get("process_s")):
            best = result
    return best


def measure(case: dict, log) -> dict:
    """Both engines on one case, side by side (each best of REPEAT)."""
    row = {k: case[k] for k in ("label", "masses", "opamp", "elements", "prepare_s")}
    row["netlist"] = case["netlist"].name
    ngspice = _best(ngspice_run, case["netlist"])
    ngspice_process = min(
        [ngspice["process_s"]] + [ngspice_run(case["netlist"])["process_s"]
                                  for _ in range(max(0, REPEAT[0] - 1))]
    ) if "error" not in ngspice else ngspice["process_s"]  # fmt: skip
    ours = _best(ours_in_process, case)
    process = min(
        (ours_process(case) for _ in range(max(1, REPEAT[0]))), key=lambda r: r["process_s"]
    )
    row.update(
        ngspice_s=ngspice.get("solve_s"),
        ngspice_process_s=ngspice_process,
        ngspice_error=ngspice.get("error"),
        ngspice_cpu_s=ngspice.get("cpu_s"),
        ours_cpu_s=ours.get("cpu_s"),
        ours_s=ours.get("solve_s"),
        ours_process_s=process["process_s"],
        ours_error=ours.get("error") or process["error"],
        kernel=ours.get("kernel"),
        steps=ours.get("steps"),
        rejected=ours.get("rejected"),
        ngspice_rejected=ngspice.get("rejected"),
        newton=ours.get("newton"),
        ngspice_steps=ngspice.get("steps"),
        ngspice_newton=ngspice.get("newton"),
        factorizations=ours.get("factorizations"),
        unknowns=ours.get("unknowns"),
    )
    if "waves" in ngspice:
        row["ngspice_nrmsd"] = accuracy(case, ngspice["waves"])
        row["ngspice_points"] = len(ngspice["waves"].time)
    if "waves" in ours:
        row["ours_nrmsd"] = accuracy(case, ours["waves"])
    if row["ours_s"] and row["ngspice_s"] and not row["ours_error"]:
        row["ratio"] = row["ours_s"] / row["ngspice_s"]
        row["ratio_process"] = row["ours_process_s"] / row["ngspice_process_s"]
        row["ratio_cpu"] = row["ours_cpu_s"] / row["ngspice_cpu_s"]
    log(
        f"  {row['label']} ({row['opamp']}): ours {_g(row['ours_s'])} s "
        f"({_g(row['ours_process_s'])} s process, {row['kernel']}, "
        f"{row['factorizations']} factorizations), ngspice {_g(row['ngspice_s'])} s "
        f"({_g(row['ngspice_process_s'])} s process)"
        + (f" ours FAILED: {row['ours_error']}" if row["ours_error"] else "")
    )
    return row


def _g(value) -> str:
    return "-" if value is None else f"{value:.3g}"


def growth(rows: list[dict], key: str) -> float | None:
    """Slope of log(time) against log(N) over the chains with N >= FIT_FROM."""
    points = [
        (r["masses"], r[key])
        for r in rows
        if r["masses"] and r["masses"] >= FIT_FROM and r.get(key) and not r.get("ours_error")
    ]
    if len(points) < 2:
        return None
    n, t = np.log([p[0] for p in points]), np.log([p[1] for p in points])
    return float(np.polyfit(n, t, 1)[0])


def warm_up() -> float:
    """Load both compiled kernels before anything is timed (auto runs either; the process
    column shows the loading)."""
    from circuitsim.solver.compiled import warm_up as load

    return load(("ports", "compiled")) or 0.0


def run(folder: Path, quick: bool, log, sizes=None, opamps=("ideal", "tl074")) -> dict:
    """Every case, both engines; the chains' growth exponents per op-amp model."""
    folder.mkdir(parents=True, exist_ok=True)
    log(f"  kernels ready in {warm_up():.3g} s")
    out: dict = {"t_stop_s": T_STOP, "repeat": REPEAT[0], "family": FAMILY, "cases": [],
                 "growth": {}}  # fmt: skip
    for opamp in opamps:
        chain_sizes = sizes or (QUICK_SIZES if quick else CHAIN_SIZES)  # both op-amp models
        rows = []
        for masses in chain_sizes:
            try:
                case = family_case(masses, opamp, folder, FAMILY)
            except Exception as exc:  # noqa: BLE001 - a size that cannot be generated is a row
                rows.append(
                    {"label": f"{FAMILY} {masses}", "masses": masses, "opamp": opamp,
                     "ours_error": f"not generated: {type(exc).__name__}: {exc}"}
                )  # fmt: skip
                log(f"  {FAMILY} {masses} ({opamp}): not generated: {exc}")
                continue
            rows.append(measure(case, log))
        if FAMILY == "chain":
            rows.append(measure(wheelset_case(opamp, folder), log))
        out["cases"].extend(rows)
        out["growth"][opamp] = {
            "ours": growth(rows, "ours_s"),
            "ngspice": growth(rows, "ngspice_s"),
            "ours_process": growth(rows, "ours_process_s"),
            "ngspice_process": growth(rows, "ngspice_process_s"),
            "ours_cpu": growth(rows, "ours_cpu_s"),
            "ngspice_cpu": growth(rows, "ngspice_cpu_s"),
        }
    return out


def report(data: dict) -> str:
    """The scaling table and the growth exponents."""
    headers = [
        "case", "op-amps", "unknowns", "diodes", "kernel", "factorizations", "steps ours",
        "steps ngspice", "rejected ours", "rejected ngspice", "Newton it. ours",
        "Newton it. ngspice",
        "ours (s)", "ngspice (s)", "ratio", "ours process (s)", "ngspice process (s)",
        "ratio (process)", "ours CPU (s)", "ngspice CPU (s)", "ratio (CPU)", "%NRMSD ours",
        "%NRMSD ngspice", "failure",
    ]  # fmt: skip
    rows = []
    for r in data["cases"]:
        elements = r.get("elements", {})
        rows.append(
            [
                r["label"], r["opamp"], r.get("unknowns"), elements.get("D"), r.get("kernel"),
                r.get("factorizations"), r.get("steps"), r.get("ngspice_steps"), r.get("rejected"),
                r.get("ngspice_rejected"), r.get("newton"),
                r.get("ngspice_newton"), r.get("ours_s"), r.get("ngspice_s"), r.get("ratio"),
                r.get("ours_process_s"), r.get("ngspice_process_s"), r.get("ratio_process"),
                r.get("ours_cpu_s"), r.get("ngspice_cpu_s"), r.get("ratio_cpu"),
                r.get("ours_nrmsd"), r.get("ngspice_nrmsd"),
                r.get("ours_error") or r.get("ngspice_error") or "",
            ]
        )  # fmt: skip
    family = {
        "chain": "chains of N masses with a dead-zone contact on each, and the wheelset",
        "lattice": "lattices of N masses (R x C grid) with one-sided floors and bumpers",
    }[data.get("family", "chain")]
    lines = [
        f"Scaling: {family}; "
        f"0-{data['t_stop_s']:g} s, best of {data['repeat']}; in-process: ngspice's "
        f"'Transient analysis time' against our simulate() (assembly, operating point, "
        f"transient); process: the whole command; %NRMSD: the worst probed state against the "
        f"direct ODE",
        table(headers, rows),
        "",
        f"growth exponents (slope of log time against log N, N >= {FIT_FROM} masses):",
    ]
    for opamp, fit in data["growth"].items():
        lines.append(
            f"- {opamp}: ours {_g(fit['ours'])} (process {_g(fit['ours_process'])}), "
            f"ngspice {_g(fit['ngspice'])} (process {_g(fit['ngspice_process'])}); CPU time: "
            f"ours {_g(fit['ours_cpu'])}, ngspice {_g(fit['ngspice_cpu'])}"
        )
    return "\n".join(lines)
