"""ODE model -> op-amp analog-computer circuit (the translator), with its scale map and BOM.

Typical use::

    from circuitsim.mechanics import load_model
    from circuitsim.synthesis import SynthesisOptions, generate, synthesize

    system = load_model().system(parameters={"V": 55, "f": 3})
    result = generate(system, "wheelset.cir", SynthesisOptions(series="exact"))
    result.report.ok                     # the written netlist realizes the model
    print(result.report.summary())       # incl. the realized circuit's critical speed

``synthesize`` returns the Circuit, ScaleMap and BOM without writing files;
``check_mapping`` proves a netlist file against a model. See docs/translator.md.
"""

from circuitsim.synthesis.blocks import BomEntry
from circuitsim.synthesis.check import MappingReport, check_mapping
from circuitsim.synthesis.generate import Generated, generate
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.scalemap import ScaleMap, StateScale
from circuitsim.synthesis.translator import Synthesis, synthesize

__all__ = [
    "BomEntry",
    "Generated",
    "MappingReport",
    "ScaleMap",
    "StateScale",
    "Synthesis",
    "SynthesisOptions",
    "check_mapping",
    "generate",
    "synthesize",
]
