"""Frequency response functions of a model and of its circuit, and how far apart they are.

The model's transfer functions come from its region's state matrix
(:mod:`circuitsim.mechanics.frf`); the circuit's from an ``.ac`` sweep of the generated netlist
with ``AC`` on the generators of one forcing input at a time, mapped back through the scale
map: the state is ``v(node) / volts_per_unit`` and a generator carries ``volts_per_unit`` of
its input per unit, so ``v(node) / volts_per_unit`` with a unit input is the receptance.
The circuit runs ``time_scale`` times faster than the model, so a model frequency f is the
circuit frequency ``f * time_scale``.

Read off both: resonance peaks (local maxima of ``|H|``, refined by a parabola in log-log)
with the damping ratio from the half-power bandwidth, ``zeta = (f2 - f1) / (2 f_r)``.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np

from circuitsim.compare.errors import ComparisonError
from circuitsim.mechanics.frf import FrequencyResponse, frequency_response, input_names
from circuitsim.mechanics.system import System
from circuitsim.netlist.circuit import AcSweep, VoltageSource
from circuitsim.synthesis.translator import Synthesis

#: Below this fraction of a transfer function's largest magnitude its phase is rounding:
#: such points are left out of the dB and degree differences.
SIGNIFICANT = 1e-9


@dataclass(frozen=True)
class Resonance:
    """One peak of ``|H|``: frequency (Hz, model time), magnitude (state unit per input
    unit) and the half-power damping ratio (NaN where a half-power point is outside the
    sweep)."""

    frequency: float
    magnitude: float
    damping_ratio: float


def model_sweep(sweep: AcSweep) -> np.ndarray:
    """The model frequencies of ``sweep`` (Hz), on SPICE's grid (what the circuit sweeps)."""
    from circuitsim.solver.ac import ac_frequencies

    return ac_frequencies(sweep)


def circuit_response(
    synthesis: Synthesis,
    system: System,
    sweep: AcSweep,
    engine: str = "builtin",
    ngspice_timeout: float | None = None,
) -> FrequencyResponse:
    """The circuit's transfer functions from each forcing input to each state.

    Parameters
    ----------
    synthesis : Synthesis
        The translated circuit of ``system`` (its generators and scale map).
    system : System
    sweep : AcSweep
        In model frequencies (Hz); the circuit sweeps it times the time scale.
    engine : {"builtin", "ngspice"}
    ngspice_timeout : float, optional
        Seconds.

    Raises
    ------
    ComparisonError
        An input has no generator in the circuit (its amplitude is zero), or the circuit's
        sweep is not the model's grid.
    """
    from circuitsim.compare.case import run_engine

    scale = synthesis.scale_map
    K = scale.time_scale
    circuit_sweep = AcSweep(sweep.variation, sweep.points, sweep.fstart * K, sweep.fstop * K)
    names = input_names(system)
    states = tuple(system.states)
    nodes = [scale.states[s].node for s in states]
    gains = np.array([scale.states[s].volts_per_unit for s in states])
    responses, frequencies = [], model_sweep(sweep)
    for index, name in enumerate(names):
        generators = [g for g in synthesis.generators if g.forcing == index]
        if not generators:
            raise ComparisonError(
                f"the forcing input {name!r} has no generator in the circuit (its amplitude "
                "is zero): give it an amplitude"
            )
        circuit = _driven(synthesis, generators, circuit_sweep)
        if engine == "builtin":
            from circuitsim.solver import ac_analysis

            waves = ac_analysis(circuit, probes=nodes)
        else:
            waves = run_engine(engine, circuit, ngspice_timeout=ngspice_timeout)
        if waves.time.size != frequencies.size or not np.allclose(
            waves.time / K, frequencies, rtol=1e-9
        ):
            raise ComparisonError(f"{engine}: the circuit's sweep is not the model's grid")
        volts = np.array(
            [waves[f"vm({n})"] * np.exp(1j * np.radians(waves[f"vp({n})"])) for n in nodes]
        )
        responses.append(volts / gains[:, None])
    return FrequencyResponse(
        frequencies=frequencies,
        states=states,
        units=tuple(scale.states[s].unit for s in states),
        inputs=names,
        input_units=tuple(getattr(f, "amplitude_unit", "") for f in system.forcing),
        response=np.array(responses),
    )


def _driven(synthesis: Synthesis, generators, sweep: AcSweep):
    """A copy of the circuit with ``AC volts_per_unit`` on ``generators`` (a unit input) and
    no other AC source, analysing ``sweep`` only."""
    circuit = copy.deepcopy(synthesis.circuit)
    amplitude = {g.source.lower(): g.volts_per_unit for g in generators}
    for element in circuit.elements:
        if isinstance(element, VoltageSource):
            volts = amplitude.get(element.name.lower(), 0.0)
            element.ac_magnitude = abs(volts)
            element.ac_phase = 180.0 if volts < 0 else 0.0
    circuit.analyses = [sweep]
    return circuit


def model_response(system: System, sweep: AcSweep, x=None) -> FrequencyResponse:
    """The model's transfer functions on the sweep's grid (:func:`frequency_response`)."""
    return frequency_response(system, model_sweep(sweep), x)


def differences(model: np.ndarray, circuit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Circuit minus model in dB and degrees (wrapped to +-180), NaN where the model's
    magnitude is below SIGNIFICANT of its largest."""
    size = np.abs(model)
    seen = size > SIGNIFICANT * (size.max() if size.size else 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        db = np.where(seen, 20 * np.log10(np.abs(circuit) / size), np.nan)
        turn = np.degrees(np.angle(circuit / model))
    return db, np.where(seen, turn, np.nan)


def departure(
    frequencies: np.ndarray, model: np.ndarray, circuit: np.ndarray, db: float, degrees: float
) -> float | None:
    """The lowest frequency (Hz) at which the circuit is more than ``db`` dB or ``degrees``
    from the model; None when it never is over the sweep."""
    d_db, d_deg = differences(model, circuit)
    beyond = (np.abs(d_db) > db) | (np.abs(d_deg) > degrees)
    hits = np.flatnonzero(np.nan_to_num(beyond, nan=False))
    return float(frequencies[hits[0]]) if hits.size else None


def resonances(frequencies: np.ndarray, response: np.ndarray) -> list[Resonance]:
    """The peaks of ``|response|`` inside the sweep, with half-power damping ratios."""
    size = np.abs(response)
    out = []
    if size.size < 3:
        return out
    peaks = np.flatnonzero((size[1:-1] > size[:-2]) & (size[1:-1] >= size[2:])) + 1
    logs_f, logs_h = np.log(frequencies), np.log(np.maximum(size, 1e-300))
    for k in peaks:
        # vertex of the parabola through the three points in log-log
        x, y = logs_f[k - 1 : k + 2], logs_h[k - 1 : k + 2]
        a, b, c = np.polyfit(x - x[1], y, 2)
        shift = -b / (2 * a) if a < 0 else 0.0
        peak_f = float(np.exp(x[1] + shift))
        peak_h = float(np.exp(c - b * b / (4 * a))) if a < 0 else float(size[k])
        half = peak_h / math.sqrt(2.0)
        low = _crossing(frequencies, size, k, half, -1)
        high = _crossing(frequencies, size, k, half, +1)
        zeta = (high - low) / (2 * peak_f) if low is not None and high is not None else math.nan
        out.append(Resonance(peak_f, peak_h, zeta))
    return out


def _crossing(frequencies, size, start: int, level: float, step: int) -> float | None:
    """Where ``size`` first falls below ``level`` walking from ``start`` by ``step``
    (log-log interpolation), or None if it does not inside the sweep."""
    k = start
    while 0 <= k + step < size.size:
        if size[k + step] < level:
            s0, s1 = math.log(size[k]), math.log(size[k + step])
            f0, f1 = math.log(frequencies[k]), math.log(frequencies[k + step])
            return float(np.exp(f0 + (math.log(level) - s0) / (s1 - s0) * (f1 - f0)))
        k += step
    return None
