"""A bench session: the circuit run in chunks beside the direct ODE solution with the same
knob history, the traces of both, and the history of every change.

Both sides step together. A chunk of ``chunk`` model seconds runs the circuit from its own
final state (:class:`~circuitsim.bench.running.RunningCircuit`) and integrates the ODE
(:func:`~circuitsim.mechanics.solve.solve`) from its own final state with the same
piecewise-constant knob values; both are sampled on one uniform grid (``sample`` model
seconds), where the running NRMSD between them is kept. A knob change or a push made while a
chunk runs waits for it to end and applies from that boundary: ``t_applied``.

Two locks: changes (a chunk, a knob, a push) take turns on one; what readers see (time,
traces, sums, history, knob values) is swapped under ``lock``, held only for that, so that
reading the state never waits for a chunk to be computed (the first chunk of a process may
compile the kernels: minutes on a loaded machine).
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections import deque
from dataclasses import dataclass, fields

import numpy as np

from circuitsim.bench.errors import BenchError
from circuitsim.bench.knobs import (
    BenchSetup,
    Knob,
    differences,
    find_knobs,
    fixed_ranges,
    synthesize_at,
)
from circuitsim.bench.running import OVERLOAD_VOLTS, RunningCircuit
from circuitsim.mechanics.solve import solve
from circuitsim.netlist.circuit import Resistor
from circuitsim.solver.engine import flat_circuit

#: Tolerances of the ODE beside the circuit: rtol 1e-8 keeps it within 2e-6 % NRMSD of a
#: 1e-10 solution (five orders inside the 0.5 % it is compared at) with 0.61 times the
#: right-hand-side evaluations (10 s of the wheelset at 57 m/s in 0.1 s chunks).
ODE_RTOL, ODE_ATOL = 1e-8, 1e-12

#: Samples kept for the trace API and the export (the oldest are dropped past it): 1e6
#: samples at the default 2 ms are 33 min of model time.
MAX_SAMPLES = 1_000_000


@dataclass
class _Chunk:
    """One chunk's samples: model times (s), circuit and ODE states (SI, shape (n, m))."""

    t: np.ndarray
    circuit: np.ndarray
    ode: np.ndarray


class BenchSession:
    """The circuit of ``setup`` running beside its ODE, with knobs.

    Parameters
    ----------
    setup : BenchSetup
        Model, scenario and translator options.
    chunk : float
        Model seconds per chunk: a knob change waits at most this long (> 0).
    sample : float
        Model seconds between trace samples (> 0; rounded so that a chunk holds a whole
        number of them).
    overload : float
        Peak |V| of a state node past which a chunk is refused and the session stays before
        it (V, > 0; default :data:`~circuitsim.bench.running.OVERLOAD_VOLTS`, a real op-amp's
        swing; ``inf``: never, as for the paper's unbounded linear growth).

    Raises
    ------
    BenchError
        A setup the bench cannot run (time-series forcing, inductors, values the translator
        refuses).
    """

    def __init__(
        self,
        setup: BenchSetup,
        chunk: float = 0.1,
        sample: float = 0.002,
        overload: float = OVERLOAD_VOLTS,
    ):
        if not (math.isfinite(chunk) and chunk > 0 and math.isfinite(sample) and sample > 0):
            raise BenchError(f"chunk and sample must be positive, got {chunk:g} and {sample:g}")
        if not overload > 0:
            raise BenchError(f"the overload limit must be a positive voltage, got {overload:g}")
        self.setup = setup
        self.chunk = chunk
        self.per_chunk = max(1, round(chunk / sample))
        self.sample = chunk / self.per_chunk
        self.lock = threading.RLock()  # what readers see; held briefly
        self._changing = threading.Lock()  # a chunk, a knob change or a push at a time
        self.parameters = dict(setup.parameters)
        self.switches = dict(setup.switches)
        first = synthesize_at(setup, self.parameters, self.switches, setup.options, True).synthesis
        self.warnings = list(first.warnings)
        self.options = fixed_ranges(first, setup.options)
        synthesis, self.pots = synthesize_at(setup, self.parameters, self.switches, self.options)
        if synthesis.scale_map != first.scale_map:
            raise BenchError("the translator did not keep the scales of the first circuit")
        self.circuit = RunningCircuit(synthesis, overload)
        self.scale_map = synthesis.scale_map
        self.knobs: list[Knob] = find_knobs(setup, self.options, synthesis)
        self.system = setup.system(self.parameters, self.switches)
        self.states = tuple(self.system.states)
        self.units = tuple(self.system.units)
        self.x_ode = np.array([setup.x0.get(s, 0.0) for s in self.states], dtype=float)
        self.t = 0.0
        self.resistors = self._resistor_values()
        start = self.circuit.states()
        #: The circuit's state (SI units, ``states`` order) at model time ``t``.
        self.circuit_state = start
        self._chunks: deque[_Chunk] = deque()
        self._samples = 0
        self._append(_Chunk(np.zeros(1), start[:, None], self.x_ode[:, None].copy()))
        self._sums = np.zeros((2, len(self.states)))  # squared error, count
        self._low = self.x_ode.copy()
        self._high = self.x_ode.copy()
        self._accumulate(self._chunks[0])
        self.started = time.monotonic()
        self.history: list[dict] = [
            {
                "t": 0.0,
                "wall": 0.0,
                "kind": "start",
                "knobs": self.knob_values(),
                "state": dict(zip(self.states, map(float, self.x_ode), strict=True)),
            }
        ]
        self.steps = 0

    # --- knobs -------------------------------------------------------------------------

    def knob_values(self) -> dict[str, float | bool]:
        """Every knob's current value (parameters in their unit, switches as bools)."""
        out: dict[str, float | bool] = {}
        for knob in self.knobs:
            if knob.kind == "switch":
                out[knob.name] = bool(self.switches[knob.name])
            else:
                out[knob.name] = float(self.parameters[knob.parameter])
        return out

    def _resistor_values(self) -> dict[str, float]:
        """Ohms of every resistor a number knob sets."""
        parts = {p for k in self.knobs if k.kind == "number" for p in k.parts}
        return {
            e.name: float(e.resistance)
            for e in self.circuit.flat.elements
            if e.name in parts and isinstance(e, Resistor)
        }

    def pot_settings(self) -> dict[str, dict]:
        """Each potentiometer-realized resistor (``--speed-range``): its fixed part and
        potentiometer (names, ohms) and the dial's rotation fraction (0..1) now."""
        return {
            pot.resistor: {"fixed_part": pot.fixed_part, "fixed": pot.fixed,
                           "pot_part": pot.pot_part, "pot": pot.pot,
                           "dial": pot.setting.fraction}
            for pot in self.pots
        }  # fmt: skip

    def _parse_knobs(self, values: dict) -> tuple[dict, dict]:
        """New parameters and switches from a request's knob values.

        Raises
        ------
        BenchError
            Not an object, an unknown knob, a switch that is not true/false, a number that is
            not finite.
        """
        if not isinstance(values, dict) or not values:
            raise BenchError('expected a JSON object of knob values, e.g. {"speed": 57}')
        by_name = {k.name: k for k in self.knobs}
        parameters, switches = dict(self.parameters), dict(self.switches)
        for name, value in values.items():
            knob = by_name.get(name)
            if knob is None:
                raise BenchError(f"unknown knob {name!r}; the knobs are {', '.join(by_name)}")
            if knob.kind == "switch":
                if not isinstance(value, bool):
                    raise BenchError(f"knob {name!r} is a switch: true or false, got {value!r}")
                switches[name] = value
            else:
                if (
                    isinstance(value, bool)
                    or not isinstance(value, int | float)
                    or not (math.isfinite(value))
                ):
                    raise BenchError(f"knob {name!r} needs a finite number, got {value!r}")
                if name == "freq" and not 0 <= value <= 0.5 / self.sample:  # the trace's Nyquist
                    raise BenchError(
                        f"knob 'freq' = {value:g} Hz is outside 0..{0.5 / self.sample:g} Hz (half "
                        f"the rate of the trace's samples, every {self.sample:g} s)"
                    )
                parameters[knob.parameter] = float(value)
        return parameters, switches

    def set_knobs(self, values: dict) -> float:
        """Turn knobs; they act from the next chunk boundary, from the state reached.

        Parameters
        ----------
        values : dict
            Knob name to value (``{"speed": 57, "flange": False}``).

        Returns
        -------
        float
            The model time (s) from which the new values act.

        Raises
        ------
        BenchError
            A bad name or value, or values the circuit cannot realize by turning resistors
            and switches (nothing changes then).
        """
        with self._changing:
            parameters, switches = self._parse_knobs(values)
            synthesis, pots = synthesize_at(self.setup, parameters, switches, self.options)
            system = self.setup.system(parameters, switches)
            if synthesis.scale_map != self.scale_map:
                raise BenchError("these values change the circuit's scales")
            moved = differences(self.circuit.flat, flat_circuit(synthesis.circuit))
            self._refuse_silent(values, parameters, system, moved)
            changed = self.circuit.restamp(synthesis)
            return self._knobs_changed(values, parameters, switches, system, pots, changed)

    def _refuse_silent(self, values: dict, parameters: dict, system, moved: dict) -> None:
        """Refuse a parameter knob (not the generator's ``freq``, ``amplitude``) turned to a
        new value that moves no resistor: the circuit would run on as before.

        Raises
        ------
        BenchError
            Naming the knob, its parameter and why: the model's linear part changes but no
            resistor follows, or the parameter changes nothing the model computes.
        """
        if moved:
            return
        by_name = {k.name: k for k in self.knobs}
        for name in values:
            knob = by_name[name]
            if knob.kind != "number" or name in ("freq", "amplitude"):
                continue
            old, new = self.parameters[knob.parameter], parameters[knob.parameter]
            if old == new:
                continue
            unit = f" {knob.unit}" if knob.unit else ""
            turned = f"knob {name!r} ({knob.parameter} {old:g} -> {new:g}{unit})"
            if not np.array_equal(system.A, self.system.A):
                raise BenchError(
                    f"{turned} changes the model's linear part but no resistor of the circuit "
                    "follows it; nothing changed"
                )
            if _same_forcing(system.forcing, self.system.forcing):
                raise BenchError(
                    f"{turned} changes no resistor and nothing else the model computes "
                    f"({knob.parameter} enters none of its coefficients); nothing changed"
                )

    def _knobs_changed(self, values, parameters, switches, system, pots, changed) -> float:
        """What readers see of a knob change (the circuit is restamped); returns t."""
        with self.lock:
            self.parameters, self.switches, self.system = parameters, switches, system
            self.pots = pots
            self.resistors = self._resistor_values()
            self.history.append(
                {
                    "t": self.t,
                    "wall": self._wall(),
                    "kind": "knobs",
                    "values": dict(values),
                    "resistors": {name: list(pair) for name, pair in changed.items()},
                }
            )
            return self.t

    def set_state(self, values: dict) -> float:
        """Push: set states (SI units) of both the circuit and the ODE at the next boundary.

        Returns
        -------
        float
            The model time (s) of the push.

        Raises
        ------
        BenchError
            Not an object, an unknown state, a value that is not a finite number.
        """
        if not isinstance(values, dict) or not values:
            raise BenchError('expected a JSON object of state values, e.g. {"y": 0.005}')
        for name, value in values.items():
            if name not in self.states:
                raise BenchError(f"unknown state {name!r}; the states are {', '.join(self.states)}")
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float)
                or not (math.isfinite(value))
            ):
                raise BenchError(f"state {name!r} needs a finite number, got {value!r}")
        with self._changing:
            self.circuit.push({k: float(v) for k, v in values.items()})
            with self.lock:
                for name, value in values.items():
                    self.x_ode[self.states.index(name)] = float(value)
                self.circuit_state = self.circuit.states()
                self.history.append(
                    {"t": self.t, "wall": self._wall(), "kind": "state", "values": dict(values)}
                )
                return self.t

    # --- running -------------------------------------------------------------------------

    def step(self) -> None:
        """Run one chunk of circuit and ODE from the current state and knob values.

        Raises
        ------
        ConvergenceError, RunLimitError, IntegrationError
            From the engine or the ODE solver; the session stays at the chunk's start.
        """
        with self._changing:  # readers go on reading the state before the chunk meanwhile
            t0 = self.t
            t1 = (self.steps + 1) * self.chunk  # no float drift over hours of chunks
            grid = t0 + self.sample * np.arange(1, self.per_chunk + 1)
            grid[-1] = t1
            share = self._generator_share()
            start = self.circuit.states()
            times, states = self.circuit.run(t0, self.chunk, share)
            times = np.concatenate(([t0], times))
            circuit = np.array(
                [
                    np.interp(grid, times, np.concatenate(([start[i]], states[name])))
                    for i, name in enumerate(self.states)
                ]
            )
            ode = solve(self.system, (t0, t1), rtol=ODE_RTOL, atol=ODE_ATOL, x0=self.x_ode)
            chunk = _Chunk(grid, circuit, np.atleast_2d(ode.sol(grid)))
            with self.lock:
                self.x_ode = ode.x[:, -1].copy()
                self.circuit_state = self.circuit.states()
                self._append(chunk)
                self._accumulate(chunk)
                self.steps += 1
                self.t = t1

    def _generator_share(self) -> float:
        """The amplitude knob's value as a share of the amplitude the circuit was built with."""
        name = self.setup.amplitude_parameter
        if name is None:
            return 1.0
        return self.parameters[name] / self.setup.reference_amplitude()

    def _append(self, chunk: _Chunk) -> None:
        self._chunks.append(chunk)
        self._samples += len(chunk.t)
        while self._samples > MAX_SAMPLES and len(self._chunks) > 1:
            self._samples -= len(self._chunks.popleft().t)

    def _accumulate(self, chunk: _Chunk) -> None:
        """Running NRMSD sums: squared circuit-ODE error and the ODE's range, per state."""
        self._sums[0] += np.sum((chunk.circuit - chunk.ode) ** 2, axis=1)
        self._sums[1] += chunk.t.size
        self._low = np.minimum(self._low, chunk.ode.min(axis=1))
        self._high = np.maximum(self._high, chunk.ode.max(axis=1))

    def _wall(self) -> float:
        return time.monotonic() - self.started

    # --- reading -----------------------------------------------------------------------

    def nrmsd(self) -> dict[str, float]:
        """Running %NRMSD of the circuit against the ODE over the whole session, per state
        (RMS of the difference over the ODE's range, as :func:`~circuitsim.compare.signals.
        nrmsd_percent`; NaN while a state has had no range)."""
        with self.lock:
            rms = np.sqrt(self._sums[0] / self._sums[1])
            span = self._high - self._low
        return {
            name: float(100 * rms[i] / span[i]) if span[i] > 0 else math.nan
            for i, name in enumerate(self.states)
        }

    def trace(self, since: float = -math.inf, last: float | None = None) -> dict:
        """Samples after model time ``since`` (s): ``{"t": [...], "states": {...}, "ode":
        {...}}``, SI units. ``last``: at most this many model seconds, the newest."""
        with self.lock:
            chunks = [c for c in self._chunks if c.t[-1] > since]
        if not chunks:
            empty = {name: [] for name in self.states}
            return {"t": [], "states": empty, "ode": dict(empty)}
        t = np.concatenate([c.t for c in chunks])
        circuit = np.concatenate([c.circuit for c in chunks], axis=1)
        ode = np.concatenate([c.ode for c in chunks], axis=1)
        keep = t > since
        if last is not None:
            keep &= t > t[-1] - last
        return {
            "t": t[keep].tolist(),
            "states": {name: circuit[i, keep].tolist() for i, name in enumerate(self.states)},
            "ode": {name: ode[i, keep].tolist() for i, name in enumerate(self.states)},
        }

    def trace_csv(self) -> str:
        """The kept samples as CSV: ``time`` then each state's circuit and ODE columns (SI
        units, header names with units)."""
        data = self.trace()
        header = ["time_s"]
        columns = [data["t"]]
        for name, unit in zip(self.states, self.units, strict=True):
            header += [f"{name}_circuit_{unit}", f"{name}_ode_{unit}"]
            columns += [data["states"][name], data["ode"][name]]
        lines = [",".join(header)]
        lines += [",".join(f"{v:.10g}" for v in row) for row in zip(*columns, strict=True)]
        return "\n".join(lines) + "\n"

    def history_json(self) -> str:
        """The knob and state changes with their model and wall times (s), as JSON text."""
        with self.lock:
            return json.dumps({"chunk_s": self.chunk, "events": self.history}, indent=1)


def _same_forcing(a: tuple, b: tuple) -> bool:
    """Whether two Systems' forcing terms are the same (arrays compared by value)."""
    if len(a) != len(b) or any(type(x) is not type(y) for x, y in zip(a, b, strict=True)):
        return False
    for x, y in zip(a, b, strict=True):
        for field in fields(x):
            u, v = getattr(x, field.name), getattr(y, field.name)
            if isinstance(u, np.ndarray) or isinstance(v, np.ndarray):
                if not np.array_equal(u, v):
                    return False
            elif u != v:
                return False
    return True
