"""cProfile of one builtin single run of the wheelset circuit (ideal op-amps)."""

from __future__ import annotations

import cProfile
import io
import pstats
from pathlib import Path

from bench_wheelset import SCENARIO, T_STOP

from circuitsim.mechanics import load_model
from circuitsim.solver import simulate
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.translator import synthesize

TOP = 25


def run(folder: Path, quick: bool, log) -> dict:
    model = load_model()
    system = model.system(parameters=SCENARIO, nonlinear={"flange": True})
    t_stop = 1.0 if quick else T_STOP
    circuit = synthesize(system, SynthesisOptions(series="exact", t_stop=t_stop)).circuit
    profile = cProfile.Profile()
    profile.enable()
    waves = simulate(circuit)
    profile.disable()
    text = io.StringIO()
    stats = pstats.Stats(profile, stream=text)
    stats.sort_stats("tottime").print_stats(TOP)
    listing = text.getvalue()
    body = listing[listing.index("   ncalls") :] if "   ncalls" in listing else listing
    return {"t_stop": t_stop, "stats": waves.stats, "total_s": stats.total_tt, "top": body}


def report(data: dict) -> str:
    s = data["stats"]
    head = (
        f"cProfile of one builtin run, wheelset (ideal op-amps), 0-{data['t_stop']:g} s: "
        f"{data['total_s']:.3g} s under the profiler, {s.get('accepted')} steps, "
        f"{s.get('newton_iterations')} Newton iterations, {s.get('factorizations')} LU "
        f"factorizations, {s.get('unknowns')} unknowns (top {TOP} by own time)"
    )
    return head + "\n" + data["top"].rstrip()
