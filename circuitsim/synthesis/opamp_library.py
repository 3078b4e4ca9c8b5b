"""A user's op-amp from a SPICE library file: loading, checking, putting it into a circuit.

The subcircuit must have five pins in the order vendor libraries use (TI, ADI, ST, onsemi
op-amp models): non-inverting input, inverting input, positive supply, negative supply,
output. The generator connects them to (in+, in-, ``vcc``, ``vee``, out) with +/-15 V
supplies, as it does its own TL074.

Checked on loading, each failure a :class:`SynthesisError` naming the file and subcircuit:
the file reads (the netlist reader's errors keep their file and line), the subcircuit exists,
it has five pins, every model and subcircuit it uses is defined, and it behaves as an op-amp
with that pin order (operating points in the builtin engine, +/-15 V supplies, 10 kOhm load):
as a unit-gain follower (out to in-) its output follows in+ at -1 V and +1 V within 50 mV,
and open loop with in+ - in- = +/-0.1 V its output is beyond +/-1 V with that sign. A model
with its inputs or supplies in another order fails instead of silently building a circuit
that saturates.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path

from circuitsim.netlist.circuit import (
    Bjt,
    Circuit,
    Diode,
    Jfet,
    Model,
    Resistor,
    Subcircuit,
    SubcircuitCall,
    Switch,
    VoltageSource,
)
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.names import fold
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.opamps import LIBRARY_PREFIX, SUPPLY_VOLTS

PIN_ORDER = ("non-inverting input", "inverting input", "V+ supply", "V- supply", "output")
FOLLOWER_TOLERANCE = 0.05  # volts: a real op-amp follower is within millivolts
OPEN_LOOP_INPUT = 0.1  # volts of differential input that drive any op-amp far from 0 V


@dataclass
class LibraryOpamp:
    """An op-amp subcircuit with everything it needs from its library file.

    Attributes
    ----------
    name : str
        The subcircuit's name as the file spells it.
    subcircuit : Subcircuit
    models : dict of str to Model
        The file's top-level models the subcircuit uses (keys lower case).
    subcircuits : dict of str to Subcircuit
        The file's other top-level subcircuits it calls (keys lower case).
    source : str
        The library file.
    """

    name: str
    subcircuit: Subcircuit
    models: dict[str, Model] = field(default_factory=dict)
    subcircuits: dict[str, Subcircuit] = field(default_factory=dict)
    source: str = ""

    @property
    def kind(self) -> str:
        """The op-amp kind ``add_opamp`` takes for it (``"lib:name"``)."""
        return LIBRARY_PREFIX + fold(self.name)


def load_opamp(path: str | Path, name: str, check: bool = True) -> LibraryOpamp:
    """Read subcircuit ``name`` (case-insensitive) from library file ``path`` and check it.

    Raises
    ------
    SynthesisError
        The file cannot be read or parsed, has no such subcircuit, the subcircuit has not
        five pins, uses undefined models or subcircuits, or does not follow in a unit-gain
        follower (see the module docstring).
    """
    from circuitsim.netlist.reader import parse_netlist

    path = Path(path)
    where = f"{path}: subcircuit {name}"
    if not path.is_file():
        raise SynthesisError(f"op-amp library {path}: no such file")
    try:
        # the file is included, so it has no title line and its errors name its own lines
        library = parse_netlist(
            f"* op-amp library\n.include {path.resolve()}\n", str(path), str(path.parent)
        )
    except NetlistError as exc:
        raise SynthesisError(f"op-amp library {exc}") from None
    found = library.subcircuits.get(fold(name))
    if found is None:
        have = ", ".join(s.name for s in library.subcircuits.values()) or "none"
        raise SynthesisError(f"{path}: no subcircuit {name!r} (the file defines: {have})")
    where = f"{path}: subcircuit {found.name}"
    if len(found.ports) != 5:
        raise SynthesisError(
            f"{where} has {len(found.ports)} pins ({' '.join(found.ports)}); an op-amp needs 5, "
            f"in this order: {', '.join(PIN_ORDER)}"
        )
    opamp = LibraryOpamp(found.name, copy.deepcopy(found), source=str(path))
    _collect(found, library, opamp, where, [])
    if check:
        _check_follower(opamp, where)
    return opamp


def _collect(sub: Subcircuit, library: Circuit, opamp: LibraryOpamp, where: str, stack) -> None:
    """Top-level models and subcircuits of the file that ``sub`` (or what it calls) uses."""
    for element in sub.elements:
        if isinstance(element, Diode | Jfet | Bjt | Switch):
            key = fold(element.model)
            if key in sub.models or any(key in s.models for s in stack):
                continue
            if key not in library.models:
                raise SynthesisError(
                    f"{where}: {element.name} uses model {element.model!r}, which the file "
                    "does not define"
                )
            opamp.models[key] = copy.deepcopy(library.models[key])
        elif isinstance(element, SubcircuitCall):
            key = fold(element.subcircuit)
            if key in sub.subcircuits or any(key in s.subcircuits for s in stack):
                continue
            called = library.subcircuits.get(key)
            if called is None:
                raise SynthesisError(
                    f"{where}: {element.name} calls subcircuit {element.subcircuit!r}, which "
                    "the file does not define"
                )
            if key not in opamp.subcircuits and key != fold(opamp.name):
                opamp.subcircuits[key] = copy.deepcopy(called)
                _collect(called, library, opamp, where, [*stack, sub])
    for inner in sub.subcircuits.values():
        _collect(inner, library, opamp, where, [*stack, sub])


def install(circuit: Circuit, opamp: LibraryOpamp) -> str:
    """Put the op-amp's subcircuit (and what it uses) into ``circuit``; return its kind.

    Raises
    ------
    SynthesisError
        The circuit already has another subcircuit or model of one of those names.
    """
    for table, additions in (
        (circuit.subcircuits, {fold(opamp.name): opamp.subcircuit, **opamp.subcircuits}),
        (circuit.models, opamp.models),
    ):
        for key, value in additions.items():
            if key in table and table[key] != value:
                raise SynthesisError(
                    f"{opamp.source}: {key} is also a name of the generated circuit's own parts"
                )
            table[key] = copy.deepcopy(value)
    return opamp.kind


def _check_follower(opamp: LibraryOpamp, where: str) -> None:
    """The checks of the module docstring (builtin engine, operating points): a unit-gain
    follower follows, and open loop the output takes the sign of v(in+) - v(in-) (a
    follower with swapped inputs has an unstable equilibrium at out = in that an operating
    point finds, so the follower alone cannot tell the inputs apart)."""
    for volts in (-1.0, 1.0):
        out = _output(opamp, where, ("in", "out"), volts)
        if not abs(out - volts) <= FOLLOWER_TOLERANCE:
            raise SynthesisError(
                f"{where}: as a unit-gain follower at +/-{SUPPLY_VOLTS:g} V it gives {out:.4g} V "
                f"for {volts:g} V in; are its pins in the order {', '.join(PIN_ORDER)}?"
            )
    for volts in (-OPEN_LOOP_INPUT, OPEN_LOOP_INPUT):
        out = _output(opamp, where, ("in", "0"), volts)
        if not out * volts > 0 or abs(out) < 1.0:
            raise SynthesisError(
                f"{where}: open loop with in+ - in- = {volts:g} V its output is {out:.4g} V "
                f"(expected beyond {'+' if volts > 0 else '-'}1 V); are its pins in the order "
                f"{', '.join(PIN_ORDER)}?"
            )


def _output(opamp: LibraryOpamp, where: str, inputs: tuple[str, str], volts: float) -> float:
    """v(out) (V) of the op-amp with in+ at node ``inputs[0]`` driven to ``volts`` and in- at
    node ``inputs[1]`` (``"out"``: a follower), 10 kOhm load, +/-15 V supplies."""
    from circuitsim.solver.engine import operating_point
    from circuitsim.solver.errors import SolverError

    test = Circuit(title="op-amp check")
    install(test, opamp)
    test.add(
        VoltageSource("VCC", "vcc", "0", dc=SUPPLY_VOLTS),
        VoltageSource("VEE", "vee", "0", dc=-SUPPLY_VOLTS),
        VoltageSource("VIN", "in", "0", dc=volts),
        SubcircuitCall("XU", (*inputs, "vcc", "vee", "out"), opamp.subcircuit.name),
        Resistor("RL", "out", "0", 10e3),
    )
    try:
        return float(operating_point(test, probes=["v(out)"])["v(out)"][0])
    except (SolverError, NetlistError) as exc:
        raise SynthesisError(
            f"{where}: the op-amp check did not run in the builtin engine ({exc})"
        ) from None
