"""The circuit as it runs on the bench: a flat Circuit and the state it has reached.

Each chunk is a ``uic`` transient of the builtin engine from 0 to the chunk's length (circuit
seconds) that starts from every unknown the previous chunk ended with
(:class:`~circuitsim.solver.continuation.Continuation`, assembled once per set of knob
values): the capacitors hold their charge across the boundary as on a real circuit, with
ideal or macromodel op-amps alike; the sine generators get the phase the model time has
reached. Turning a knob swaps in the circuit at
the new values (same wiring, other resistor values or source settings) and keeps the state:
the matrix is restamped, nothing restarts.
"""

from __future__ import annotations

import copy
import math

import numpy as np

from circuitsim.bench.errors import BenchError
from circuitsim.bench.knobs import differences
from circuitsim.netlist.circuit import Sin, VoltageSource
from circuitsim.netlist.names import fold
from circuitsim.solver.continuation import Continuation, initial_state
from circuitsim.solver.engine import flat_circuit
from circuitsim.synthesis.options import SWING_LIMIT
from circuitsim.synthesis.scalemap import ScaleMap
from circuitsim.synthesis.translator import Synthesis

#: Peak |V| (V) of a state node past which a chunk is refused as an overload, by default: the
#: swing of a real build's op-amps (a TL074's on +/-15 V supplies), which clip there, so that
#: past it the circuit no longer computes the model's equations. Ideal op-amps have no rails;
#: a session may lift the limit (``inf``) to follow a linear model's unbounded growth.
OVERLOAD_VOLTS = SWING_LIMIT["tl074"]


class Overload(BenchError):
    """A chunk whose state nodes went past the op-amps' output swing; nothing changed."""


class RunningCircuit:
    """A translated circuit run chunk after chunk from its own final state.

    Parameters
    ----------
    synthesis : Synthesis
        The circuit at the starting knob values; its ``.ic`` values are the first state.
    overload : float
        Peak |V| of a state node past which a chunk is refused (:class:`Overload`; ``inf``:
        never).
    """

    def __init__(self, synthesis: Synthesis, overload: float = OVERLOAD_VOLTS):
        self.overload = overload
        self.scale_map: ScaleMap = synthesis.scale_map
        self.flat = copy.deepcopy(flat_circuit(synthesis.circuit))
        self._set_circuit_values(synthesis)
        self.state = initial_state(self.flat)
        # the integrator output of each state holds -G x (the translator's .ic nodes)
        self.integrators = {}
        for name, scale in self.scale_map.states.items():
            node = f"{scale.node}_neg"
            if node in synthesis.circuit.initial_conditions:
                self.integrators[name] = node

    def _set_circuit_values(self, synthesis: Synthesis) -> None:
        tran = synthesis.circuit.transient
        self.tmax = float(tran.tmax or tran.tstep)
        self.generators = {
            e.name: e.waveform
            for e in self.flat.elements
            if isinstance(e, VoltageSource) and isinstance(e.waveform, Sin)
        }
        self.engine = Continuation(self.flat)

    def restamp(self, synthesis: Synthesis) -> dict[str, tuple[float, float]]:
        """Put in the circuit of ``synthesis`` (new knob values), keeping the state.

        Returns
        -------
        dict of str to (float, float)
            The resistors that changed, (old, new) ohms.

        Raises
        ------
        BenchError
            The new circuit is wired differently or changes a capacitor (nothing changed).
        """
        new = copy.deepcopy(flat_circuit(synthesis.circuit))
        changed = differences(self.flat, new)
        self.flat = new
        self._set_circuit_values(synthesis)
        return changed

    def states(self) -> np.ndarray:
        """The state (SI units, the scale map's order) the next chunk starts from, read from
        the integrator outputs; NaN for a state without one."""
        out = []
        for name, scale in self.scale_map.states.items():
            node = self.integrators.get(name)
            volts = self.state.voltage(node) if node else np.nan
            out.append(-volts / scale.volts_per_unit)
        return np.array(out)

    def push(self, values: dict[str, float]) -> None:
        """Set states (SI units) as an initial-condition kick: each integrator's output, and
        so its capacitor, is set to the state's value; every other unknown keeps its value
        (the first step of the next chunk settles them).

        Raises
        ------
        BenchError
            A state without an integrator, or a value whose node voltage would be past the
            overload limit (or past any float, with ``overload = inf``); nothing changed.
        """
        missing = [name for name in values if name not in self.integrators]
        if missing:
            raise BenchError(f"no integrator holds state {', '.join(missing)}")
        for name, value in values.items():
            scale = self.scale_map.states[name]
            volts = abs(value * scale.volts_per_unit)
            if not (math.isfinite(volts) and volts <= self.overload):
                raise BenchError(
                    f"state {name!r} = {value:g} would put its node {scale.node} at {volts:.4g} V, "
                    f"past the {self.overload:g} V overload limit (the bench's --overload): "
                    f"push at most {self.overload / abs(scale.volts_per_unit):.4g}"
                    if math.isfinite(self.overload)
                    else f"state {name!r} = {value:g} is past any voltage its node {scale.node} "
                    "can hold in the engine's numbers"
                )
        self.state = self.state.with_voltages(
            {
                self.integrators[name]: -value * self.scale_map.states[name].volts_per_unit
                for name, value in values.items()
            }
        )

    def run(self, t_model: float, duration: float, share: float) -> tuple[np.ndarray, dict]:
        """Run the circuit for ``duration`` model seconds from model time ``t_model``.

        Parameters
        ----------
        t_model, duration : float
            Start and length of the chunk, model seconds.
        share : float
            The generators' amplitude as a share of the translated one (the amplitude knob).

        Returns
        -------
        times : ndarray, shape (m,)
            Model times of the engine's accepted points after ``t_model``, s.
        states : dict of str to ndarray, shape (m,)
            Each state at those times, SI units.

        Raises
        ------
        ConvergenceError, RunLimitError
            From the engine (the state is then the one before the chunk).
        Overload
            A state node went past ``overload`` volts during the chunk (the state is then the
            one before the chunk): a real circuit clips there, so the chunk would no longer
            be the model's.
        """
        K = self.scale_map.time_scale
        start = t_model / K
        for name, base in self.generators.items():  # sin(2 pi f t + phase), t reached
            phase = (float(base.phase) + 360.0 * float(base.frequency) * start) % 360.0
            self.engine.set_sine(name, float(base.amplitude) * share, phase)
        waveforms, state = self.engine.run(self.tmax, duration / K, self.tmax, self.state)
        self._check_overload(waveforms, t_model)
        self.state = state
        states = {
            name: self.scale_map.to_state(name, waveforms.signals[f"v({fold(scale.node)})"])
            for name, scale in self.scale_map.states.items()
        }
        return t_model + waveforms.time * K, states

    def _check_overload(self, waveforms, t_model: float) -> None:
        """Raise :class:`Overload` if a state node's |V| went past ``overload``."""
        for name, scale in self.scale_map.states.items():
            signal = waveforms.signals[f"v({fold(scale.node)})"]
            volts = np.abs(signal)
            k = int(np.argmax(volts))
            if not volts[k] <= self.overload:  # NaN counts as past it
                t = t_model + float(waveforms.time[k]) * self.scale_map.time_scale
                value = self.scale_map.to_state(name, signal[k : k + 1])[0]
                raise Overload(
                    f"overload at model time {t:.6g} s: state {name}'s node {scale.node} "
                    f"reached {volts[k]:.4g} V ({name} = {value:.4g}), past the op-amps' "
                    f"{self.overload:g} V swing (a real circuit clips there): the circuit diverges "
                    "at these knob values. Turn a knob (e.g. a lower speed) or push the state "
                    "back, then resume (the overload limit is the bench's --overload)"
                )
