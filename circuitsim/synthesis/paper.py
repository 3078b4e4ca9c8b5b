"""The paper's circuits as committed netlists: the cases and how they are generated.

``netlists/`` holds the wheelset circuit at V = 55 m/s, f = 3 Hz, a = 0.040 m, with the flange
(switch S1 closed) and without it (linear: the same circuit with S1 open, as in the paper,
where closing S1 brings the flange in), with ideal and with TL074-like op-amps, in the
ngspice and Multisim dialects, each with its scale file and bill of materials, all with the
generator's defaults otherwise (auto scaling to 5 V, real time, E96 resistors, |x| blocks).
``python netlists/regenerate.py`` rewrites them; a test checks they are what the generator
produces now.
"""

from __future__ import annotations

import math
import os
from itertools import product
from pathlib import Path

from circuitsim.synthesis.generate import Generated, generate, switch_at
from circuitsim.synthesis.options import SynthesisOptions

SCENARIO = {"V": 55.0, "f": 3.0, "a": 0.040}
"""Parameters of the committed netlists (the paper's Fig. 6 at 3 Hz)."""

CASES = tuple(
    product(("linear", "flange"), ("ideal", "tl074"), ("ngspice", "multisim"))
)  # fmt: skip
"""(flange, op-amp, dialect) of every committed netlist."""


def file_name(flange: str, opamp: str, dialect: str) -> str:
    """``wheelset_<flange>_<opamp>_<dialect>.cir``."""
    return f"wheelset_{flange}_{opamp}_{dialect}.cir"


def paper_netlists(folder: str | os.PathLike) -> list[Generated]:
    """Write every case into ``folder`` (created if needed); returns what was generated."""
    from circuitsim.mechanics import load_model

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    model = load_model()
    results = []
    for flange, opamp, dialect in CASES:
        system = model.system(parameters=SCENARIO)
        if flange == "linear":  # the paper's linear circuit: the same one with S1 open
            system = switch_at(system, math.inf)
        results.append(
            generate(
                system,
                folder / file_name(flange, opamp, dialect),
                SynthesisOptions(opamp=opamp),
                dialect,
            )
        )
    return results
