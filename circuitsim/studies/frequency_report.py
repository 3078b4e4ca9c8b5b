"""The report's frequency-response section: the wheelset's FRF inside the flange clearance
(model against the ideal circuit's .ac on each engine) and its stepped-sine response curve
with the flange on (ODE and circuit), as ``circuitsim frf`` and ``circuitsim stepped-sine``
compute them (docs/frf.md)."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from circuitsim.studies.agreement_report import number_cell

#: the FRF's sweep, Hz of model time, points per decade (the issue's 0.1-100 Hz)
FRF_SWEEP = (0.1, 100.0, 20)
#: the stepped sine's forcing frequencies (Hz) around the hunting resonance, and its timing
STEPPED_SINE_FREQUENCIES = tuple(float(f) for f in np.arange(6.0, 11.01, 0.5))
STEPPED_SINE_SETTLE, STEPPED_SINE_RECORD = 4.0, 1.0


def frequency_study(
    model, engines: dict[str, str | None], frf_figure: Path, curves_figure: Path,
    frequencies: tuple[float, ...] = STEPPED_SINE_FREQUENCIES, dpi: float | None = None,
) -> dict:  # fmt: skip
    """Both parts, figures written; a JSON-ready summary with ``wall_s``.

    Parameters
    ----------
    model : Model
        The wheelset (its forcing frequency ``[options] freq``).
    engines : dict of str to str or None
        Engine to why it cannot run (None: available).
    frequencies : tuple of float
        The stepped sine's frequencies, Hz; empty to leave it out.
    dpi : float, optional
        Resolution of PNG figures (default the house style's); their format by suffix.
    """
    from circuitsim.compare.frf import circuit_response, departure, differences, model_response
    from circuitsim.compare.frf_plot import plot_frf
    from circuitsim.netlist.circuit import AcSweep
    from circuitsim.synthesis import synthesize
    from circuitsim.synthesis.options import SynthesisOptions

    started = time.perf_counter()
    system = model.system(None, model.option_parameters({"freq": 3.0}), {"flange": True})
    low, high, per_decade = FRF_SWEEP
    sweep = AcSweep("dec", per_decade, low, high)
    responses = {"model": model_response(system, sweep)}
    synthesis = synthesize(system, SynthesisOptions(series="exact"))
    for engine, reason in engines.items():
        if reason is None:
            responses[engine] = circuit_response(synthesis, system, sweep, engine)
    plot_frf(responses, responses["model"].inputs[0], frf_figure, dpi=dpi)
    rows = []
    model_frf = responses["model"]
    for state in model_frf.states:
        h = model_frf.of(model_frf.inputs[0], state)
        row = {"state": state}
        for engine, response in responses.items():
            if engine == "model":
                continue
            c = response.of(model_frf.inputs[0], state)
            d_db, d_deg = differences(h, c)
            row[engine] = {
                "worst_db": float(np.nanmax(np.abs(d_db))),
                "worst_degrees": float(np.nanmax(np.abs(d_deg))),
                "departs_at_hz": departure(model_frf.frequencies, h, c, 0.1, 1.0),
            }
        rows.append(row)
    summary = {"sweep_hz": [low, high, per_decade], "input": model_frf.inputs[0], "rows": rows}
    if frequencies:
        summary["stepped_sine"] = _stepped_sine(model, frequencies, curves_figure, dpi)
    summary["wall_s"] = time.perf_counter() - started
    return summary


def _stepped_sine(model, frequencies, path: Path, dpi: float | None) -> dict:
    from circuitsim.studies.hunting_result import HuntingSettings
    from circuitsim.studies.stepped_sine import plot_response_curves, run_stepped_sine, summary

    def forced(frequency: float, flange: bool):
        parameters = model.option_parameters({"freq": frequency})
        return model.system(None, parameters, {name: flange for name in model.nonlinear_terms})

    settings = HuntingSettings(STEPPED_SINE_SETTLE, STEPPED_SINE_RECORD, repush=0.0)
    result = run_stepped_sine(forced, np.asarray(frequencies, dtype=float), settings, (True,))
    plot_response_curves(result, path, dpi)
    return summary(result)


def render_frequency(summary: dict | None, figures: dict[str, str], add) -> None:
    """Append the section's Markdown lines with ``add``."""
    if not summary:
        return
    low, high, per_decade = summary["sweep_hz"]
    add("## Frequency response (docs/frf.md)")
    add("")
    add(
        f"Receptances from the {summary['input']} input inside the flange clearance (the "
        "linear part's state matrix) against the ideal exact circuit's `.ac`, mapped back "
        f"through the scale map: {low:g}-{high:g} Hz of model time, {per_decade} points per "
        "decade (`circuitsim frf`)."
    )
    add("")
    engines = [k for k in summary["rows"][0] if k != "state"]
    add("| state | " + " | ".join(f"{e}: worst dB / degrees" for e in engines) + " |")
    add("|---|" + "---|" * len(engines))
    for row in summary["rows"]:
        cells = [
            f"{number_cell(row[e]['worst_db'], '.2g')} / "
            f"{number_cell(row[e]['worst_degrees'], '.2g')}"
            for e in engines
        ]
        add(f"| {row['state']} | " + " | ".join(cells) + " |")
    add("")
    if "frf" in figures:
        add(f"![frequency response, model and circuit]({figures['frf']})")
        add("")
    curves = summary.get("stepped_sine")
    if not curves:
        return
    frequencies = curves["frequencies_hz"]
    add(
        f"Stepped sine with the flange on (`circuitsim stepped-sine`): {frequencies[0]:g}-"
        f"{frequencies[-1]:g} Hz ({len(frequencies)} frequencies) up then down, "
        f"{curves['settle_s']:g} s settling, amplitude max |{curves['state']}| over the next "
        f"{curves['record_s']:g} s, ODE and builtin circuit."
    )
    add("")
    for flange, entry in curves["flange"].items():
        for direction in ("up", "down"):
            jumps = {
                path: ", ".join(f"{f:g} Hz" for f in entry.get(f"{path}_{direction}_jumps_hz", []))
                or "none"
                for path in ("ode", "circuit")
            }
            difference = entry.get(f"circuit_vs_ode_{direction}", math.nan)
            add(
                f"- flange {flange}, {direction}: jumps ODE {jumps['ode']}, circuit "
                f"{jumps['circuit']}; circuit amplitudes within "
                f"{number_cell(100 * difference, '.2g')} % of the ODE's"
            )
    add("")
    if "stepped_sine" in figures:
        add(f"![stepped-sine response curves]({figures['stepped_sine']})")
        add("")
