"""The part library: op-amp macromodels and diode models shipped as SPICE text.

One source of truth: ``library/parts.lib`` beside this module, plain SPICE that ngspice,
LTspice and Multisim read as it is (``.include`` it). Python callers get the same parts as
:class:`~circuitsim.netlist.circuit.Subcircuit` and :class:`~circuitsim.netlist.circuit.Model`
objects, parsed from that text by the netlist reader, so the file and the objects never
disagree. The designs and their measured figures are in ``docs/parts.md``.

Parts
-----
``OPAMP_IDEAL`` (in+ in- out; ``gain``, default 1e6)
    A high-gain voltage-controlled voltage source.
``TL074`` (in+ in- V+ V- out; ``vos`` 0 V, ``ib`` 0 A, ``ios`` 0 A by default)
    One section of a TL074-like JFET-input op-amp: DC gain 200 V/mV, unity-gain frequency
    3 MHz, slew rate 13 V/us, swing +/-13.5 V into 10 kOhm on +/-15 V.
``D1N4148`` (diode model)
    A 1N4148-like small-signal switching diode.
"""

from __future__ import annotations

import copy
from functools import lru_cache
from pathlib import Path

from circuitsim.netlist.circuit import Model, Subcircuit
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.names import fold

LIBRARY_PATH = Path(__file__).with_name("library") / "parts.lib"
"""Where ``parts.lib`` lives (inside the installed package)."""


def library_text() -> str:
    """The SPICE text of ``parts.lib``."""
    return LIBRARY_PATH.read_text()


@lru_cache(maxsize=1)
def _parsed() -> tuple[dict[str, Subcircuit], dict[str, Model]]:
    # The reader is imported here, not at module level: the library is data the reader reads,
    # and keeping the import late lets either module be loaded first.
    from circuitsim.netlist.reader import parse_netlist

    circuit = parse_netlist(library_text(), str(LIBRARY_PATH), LIBRARY_PATH.parent)
    if circuit.elements:
        names = ", ".join(e.name for e in circuit.elements)
        raise NetlistError(
            f"the part library must hold only .subckt and .model statements; found {names}",
            file=str(LIBRARY_PATH),
        )
    return dict(circuit.subcircuits), dict(circuit.models)


def load_library() -> tuple[dict[str, Subcircuit], dict[str, Model]]:
    """All subcircuits and models of ``parts.lib``, keys lower case.

    Parsed once and cached; the dictionaries returned are fresh deep copies, so callers may
    change them (or put their values into a circuit) without touching the cache.

    Returns
    -------
    subcircuits : dict of str to Subcircuit
    models : dict of str to Model
    """
    subcircuits, models = _parsed()
    return copy.deepcopy(subcircuits), copy.deepcopy(models)


def subcircuit(name: str) -> Subcircuit:
    """A fresh copy of the library subcircuit ``name`` (case-insensitive).

    Raises
    ------
    NetlistError
        If the library has no such subcircuit (the message lists what it has).
    """
    subcircuits, _ = _parsed()
    key = fold(name)
    if key not in subcircuits:
        raise NetlistError(
            f"no subcircuit {name!r} in the part library; it has {', '.join(subcircuits)}",
            file=str(LIBRARY_PATH),
        )
    return copy.deepcopy(subcircuits[key])


def model(name: str) -> Model:
    """A fresh copy of the library model ``name`` (case-insensitive).

    Raises
    ------
    NetlistError
        If the library has no such model (the message lists what it has).
    """
    _, models = _parsed()
    key = fold(name)
    if key not in models:
        raise NetlistError(
            f"no model {name!r} in the part library; it has {', '.join(models)}",
            file=str(LIBRARY_PATH),
        )
    return copy.deepcopy(models[key])
