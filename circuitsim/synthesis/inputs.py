"""The forcing as voltage sources: a SIN source per sinusoid, a PWL source per other input.

Each input u_j(t) entering along ``direction`` becomes one grounded generator carrying
``sign * volts_per_unit * u_j`` (a second, negated one where some direction entry has the
other sign) and one resistor per state it enters. A time series or step is written point for
point (a jump gets a short rise, ``JUMP_RISE`` of the ``.tran`` step); a smooth bump is
sampled so that linear interpolation stays within ``SAMPLING_ERROR`` of its peak; times are
divided by the time scale K. Points past the end of the run are left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from circuitsim.mechanics.system import Bump, PiecewiseLinearInput, Sinusoid
from circuitsim.netlist.circuit import Pwl, Sin, VoltageSource
from circuitsim.synthesis.eseries import floor_to_series
from circuitsim.synthesis.timestep import bump_spacing

#: Largest linear-interpolation error of a sampled smooth input, relative to its peak
#: (50 times below the 0.5 % NRMSD target).
SAMPLING_ERROR = 1e-4

#: A jump of a time series or step is written as a ramp this fraction of the .tran step long
#: (the direct solution jumps; the difference in the response is of this relative order).
JUMP_RISE = 1e-3


def source_volts_per_unit(force, system, G: np.ndarray, swing: float) -> float:
    """Volts per unit of the input's generator.

    When its unit is a state's (the wheelset's track displacement, in metres like y) it is
    scaled like that state, so the paper's R17 = R31 in every scaling; otherwise its peak is
    brought to ``swing`` (an E24 scale), so that a force of 3 kN is not a 3 kV generator.
    """
    like = [j for j, unit in enumerate(system.units) if unit and unit == force.amplitude_unit]
    if like:
        return float(G[like[0]])
    peak = force.peak
    return floor_to_series(swing / peak, "E24") if peak > 0 else 1.0


def pwl_points(force, volts: float, K: float, t_stop: float, tmax: float):
    """(circuit time s, volts) points of a non-sinusoidal input over [0, t_stop] model s."""
    if isinstance(force, Bump):
        h = bump_spacing(force, SAMPLING_ERROR)
        count = max(2, math.ceil(force.duration / h) + 1)
        times = force.start + np.linspace(0.0, force.duration, count)
        values = force._inside(times)
        values[0] = values[-1] = 0.0
    else:
        times = np.asarray(force.times, dtype=float).copy()
        values = np.asarray(force.values, dtype=float)
        rise = JUMP_RISE * tmax * K
        for k in range(1, len(times)):  # a jump becomes a short ramp
            if times[k] <= times[k - 1]:
                times[k] = times[k - 1] + rise
    keep = (times > 0) & (times < t_stop)
    inside = np.flatnonzero(keep)
    if inside.size == 0:
        # the whole run before, between or after the points: the value there, held
        grid = np.array([0.0])
    else:
        # the value at 0 (interpolated), the points in the run, and the first point past it
        last = min(inside[-1] + 1, len(times) - 1)
        grid = np.concatenate(([0.0], times[inside[0] : last + 1]))
    u = force.value(grid) if isinstance(force, Bump) else np.interp(grid, times, values)
    return tuple(
        (float(f"{t / K:.12g}"), float(f"{volts * v:.12g}")) for t, v in zip(grid, u, strict=True)
    )


@dataclass(frozen=True)
class Generator:
    """One voltage source of a forcing input.

    Attributes
    ----------
    source : str
        The voltage source's name (``VXFG1``).
    forcing : int
        Index of the input in ``System.forcing``.
    volts_per_unit : float
        Its volts per unit of the input, signed (negative for the negated generator).
    """

    source: str
    forcing: int
    volts_per_unit: float


def add_forcing(
    system, circuit, names, inputs, make_input, G, K, options, t_stop, tmax
) -> list[Generator]:
    """One generator per forcing input (a negated one when an entry has the other sign) and a
    resistor into each integrator it enters (``make_input(name, node, gain, target, role)``
    appended to ``inputs[state]``). Returns the generators, in the circuit's order."""
    generators = []
    for k, force in enumerate(system.forcing, start=1):
        direction = np.asarray(force.direction, dtype=float)
        used = np.flatnonzero(direction)
        if used.size == 0 or force.peak == 0:
            continue
        volts = source_volts_per_unit(force, system, G, options.swing)
        key = getattr(force, "name", "") or f"forcing{k}"
        first_sign = np.sign(direction[used[0]])
        sources = {}
        for sign in (first_sign, -first_sign):
            if not np.any(np.sign(direction[used]) == sign):
                continue
            name = names.forcing_source(k, key, negated=sign != first_sign)
            node = name.lower()
            if isinstance(force, Sinusoid):
                waveform = Sin(0.0, sign * volts * force.amplitude, force.frequency * K, 0.0,
                               0.0, math.degrees(force.phase))  # fmt: skip
            elif isinstance(force, PiecewiseLinearInput | Bump):
                waveform = Pwl(pwl_points(force, sign * volts, K, t_stop, tmax))
            else:
                raise TypeError(f"unknown forcing {type(force).__name__}")
            circuit.add(VoltageSource(name, node, "0", waveform=waveform))
            generators.append(Generator(name, k - 1, float(sign * volts)))
            sources[sign] = node
        for i in used:
            target = system.states[i]
            inputs[target].append(
                make_input(
                    names.forcing_resistor(target, k, key),
                    sources[np.sign(direction[i])],
                    K * G[i] * abs(float(direction[i])) / volts,
                    float(direction[i]),
                    f"forcing {k} -> {target} integrator (direction[{target}])",
                )
            )
    return generators
