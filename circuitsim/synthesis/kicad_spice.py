"""The SPICE side of the KiCad schematic (:mod:`~circuitsim.synthesis.kicad`): values in
KiCad's notation, each source's ``Spice_Model`` text, the library written beside the schematic
(the circuit's models and subcircuits plus the quad wrapper KiCad's netlister needs) and the
check that every switch can be drawn closed.
"""

from __future__ import annotations

import math

from circuitsim.netlist.circuit import Circuit, SubcircuitCall, Switch, VoltageSource
from circuitsim.netlist.writer import write_netlist
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.kicad_symbols import TL074_SECTIONS
from circuitsim.synthesis.schematic import GROUND

#: The 14-pin subcircuit (pins in TL074 order) that one quad package calls.
QUAD = "TL074_QUAD"


def kicad_value(value: float, unit: str) -> str:
    """A value in KiCad's (and SPICE's) notation: 30100 -> ``30.1k``, 1e-7 -> ``100n``."""
    if value == 0 or not math.isfinite(value):
        return f"{value:g}"
    exponent = min(max(3 * math.floor(math.log10(abs(value)) / 3), -12), 6)
    prefix = {-12: "p", -9: "n", -6: "u", -3: "m", 0: "", 3: "k", 6: "Meg"}[exponent]
    return f"{float(f'{value / 10.0**exponent:.6g}'):g}{prefix}"


def source_models(circuit: Circuit) -> dict[str, str]:
    """Each voltage source's value as the ngspice netlist writes it (``DC 15``, ``SIN(0 13.2
    3)``, ``PWL(...)``), by lower-case name: KiCad's ``Spice_Model`` field."""
    names = {e.name.lower() for e in circuit.elements if isinstance(e, VoltageSource)}
    cards: list[str] = []
    for line in write_netlist(circuit, "ngspice").splitlines():
        if line.startswith("+") and cards:
            cards[-1] += " " + line[1:].strip()
        else:
            cards.append(line.strip())
    models = {}
    for card in cards:
        fields = card.split(None, 3)
        if len(fields) == 4 and fields[0].lower() in names:
            models[fields[0].lower()] = fields[3]
    return models


def spice_library_text(circuit: Circuit) -> str:
    """The models and subcircuits of ``circuit`` plus one 14-pin quad wrapper (pins in TL074
    order) around its op-amp subcircuit, for the schematic's ``Spice_Lib_File``."""
    text = write_netlist(circuit, "ngspice", fold_subcircuit_defaults=True)
    kept, inside, previous = [], False, False
    for line in text.splitlines():
        head = line.strip().lower()
        if head.startswith(".subckt"):
            inside = True
        take = inside or head.startswith(".model") or (previous and head.startswith("+"))
        if take:
            kept.append(line)
        previous = take
        if head.startswith(".ends"):
            inside = False
    calls = [e for e in circuit.elements if isinstance(e, SubcircuitCall)]
    if calls:
        model, ports = calls[0].subcircuit, len(calls[0].connections)
        kept.append(f".subckt {QUAD} " + " ".join(f"p{k}" for k in range(1, 15)))
        for section, (plus, minus, out) in TL074_SECTIONS.items():
            supplies = ["p4", "p11"][: ports - 3]
            nodes = [f"p{plus}", f"p{minus}", *supplies, f"p{out}"]
            kept.append(f"X{section} " + " ".join(nodes) + f" {model}")
        kept.append(f".ends {QUAD}")
    return "\n".join(kept) + "\n"


def check_switches(circuit: Circuit) -> None:
    """SynthesisError unless every switch is held on by a constant control (drawn closed)."""
    sources = {e.positive.lower(): e for e in circuit.elements if isinstance(e, VoltageSource)}
    for switch in (e for e in circuit.elements if isinstance(e, Switch)):
        control = sources.get(switch.control_positive.lower())
        model = circuit.models.get(switch.model.lower())
        threshold = float((model.params if model else {}).get("vt", 0.0))
        if (control is None or control.waveform is not None or switch.control_negative != GROUND
                or not float(control.dc) > threshold):  # fmt: skip
            raise SynthesisError(
                f"kicad schematic: switch {switch.name} is not held on by a constant control; "
                "the schematic draws it as a closed panel switch"
            )
