"""Measure the part library for docs/parts.md: figures table, glitch table, step-response plot.

Run from the repository root: ``python tests/parts/report.py [--wheelset]`` (prints Markdown
tables and writes ``docs/figures/tl074_step.png``; ``--wheelset`` adds the translator's
wheelset circuit with tl074 op-amps against the direct ODE). Uses every engine available:
ngspice and our solver (``circuitsim.solver.simulate``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

import partbench  # noqa: E402

from circuitsim.interop.ngspice import run_ngspice  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
FIGURE = ROOT / "docs" / "figures" / "tl074_step.png"
KINDS = ("ideal", "tl074")
GLITCH_CASES = [(5.0, 10.0), (5.0, 100.0), (5.0, 1e3), (5.0, 1e4), (0.05, 10.0)]
"""(sine amplitude V, frequency Hz); 50 mV is the size of the paper's unscaled (1 V = 1 m) y."""
WHEELSET_CASES = [
    (1.0, True, 0.0),
    (1.0, True, 3e-3),
    (1.0, False, 0.0),
    (10.0, True, 0.0),
    (100.0, True, 0.0),
    (100.0, False, 0.0),
    (1000.0, True, 0.0),
    (1000.0, False, 0.0),
]
"""(time scale K, flange on, input offset of every op-amp V) for ``--wheelset``."""


def plot_steps(runs: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (big, small) = plt.subplots(1, 2, figsize=(9, 3.4))
    for name, run in runs.items():
        w = partbench.follower_step(run, -5.0, 5.0, 1.5e-6, 5e-9, "RL out 0 10k\n")
        style = "-" if name == "ngspice" else "--"
        big.plot(w.time * 1e6, w["out"], style, label=f"out ({name})")
        w = partbench.follower_step(run, 0.0, 0.01, 0.6e-6, 2e-9)
        small.plot(w.time * 1e6, w["out"] * 1e3, style, label=f"out ({name})")
    w = partbench.follower_step(run_ngspice, -5.0, 5.0, 1.5e-6, 5e-9)
    big.plot(w.time * 1e6, w["in"], "k:", label="in")
    w = partbench.follower_step(run_ngspice, 0.0, 0.01, 0.6e-6, 2e-9)
    small.plot(w.time * 1e6, w["in"] * 1e3, "k:", label="in")
    big.set(xlabel="time (us)", ylabel="V", title="10 V step: slew 13 V/us")
    small.set(xlabel="time (us)", ylabel="mV", title="10 mV step: tau = 1/(2 pi 3 MHz)")
    for ax in (big, small):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("TL074 macromodel, unity-gain follower")
    fig.tight_layout()
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(FIGURE, dpi=80)
    plt.close(fig)


def wheelset_table() -> None:
    """%NRMSD of the wheelset's tl074 circuit (exact values, ngspice) against the direct ODE."""
    from circuitsim.compare.case import reference_traces, run_engine
    from circuitsim.compare.comparison import Thresholds, compare_traces
    from circuitsim.compare.mapping import map_waveforms
    from circuitsim.mechanics.model import load_model
    from circuitsim.netlist.circuit import SubcircuitCall
    from circuitsim.synthesis.options import SynthesisOptions
    from circuitsim.synthesis.translator import synthesize

    model = load_model()
    print(
        "| time scale K | flange | vos (mV) | "
        + " | ".join(f"y at {f} Hz" for f in (3, 5, 10))
        + " | worst of y' at 3/5/10 Hz |"
    )
    print("|---|---|---|---|---|---|---|")
    for time_scale, flange, vos in WHEELSET_CASES:
        y, y_dot = [], []
        for f in (3.0, 5.0, 10.0):
            system = model.system(
                parameters={"V": 55.0, "f": f, "a": 0.040}, nonlinear={"flange": flange}
            )
            options = SynthesisOptions(opamp="tl074", series="exact", time_scale=time_scale)
            synthesis = synthesize(system, options)
            for element in synthesis.circuit.elements:
                if isinstance(element, SubcircuitCall) and vos:
                    element.params["vos"] = vos
            waves = run_engine("ngspice", synthesis.circuit)
            traces = map_waveforms(waves, synthesis.scale_map, list(system.states))
            _, reference = reference_traces(system, synthesis.t_stop)
            units = dict(zip(system.states, system.units, strict=False))
            result = compare_traces(reference, traces, Thresholds(nrmsd_percent=2.0), 4096, units)
            y.append(result.states[system.states[0]].nrmsd_percent)
            y_dot.append(result.states[system.states[2]].nrmsd_percent)
        cells = " | ".join(f"{v:.3g}" for v in y)
        print(
            f"| {time_scale:g} | {'on' if flange else 'off'} | {vos * 1e3:g} | {cells} "
            f"| {max(y_dot):.3g} |"
        )


def main() -> None:
    runs = partbench.engines()
    measured = {name: partbench.figures(run) for name, run in runs.items()}
    print("| figure | design | " + " | ".join(runs) + " |")
    print("|---|---|" + "---|" * len(runs))
    for key, design in partbench.DESIGN.items():
        cells = " | ".join(f"{measured[n][key]:.5g}" for n in runs)
        print(f"| {key} | {design:.4g} | {cells} |")
    print()
    heads = [
        f"{n} {k}: peak (mV), width > 1 % of amplitude (us), mean error / mean abs(x) (%)"
        for n in runs
        for k in ("ideal", "tl074")
    ]
    print("| amplitude (V) | f (Hz) | slope at crossing (V/ms) | " + " | ".join(heads) + " |")
    print("|---|---|---|" + "---|" * len(heads))
    for amplitude, f in GLITCH_CASES:
        cells = []
        for run in runs.values():
            for kind in KINDS:
                peak, width, mean = partbench.glitch(run, kind, f, amplitude)
                cells.append(f"{peak * 1e3:.3g}, {width * 1e6:.3g}, {mean * 100:.3g}")
        slope = 2 * np.pi * f * amplitude / 1e3
        print(f"| {amplitude:g} | {f:g} | {slope:.3g} | " + " | ".join(cells) + " |")
    print()
    print("| block | " + " | ".join(f"{n} {k} max error (mV)" for n in runs for k in KINDS) + " |")
    print("|---|" + "---|" * (2 * len(runs)))
    for block in partbench.BLOCKS:
        cells = []
        for run in runs.values():
            for kind in KINDS:
                if block == "dead_zone_supplies" and kind != "tl074":
                    cells.append("-")
                    continue
                x, y, reference = partbench.transfer_curve(run, block, kind, points=4000)
                cells.append(f"{np.max(np.abs(y - reference)) * 1e3:.3g}")
        print(f"| {block} | " + " | ".join(cells) + " |")
    plot_steps(runs)
    print(f"\nwrote {FIGURE}\n")
    if "--wheelset" in sys.argv:
        wheelset_table()


if __name__ == "__main__":
    main()
