"""How a circuit's node voltages map back to a model's physical states.

The scale file (``FILE.scale.json`` beside a generated netlist) is

    {"time_scale": K, "states": {"<state>": {"node": "<node>", "volts_per_unit": G, "unit": U}}}

meaning: one second of model time takes 1/K seconds in the circuit, and

    state(t) = v(node)(t / K) / G

for every state (the sign is folded into G).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from circuitsim.atomic import write_text_atomic
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
        """Build from a scale-file object; SynthesisError naming ``source`` and the key if bad."""
        try:
            time_scale = float(data["time_scale"])
            states = {
                str(name): StateScale(
                    node=str(entry["node"]).lower(),
                    volts_per_unit=float(entry["volts_per_unit"]),
                    unit=str(entry.get("unit", "")),
                )
                for name, entry in data["states"].items()
            }
        except KeyError as exc:
            raise SynthesisError(f"{source}: missing key {exc.args[0]!r}") from None
        except (TypeError, ValueError, AttributeError) as exc:
            raise SynthesisError(f"{source}: malformed scale map ({exc})") from None
        if not np.isfinite(time_scale) or time_scale <= 0:
            raise SynthesisError(f"{source}: time_scale must be a positive number")
        for name, s in states.items():
            if not np.isfinite(s.volts_per_unit) or s.volts_per_unit == 0:
                raise SynthesisError(f"{source}: states.{name}.volts_per_unit must be nonzero")
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
        return cls.from_json(data, source=source)

    def save(self, path: str | os.PathLike) -> None:
        """Write the scale file atomically (temporary name, then rename)."""
        write_text_atomic(path, self.to_text())

    @classmethod
    def load(cls, path: str | os.PathLike) -> ScaleMap:
        """Read a scale file."""
        return cls.from_text(Path(path).read_text(), source=str(path))
