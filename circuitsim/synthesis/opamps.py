"""Op-amp sections and diodes for the translator's blocks, taken from the part library.

``add_opamp`` puts one op-amp section into a :class:`~circuitsim.netlist.circuit.Circuit` as a
subcircuit call and makes sure everything it needs is there once: the library subcircuit
definition and, for real op-amps, the +/-15 V supplies. ``ensure_diode_model`` does the same for
the 1N4148-like diode model. The parts themselves live in ``netlist/library/parts.lib``.
"""

from __future__ import annotations

from circuitsim.netlist import library
from circuitsim.netlist.circuit import Circuit, SubcircuitCall, VoltageSource
from circuitsim.synthesis.errors import SynthesisError

OPAMP_KINDS = ("ideal", "tl074")
"""Op-amp kinds ``add_opamp`` knows, besides ``"lib:NAME"`` (a user's library subcircuit
``NAME``, put into the circuit first by :func:`circuitsim.synthesis.opamp_library.install`)."""

LIBRARY_PREFIX = "lib:"

SUBCIRCUIT_OF_KIND = {"ideal": "OPAMP_IDEAL", "tl074": "TL074"}
"""Library subcircuit used for each op-amp kind."""

SUPPLY_NODES = ("vcc", "vee")
"""Positive and negative supply nodes of real op-amps."""

SUPPLY_VOLTS = 15.0
"""Supply magnitude for real op-amps, volts (``VCC vcc 0 15``, ``VEE vee 0 -15``)."""

DIODE_MODEL = "D1N4148"
"""Name of the library's 1N4148-like diode model."""


def check_kind(kind: str) -> str:
    """``kind`` lower-cased if it is one of :data:`OPAMP_KINDS` or ``"lib:NAME"``;
    SynthesisError otherwise."""
    key = kind.lower() if isinstance(kind, str) else kind
    if key not in OPAMP_KINDS and not (
        isinstance(key, str) and key.startswith(LIBRARY_PREFIX) and len(key) > len(LIBRARY_PREFIX)
    ):
        raise SynthesisError(
            f"unknown op-amp kind {kind!r}; expected one of {OPAMP_KINDS} or 'lib:NAME'"
        )
    return key


def is_opamp_call(circuit: Circuit, element) -> bool:
    """Whether ``element`` is an op-amp section the generator placed: a call of a part-library
    op-amp, or of a 5-pin subcircuit with the supplies on pins 3 and 4 (a library op-amp)."""
    if not isinstance(element, SubcircuitCall):
        return False
    if element.subcircuit.lower() in (s.lower() for s in SUBCIRCUIT_OF_KIND.values()):
        return True
    definition = circuit.subcircuits.get(element.subcircuit.lower())
    return (
        definition is not None
        and len(definition.ports) == 5
        and tuple(c.lower() for c in element.connections[2:4]) == SUPPLY_NODES
    )


def add_opamp(
    circuit: Circuit,
    name: str,
    non_inverting: str,
    inverting: str,
    output: str,
    kind: str,
    *,
    offset_volts: float = 0.0,
) -> None:
    """Add one op-amp section ``name`` (e.g. ``"XU1A"``) to ``circuit``.

    Parameters
    ----------
    circuit : Circuit
        Changed in place: the call is appended; the library subcircuit definition (key lower
        case) and, for ``tl074``, the supplies ``VCC vcc 0 15`` / ``VEE vee 0 -15`` are added
        if not yet present.
    name : str
        The subcircuit-call name, starting with ``X``.
    non_inverting, inverting, output : str
        Node names (lower case by the circuit's convention).
    kind : {"ideal", "tl074", "lib:NAME"}
        ``ideal``: ``OPAMP_IDEAL`` (in+ in- out), a gain-1e6 VCVS. ``tl074``: the TL074-like
        macromodel, connections (in+, in-, vcc, vee, out). ``lib:NAME``: the circuit's
        subcircuit NAME (a user's library op-amp), connected as the TL074.
    offset_volts : float, optional
        Input offset voltage of a ``tl074`` section, volts (datasheet typical 3e-3); 0 leaves
        the parameter at the library default (0). Not allowed for ``ideal``.

    Raises
    ------
    SynthesisError
        Unknown kind, a name not starting with X, a name already used, or an offset for an
        ideal op-amp.
    """
    key = check_kind(kind)
    if not name[:1].upper() == "X":
        raise SynthesisError(f"op-amp section name {name!r} must start with X (a subcircuit call)")
    if _has_element(circuit, name):
        raise SynthesisError(f"element name {name!r} is already used in the circuit")
    params = {}
    if offset_volts:
        if key != "tl074":
            raise SynthesisError(f"a {key} op-amp has no input offset parameter; use 'tl074'")
        params["vos"] = float(offset_volts)
    if key.startswith(LIBRARY_PREFIX):
        definition = circuit.subcircuits.get(key[len(LIBRARY_PREFIX) :])
        if definition is None:
            raise SynthesisError(
                f"op-amp kind {kind!r}: the circuit has no such subcircuit (install the "
                "library op-amp first)"
            )
        ensure_supplies(circuit)
        connections = (non_inverting, inverting, *SUPPLY_NODES, output)
        circuit.add(SubcircuitCall(name, connections, definition.name, params))
        return
    subckt_name = SUBCIRCUIT_OF_KIND[key]
    if key == "ideal":
        connections = (non_inverting, inverting, output)
    else:
        connections = (non_inverting, inverting, *SUPPLY_NODES, output)
        ensure_supplies(circuit)
    _ensure_subcircuit(circuit, subckt_name)
    circuit.add(SubcircuitCall(name, connections, subckt_name, params))


def ensure_supplies(circuit: Circuit) -> None:
    """Add ``VCC vcc 0 15`` and ``VEE vee 0 -15`` unless sources of those names exist."""
    for source, node, volts in (("VCC", "vcc", SUPPLY_VOLTS), ("VEE", "vee", -SUPPLY_VOLTS)):
        if not _has_element(circuit, source):
            circuit.add(VoltageSource(source, node, "0", dc=volts))


def ensure_diode_model(circuit: Circuit) -> str:
    """Put the 1N4148-like ``.model D1N4148 D(...)`` into ``circuit`` once; return its name."""
    key = DIODE_MODEL.lower()
    if key not in circuit.models:
        circuit.models[key] = library.model(DIODE_MODEL)
    return circuit.models[key].name


def _ensure_subcircuit(circuit: Circuit, name: str) -> None:
    key = name.lower()
    if key not in circuit.subcircuits:
        circuit.subcircuits[key] = library.subcircuit(name)


def _has_element(circuit: Circuit, name: str) -> bool:
    try:
        circuit.element(name)
    except KeyError:
        return False
    return True
