"""The wheelset with vendor-style op-amp macromodels: our engine against ngspice and the ODE.

The generated wheelset circuit (flange on, V = 55 m/s, f = 3 Hz, a = 0.040 m, 0-5 s, exact
resistor values) built with each op-amp of ``circuitsim/netlist/library/macromodels.lib``
(``generate --opamp-lib``): the JFET-input Boyle model (p-channel JFET pair, POLY sources)
and the bipolar one (n-p-n pair), with the built-in TL074 (diodes only) beside them. Per
op-amp: wall time of ngspice and of our engine (kernel=auto: the MNA kernel for JFETs and
BJTs, which only it models), the worst node voltage's max deviation from ngspice relative to
its range, and %NRMSD of y against the direct ODE.
"""

from __future__ import annotations

from pathlib import Path

from bench_common import best_of, table
from bench_golden import deviation

from circuitsim.compare.mapping import map_waveforms
from circuitsim.compare.signals import nrmsd_percent
from circuitsim.interop.ngspice import run_ngspice
from circuitsim.mechanics import load_model, solve
from circuitsim.netlist.reader import read_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.scalemap import ScaleMap

SCENARIO = {"V": 55.0, "f": 3.0, "a": 0.040}
LIBRARY = Path(__file__).resolve().parent.parent / "circuitsim/netlist/library/macromodels.lib"
OPAMPS = {
    "tl074 (built-in, diodes)": {"opamp": "tl074"},
    "BOYLE_TL07X (JFET, POLY)": {
        "opamp": "lib", "opamp_lib": str(LIBRARY), "opamp_subckt": "BOYLE_TL07X"
    },
    "BOYLE_UA741 (BJT, POLY)": {
        "opamp": "lib", "opamp_lib": str(LIBRARY), "opamp_subckt": "BOYLE_UA741"
    },
}  # fmt: skip


def _only(waves, nodes: list[str]):
    """``waves`` with only the voltages of ``nodes``."""
    from circuitsim.solver.waveforms import Waveforms

    signals = {f"v({n})": waves[f"v({n})"] for n in nodes}
    return Waveforms(time=waves.time, signals=signals, engine=waves.engine, stats=waves.stats)


def run(folder: Path, quick: bool, log) -> dict:
    folder.mkdir(parents=True, exist_ok=True)
    t_stop = 1.0 if quick else 5.0
    system = load_model().system(parameters=SCENARIO)
    ode = solve(system, (0.0, t_stop), rtol=1e-11, atol=1e-14)
    rows = []
    for label, fields in OPAMPS.items():
        options = SynthesisOptions(**fields, series="exact", t_stop=t_stop)
        path = folder / f"wheelset_{fields.get('opamp_subckt', fields['opamp']).lower()}.cir"
        result = generate(system, path, options)
        scale = ScaleMap.load(result.scale_file)
        log(f"{label}: ngspice")
        theirs, ngspice_s = best_of(run_ngspice, path)
        log(f"{label}: builtin")
        circuit = read_netlist(path)
        options = SimulationOptions.from_circuit(circuit, max_wall_time=None)
        ours, ours_s = best_of(simulate, circuit, options)
        row = {"opamp": label, "ngspice_s": ngspice_s, "builtin_s": ours_s, "t_stop": t_stop}
        for engine, waves in (("ngspice", theirs), ("builtin", ours)):
            if isinstance(waves, Exception):
                row[f"{engine}_error"] = str(waves)
                continue
            ((t, y),) = [map_waveforms(waves, scale, ["y"])["y"]]
            row[f"{engine}_nrmsd_y"] = nrmsd_percent(ode.sol(t)[0], y)
            row[f"{engine}_steps"] = int(waves.time.size)
        if not isinstance(ours, Exception) and not isinstance(theirs, Exception):
            row["kernel"] = ours.stats.get("kernel", "")
            # the state nodes (each state and its negative), then every node: inside the |x|
            # blocks open-loop op-amps glitch at each zero crossing (docs/parts.md)
            states = [s.node for s in scale.states.values()]
            states += [f"{node}_neg" for node in states]
            subset = _only(theirs, states)
            row["state_deviation"], row["state_signal"] = deviation(ours, subset)
            row["deviation"], row["worst_signal"] = deviation(ours, theirs, kinds=("v(",))
            row["ratio"] = ours_s / ngspice_s
        rows.append(row)
    return {"rows": rows, "scenario": SCENARIO}


def report(data: dict) -> str:
    headers = ["op-amp", "ngspice s", "builtin s", "builtin/ngspice", "states: dev / range",
               "node", "all nodes: dev / range", "node", "NRMSD y % ngspice",
               "NRMSD y % builtin", "kernel"]  # fmt: skip
    rows = [
        [r["opamp"], r["ngspice_s"], r["builtin_s"], r.get("ratio"), r.get("state_deviation"),
         r.get("state_signal"), r.get("deviation"), r.get("worst_signal"),
         r.get("ngspice_nrmsd_y"), r.get("builtin_nrmsd_y"),
         r.get("kernel", r.get("builtin_error", ""))]
        for r in data["rows"]
    ]  # fmt: skip
    t_stop = data["rows"][0]["t_stop"] if data["rows"] else 0
    return f"Wheelset 0-{t_stop:g} s with op-amp macromodels\n\n" + table(headers, rows)
