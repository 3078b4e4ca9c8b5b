"""cProfile of one builtin single run of the wheelset circuit (ideal op-amps)."""

from __future__ import annotations

import cProfile
import io
import pstats
from pathlib import Path

import numpy as np
from bench_common import best_of
from bench_wheelset import SCENARIO, T_STOP

from circuitsim.mechanics import load_model
from circuitsim.solver import simulate
from circuitsim.solver.batch import batch_transient
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
    # the low-rank lever measured on one run: our batch code with a single variant reuses one
    # inverse across Newton iterations and steps where the engine factors every iteration
    single, t_single = best_of(simulate, circuit)
    batch, t_batch = best_of(batch_transient, [circuit], probes=["v(y)"])
    y = np.interp(single.time, batch.time, batch.signals["v(y)"][0])
    return {
        "t_stop": t_stop,
        "stats": waves.stats,
        "total_s": stats.total_tt,
        "top": body,
        "single_s": t_single,
        "batch_of_one_s": t_batch,
        "batch_of_one_stats": batch.stats,
        "batch_of_one_max_dev_over_range": float(
            np.max(np.abs(y - single["v(y)"])) / np.ptp(single["v(y)"])
        ),
    }


def report(data: dict) -> str:
    s = data["stats"]
    head = (
        f"cProfile of one builtin run, wheelset (ideal op-amps), 0-{data['t_stop']:g} s: "
        f"{data['total_s']:.3g} s under the profiler, {s.get('accepted')} steps, "
        f"{s.get('newton_iterations')} Newton iterations, {s.get('factorizations')} LU "
        f"factorizations, {s.get('unknowns')} unknowns (top {TOP} by own time)"
    )
    b = data["batch_of_one_stats"]
    lever = (
        f"Same run without the profiler: engine {data['single_s']:.3g} s; the batch code with "
        f"one variant (inverse reused across Newton iterations and steps, low-rank update on "
        f"the diode and charge ports) {data['batch_of_one_s']:.3g} s "
        f"({b.get('factorizations')} block inversions/LU instead of {s.get('factorizations')}), "
        f"v(y) within {data['batch_of_one_max_dev_over_range']:.2g} of its range"
    )
    return head + "\n" + data["top"].rstrip() + "\n\n" + lever
