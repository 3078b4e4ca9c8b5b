"""The tolerance section of ``reproduce``'s report: a small Monte Carlo of the bench build.

One scenario's circuit (ideal op-amps, E96 nominal parts) with 1 % resistors and 5 %
capacitors, a few tens of draws (:func:`circuitsim.studies.tolerance.run_tolerance`): the
spread of the realized critical speed and of y's error against the ODE, and the yield at the
thresholds. ``circuitsim tolerance`` runs the same with any N (docs/tolerances.md).
"""

from __future__ import annotations

import time
from pathlib import Path

RESISTOR_TOLERANCE, CAPACITOR_TOLERANCE = 0.01, 0.05
SEED = 1


def tolerance_study(
    system, scenario_title: str, samples: int, path: Path, workers: int, dpi: float | None = None
) -> dict:
    """Run the report's Monte Carlo on ``system`` and draw its histograms into ``path`` (its
    format by suffix; ``dpi``: a PNG's resolution, default the house style's).

    Returns
    -------
    dict
        ``summary`` (statistics of every distribution), ``yield``, ``unstable_fraction``,
        the settings, ``scenario`` and ``wall_s``.
    """
    from circuitsim.studies.tolerance import Tolerances, plot_tolerance, run_tolerance
    from circuitsim.synthesis.options import SynthesisOptions

    started = time.perf_counter()
    tolerances = Tolerances(RESISTOR_TOLERANCE, CAPACITOR_TOLERANCE)
    result = run_tolerance(
        system, tolerances, samples, SEED, SynthesisOptions(series="E96"), workers=workers
    )
    plot_tolerance(result, path, dpi=dpi)
    data = result.to_json()
    return {
        "scenario": scenario_title,
        "samples": samples,
        "seed": SEED,
        "resistor_tolerance": RESISTOR_TOLERANCE,
        "capacitor_tolerance": CAPACITOR_TOLERANCE,
        "critical_speed_model": result.critical_speed_model,
        "speed": result.speed,
        "unstable_fraction": result.unstable_fraction,
        "yield": result.yield_fraction,
        "thresholds": data["thresholds"],
        "summary": data["summary"],
        "wall_s": time.perf_counter() - started,
    }


def render_tolerance(study: dict | None, figure: str | None, add) -> None:
    """The report's section (nothing without a study)."""
    if not study:
        return
    add("## Tolerances: a bench build of the circuit")
    add("")
    th = study["thresholds"]
    add(
        f"{study['scenario']}; ideal op-amps, E96 nominal parts; {study['samples']} circuits "
        f"drawn with every resistor within {100 * study['resistor_tolerance']:g} % and every "
        f"capacitor within {100 * study['capacitor_tolerance']:g} % (uniform, seed "
        f"{study['seed']}; `circuitsim tolerance`, docs/tolerances.md), each read back into "
        f"its realized linear part and simulated ({study['wall_s']:.1f} s)."
    )
    add("")
    add("| quantity | mean | sd | min | 5 % | median | 95 % | max |")
    add("|---|---|---|---|---|---|---|---|")
    rows = [("realized critical speed (m/s)", study["summary"]["critical_speed"], ".3f")]
    for state, stats in study["summary"].items():
        if state == "critical_speed":
            continue
        rows.append((f"{state} NRMSD (%)", stats["nrmsd_percent"], ".3g"))
        rows.append((f"{state} peak ratio", stats["peak_ratio"], ".4f"))
    for label, d, fmt in rows:
        if not d.get("count"):
            continue
        cells = " | ".join(f"{d[k]:{fmt}}" for k in ("mean", "std", "min", "p5", "p50", "p95",
                                                        "max"))  # fmt: skip
        add(f"| {label} | {cells} |")
    add("")
    model = study["critical_speed_model"]
    if model is not None:
        line = f"Model critical speed {model:.4f} m/s"
        if study["unstable_fraction"] is not None:
            line += (
                f"; {100 * study['unstable_fraction']:.0f} % of the drawn circuits are linearly "
                f"unstable at the simulated {study['speed']:g} m/s"
            )
        add(line + ".")
    if study["yield"] is not None:
        add(
            f"Yield (every state within NRMSD {th['nrmsd_percent']:g} %, peak and frequency "
            f"within {100 * th['peak_ratio_tolerance']:g} %): **{100 * study['yield']:.0f} %**."
        )
    add("")
    if figure:
        add(f"![tolerance histograms]({figure})")
        add("")
