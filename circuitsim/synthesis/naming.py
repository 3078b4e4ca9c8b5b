"""Part and node names: the paper's where the model file gives them, generated otherwise.

The model file's ``[circuit]`` table (``System.circuit_hints``) may name parts::

    [circuit]
    integrators = { y = "U1A", ... }      # op-amp section of each state's integrator
    inverters = { y = "U1B", ... }        # ... and of its inverter
    capacitors = { y = "C1", ... }        # integrator capacitor
    switches = { flange = "S1" }          # the switch of a piecewise-linear term
    sources = { track = "XFG1" }          # the generator of a forcing term
    [circuit.resistors]                   # input resistors, by integrator then input
    y_dot = { y = "R31", flange = "R3", track = "R17" }

Inputs are keyed by a state name (linear term), a piecewise-linear term's name, a forcing
term's name (``forcing<k>`` for an unnamed k-th enabled forcing, 1-based) or ``constant``.
Without a hint the same rule generates a name, with states numbered from 1:
``R<i><j>`` for state j into integrator i (``R<i>_<j>`` past 9 states), ``R<i>F<k>`` for forcing
k, ``R<i>N<t>`` for nonlinear term t, ``R<i>B`` for the constant, ``C<i>``, op-amp sections
``U<p><A-D>`` two per state in order (integrator, inverter), ``S<t>`` (``S<t>_<i>`` when a
term enters several states), sources ``FG<k>``. SPICE wants a type letter first, so an op-amp
section ``U1A`` becomes the subcircuit instance ``XU1A`` and a generator ``XFG1`` the voltage
source ``VXFG1``; a hinted name that already starts with the right letter is kept.
"""

from __future__ import annotations

import re

from circuitsim.mechanics.system import System
from circuitsim.synthesis.errors import SynthesisError

SECTIONS = "ABCD"


def node_name(text: str) -> str:
    """A safe lower-case node name from a state or term name."""
    name = re.sub(r"[^0-9a-z_]", "_", text.lower())
    return name if name and name != "0" else f"n_{name}"


def _with_letter(letter: str, name: str) -> str:
    """``name`` with the SPICE type ``letter`` in front unless it already starts with it."""
    return name if name[:1].upper() == letter else letter + name


class PartNames:
    """Names for one system's parts; every name handed out is checked for uniqueness."""

    def __init__(self, system: System) -> None:
        self.system = system
        self.hints = dict(system.circuit_hints or {})
        self._index = {name: i for i, name in enumerate(system.states)}
        self._used: dict[str, str] = {}
        for key in ("integrators", "inverters", "capacitors", "switches", "sources", "resistors"):
            value = self.hints.get(key, {})
            if not isinstance(value, dict):
                raise SynthesisError(f"[circuit].{key} in the model file must be a table")

    def _claim(self, name: str, what: str) -> str:
        key = name.lower()
        if key in self._used:
            raise SynthesisError(
                f"part name {name!r} is used twice ({self._used[key]} and {what}); "
                "check the model file's [circuit] table"
            )
        self._used[key] = what
        return name

    def _number(self, state: str) -> str:
        i = self._index[state] + 1
        return str(i)

    def _pair(self, target: str, source_number: str) -> str:
        i = self._number(target)
        sep = "_" if self.system.n > 9 else ""
        return f"{i}{sep}{source_number}"

    # --- op-amps and capacitors ---------------------------------------------------------

    def opamp_section(self, state: str, role: str) -> str:
        """Subcircuit instance name of a state's ``"integrator"`` or ``"inverter"``."""
        hint = self.hints.get(role + "s", {}).get(state)
        if hint is None:
            slot = 2 * self._index[state] + (0 if role == "integrator" else 1)
            hint = f"U{slot // 4 + 1}{SECTIONS[slot % 4]}"
        return self._claim(_with_letter("X", str(hint)), f"{role} of {state}")

    def capacitor(self, state: str) -> str:
        hint = self.hints.get("capacitors", {}).get(state) or f"C{self._number(state)}"
        return self._claim(_with_letter("C", str(hint)), f"capacitor of {state}")

    # --- resistors ----------------------------------------------------------------------

    def input_resistor(self, target: str, key: str, generated: str) -> str:
        """Input resistor of ``target``'s integrator for input ``key``."""
        table = self.hints.get("resistors", {}).get(target, {})
        hint = table.get(key) if isinstance(table, dict) else None
        name = str(hint) if hint is not None else generated
        return self._claim(_with_letter("R", name), f"input {key} of {target}")

    def linear_resistor(self, target: str, source: str) -> str:
        return self.input_resistor(target, source, f"R{self._pair(target, self._number(source))}")

    def forcing_resistor(self, target: str, k: int, key: str) -> str:
        """Resistor of forcing number k (1-based), hinted under ``key`` (its name)."""
        return self.input_resistor(target, key, f"R{self._pair(target, f'F{k}')}")

    def nonlinear_resistor(self, target: str, term: str, t: int) -> str:
        return self.input_resistor(target, term, f"R{self._pair(target, f'N{t}')}")

    def constant_resistor(self, target: str) -> str:
        return self.input_resistor(target, "constant", f"R{self._number(target)}B")

    def inverter_resistors(self, state: str) -> tuple[str, str]:
        """(input, feedback) resistors of a state's inverter."""
        i = self._number(state)
        return (
            self._claim(f"RI{i}A", f"inverter input of {state}"),
            self._claim(f"RI{i}B", f"inverter feedback of {state}"),
        )

    # --- switches and sources -----------------------------------------------------------

    def switch(self, term: str, t: int, target: str, several: bool) -> str:
        """Switch of term ``term`` (number t) into ``target``'s integrator."""
        hint = self.hints.get("switches", {}).get(term)
        suffix = f"_{self._number(target)}" if several else ""
        if isinstance(hint, dict):
            name = str(hint[target]) if target in hint else f"S{t}{suffix}"
        elif hint is not None:
            name = f"{hint}{suffix}"
        else:
            name = f"S{t}{suffix}"
        return self._claim(_with_letter("S", name), f"switch of {term} into {target}")

    def forcing_source(self, k: int, key: str, negated: bool = False) -> str:
        """Generator of forcing number k (1-based), hinted under ``key`` (its name)."""
        hint = self.hints.get("sources", {}).get(key) or f"FG{k}"
        name = _with_letter("V", str(hint)) + ("N" if negated else "")
        return self._claim(name, f"generator of forcing {k}")

    def generic(self, name: str, what: str) -> str:
        """Claim a name built by a block (summers, DC sources, switch controls)."""
        return self._claim(name, what)
