"""How a circuit's node voltages map back to a model's physical states.

The scale file (``FILE.scale.json`` beside a generated netlist) is

    {"time_scale": K, "states": {"<state>": {"node": "<node>", "volts_per_unit": G, "unit": U}}}

meaning: one second of model time takes 1/K seconds in the circuit, and

    state(t) = v(node)(t / K) / G

for every state (the sign is folded into G).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from circuitsim.atomic import write_text_atomic
from circuitsim.inputfile import MAX_SCALE_STATES, SCALE_FILE_BYTES, read_text
from circuitsim.synthesis.errors import SynthesisError


@dataclass(frozen=True)
class StateScale:
    """One state's mapping: node voltage = volts_per_unit * state value.

    Attributes
    ----------
    node : str
        Circuit node carrying the state (lower case).
    volts_per_unit : float
        Volts per physical unit (V/m, V/rad, V/(m/s) ...); negative when the node carries -x.
    unit : str
        The state's SI unit.
    """

    node: str
    volts_per_unit: float
    unit: str = ""


@dataclass(frozen=True)
class ScaleMap:
    """Time scale plus per-state amplitude scales, in the model's state order."""

    time_scale: float
    states: dict[str, StateScale] = field(default_factory=dict)

    def circuit_time(self, model_time: np.ndarray | float) -> np.ndarray | float:
        """Circuit seconds for model seconds."""
        return np.asarray(model_time) / self.time_scale

    def model_time(self, circuit_time: np.ndarray | float) -> np.ndarray | float:
        """Model seconds for circuit seconds."""
        return np.asarray(circuit_time) * self.time_scale

    def to_state(self, state: str, volts: np.ndarray) -> np.ndarray:
        """Physical values of ``state`` from its node's voltages (V)."""
        return np.asarray(volts) / self.states[state].volts_per_unit

    def to_volts(self, state: str, values: np.ndarray) -> np.ndarray:
        """Node voltages (V) for physical values of ``state``."""
        return np.asarray(values) * self.states[state].volts_per_unit

    def to_json(self) -> dict:
        """The scale-file object."""
        return {
            "time_scale": self.time_scale,
            "states": {
                name: {"node": s.node, "volts_per_unit": s.volts_per_unit, "unit": s.unit}
                for name, s in self.states.items()
            },
        }

    @classmethod
    def from_json(cls, data: dict, source: str = "<scale map>") -> ScaleMap:
        """Build from a scale-file object; SynthesisError naming ``source`` and the key if bad.

        Refused: a missing key, a value of the wrong type, a number that is not finite (an
        integer of hundreds of digits included), a time scale that is not positive, a scale of
        0, two states on one node, more than :data:`~circuitsim.inputfile.MAX_SCALE_STATES`
        states.
        """

        def fail(key: str, problem: str) -> SynthesisError:
            return SynthesisError(f"{source}: {key}: {problem}")

        if not isinstance(data, dict):
            raise SynthesisError(f"{source}: malformed scale map (expected a JSON object)")
        for key in ("time_scale", "states"):
            if key not in data:
                raise SynthesisError(f"{source}: missing key {key!r}")
        time_scale = _number(data["time_scale"], "time_scale", fail)
        if time_scale <= 0:
            raise SynthesisError(f"{source}: time_scale must be a positive number")
        entries = data["states"]
        if not isinstance(entries, dict):
            raise fail("states", f"expected an object of states, got {_kind(entries)}")
        if len(entries) > MAX_SCALE_STATES:
            raise fail(
                "states",
                f"{len(entries):,} states, more than {MAX_SCALE_STATES:,} (far beyond any "
                "circuit generated here: each state is an integrator)",
            )
        states = {}
        owners: dict[str, str] = {}  # node -> the state it carries
        for name, entry in entries.items():
            key = f"states.{_shown(name)}"
            if not isinstance(entry, dict):
                raise fail(key, f"expected an object, got {_kind(entry)}")
            if "node" not in entry:
                raise SynthesisError(f"{source}: missing key 'node'")
            if "volts_per_unit" not in entry:
                raise SynthesisError(f"{source}: missing key 'volts_per_unit'")
            node, unit = entry["node"], entry.get("unit", "")
            if isinstance(node, bool) or not isinstance(node, str | int):
                raise fail(f"{key}.node", f"expected a node name, got {_kind(node)}")
            if not isinstance(unit, str):
                raise fail(f"{key}.unit", f"expected a string, got {_kind(unit)}")
            volts = _number(entry["volts_per_unit"], f"{key}.volts_per_unit", fail)
            if volts == 0:
                raise SynthesisError(f"{source}: {key}.volts_per_unit must be nonzero")
            node = str(node).lower()
            if node in owners:  # a circuit carries each state on its own integrator's output
                raise fail(
                    f"{key}.node",
                    f"{_shown(node)} is also the node of states.{_shown(owners[node])} (each "
                    "state has a node of its own)",
                )
            owners[node] = str(name)
            states[str(name)] = StateScale(node=node, volts_per_unit=volts, unit=unit)
        return cls(time_scale=time_scale, states=states)

    def to_text(self) -> str:
        """The scale file's text (indented JSON, ending with a newline)."""
        return json.dumps(self.to_json(), indent=2) + "\n"

    @classmethod
    def from_text(cls, text: str, source: str = "<scale map>") -> ScaleMap:
        """Parse a scale file's text; SynthesisError naming ``source`` (and line) if bad."""
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise SynthesisError(f"{source}:{exc.lineno}: not JSON ({exc.msg})") from None
        except RecursionError:  # json parses nested arrays and objects recursively
            raise SynthesisError(
                f"{source}: not JSON: arrays or objects nested too deeply"
            ) from None
        except ValueError as exc:  # an integer past Python's 4,300-digit limit
            raise SynthesisError(f"{source}: not JSON: {exc}") from None
        return cls.from_json(data, source=source)

    def save(self, path: str | os.PathLike) -> None:
        """Write the scale file atomically (temporary name, then rename)."""
        write_text_atomic(path, self.to_text())

    @classmethod
    def load(cls, path: str | os.PathLike) -> ScaleMap:
        """Read a scale file (at most :data:`~circuitsim.inputfile.SCALE_FILE_BYTES`).

        Raises
        ------
        SynthesisError
            Not a scale file (the message names the file, and the key or line).
        OSError
            The file cannot be read; :class:`~circuitsim.inputfile.InputTooLargeError` (an
            OSError) for one past the limit (a device such as /dev/zero included).
        """
        try:
            text = read_text(path, SCALE_FILE_BYTES, "a scale file")
        except UnicodeDecodeError as exc:
            raise SynthesisError(
                f"{path}: not a scale file (not UTF-8 text: {exc.reason})"
            ) from None
        return cls.from_text(text, source=str(path))


def _number(value, key: str, fail) -> float:
    """``value`` as a finite float; ``fail(key, problem)`` makes the error."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise fail(key, f"expected a number, got {_kind(value)}")
    try:
        number = float(value)
    except OverflowError:  # an integer of hundreds of digits
        raise fail(
            key, f"number too large: an integer of {len(str(abs(value))):,} digits"
        ) from None
    if not math.isfinite(number):
        raise fail(key, f"must be a finite number, got {value}")
    return number


def _kind(value) -> str:
    """What a JSON value is, in words."""
    return {dict: "an object", list: "an array", str: "a string", bool: "a boolean"}.get(
        type(value), "null" if value is None else "a number"
    )


def _shown(name: str) -> str:
    """A state's name for a message, cut to 40 characters."""
    return name if len(name) <= 40 else name[:37] + "..."
