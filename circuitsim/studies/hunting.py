"""The hunting bifurcation diagram: limit-cycle amplitude against speed, swept up then down.

A roller rig turns its speed knob while the wheelset keeps moving. Here each speed step starts
from the previous step's final state, on two paths side by side:

    ode:     the direct solution (mechanics.solve: exact kink handling), state handed on;
    circuit: the equivalent circuit (one translation, one scaling), each step a restamp of the
             speed resistors (R33, R44 for the wheelset) started from every unknown the
             previous run ended with (solver.continuation.transient_from).

Each step runs ``settle + record`` model seconds; its amplitude is max |y| over the last
``record`` seconds (after the settling time). Comparing the two halves of that window says
whether the response still decays, holds a steady cycle or grows. A limit cycle is *present*
where the amplitude is at least ``threshold`` and the response neither decays nor passes
``bound`` (unbounded: the flange-off wheelset above the critical speed, which has no limit
cycle; the next step then starts again from the push).

Without any disturbance, a wheelset at rest stays at rest above the critical speed (its
growth starts from the integrator's round-off, slowly near the critical speed), so a step whose
amplitude fell below ``repush * push`` hands the push itself to the next step: a rig's track
keeps disturbing the wheelset. ``repush = 0`` is strict continuation.

The nonlinear critical speed is read on each path: sweeping up, the first speed with a cycle;
sweeping down, the lowest speed the cycle holds down to. A subcritical bifurcation shows as a
vanishing speed below the appearing one (hysteresis).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from circuitsim.compare.errors import ComparisonError
from circuitsim.compare.values import parse_values
from circuitsim.mechanics.system import System
from circuitsim.studies.hunting_result import (
    DIRECTIONS,
    HuntingBranch,
    HuntingError,
    HuntingResult,
    HuntingSettings,
)

Progress = Callable[[int, int, str], None]
"""Called with (steps done, steps in all, a short message) after each speed step."""

# the two halves of the record window differing by more than this tell growth or decay
STEADY = 0.02


def speed_grid(text: str, option: str = "--speeds") -> np.ndarray:
    """The increasing speeds of ``START:STOP:STEP`` or ``v1,v2,...`` (at least two).

    Raises
    ------
    HuntingError
        Naming ``option``: unparsable text, fewer than two speeds, a list not increasing.
    """
    try:
        speeds = parse_values(text, limit=2000)
    except ComparisonError as exc:
        raise HuntingError(str(exc).replace("--values", option, 1)) from None
    if speeds.size < 2:
        raise HuntingError(f"{option} {text!r}: at least two speeds are needed to sweep")
    # 12 digits: 67.2, not the grid arithmetic's 67.19999999999999 (the CSV writes repr)
    speeds = np.array([float(f"{v:.12g}") for v in speeds])
    if np.any(np.diff(speeds) <= 0):
        raise HuntingError(f"{option} {text!r}: list the speeds in increasing order, each once")
    return speeds


def measure(t: np.ndarray, y: np.ndarray, settings: HuntingSettings) -> tuple[float, str]:
    """Amplitude (max |y| over the record window) and status of one step's samples.

    Parameters
    ----------
    t : ndarray, shape (m,)
        Model seconds from the step's start.
    y : ndarray, shape (m,)
        The state, its unit.
    """
    start, end = settings.settle, settings.settle + settings.record
    middle = start + settings.record / 2
    first = np.abs(y[(t >= start) & (t < middle)])
    second = np.abs(y[(t >= middle) & (t <= end + 1e-12)])
    if not first.size or not second.size:
        raise HuntingError("the record window holds no sample: make --record longer")
    return classify(float(first.max()), float(second.max()), settings)


def classify(first: float, second: float, settings: HuntingSettings) -> tuple[float, str]:
    """Amplitude and status from the peaks of the record window's two halves: unbounded past
    ``bound``, else decaying or growing when they differ by more than :data:`STEADY`."""
    amplitude = max(first, second)
    if not math.isfinite(amplitude) or amplitude > settings.bound:
        return amplitude, "unbounded"
    if second < (1 - STEADY) * first:
        return amplitude, "decaying"
    if second > (1 + STEADY) * first:
        return amplitude, "growing"
    return amplitude, "steady"


def _restart(amplitude: float, status: str, push: float, settings: HuntingSettings) -> bool:
    """Whether the next step starts from the push rather than this step's final state."""
    return status == "unbounded" or amplitude < settings.repush * abs(push)


def ode_branch(
    systems: Sequence[System],
    speeds: np.ndarray,
    direction: str,
    settings: HuntingSettings,
    state: str,
    flange: bool,
    start: np.ndarray | None = None,
    progress: Callable[[str], None] | None = None,
) -> tuple[HuntingBranch, np.ndarray | None, np.ndarray]:
    """One direction on the ODE path: each step ``solve`` from the previous final state.

    Parameters
    ----------
    systems : sequence of System
        One per speed, in the order run; their ``x0`` is the push.
    speeds : ndarray, shape (k,)
    direction : {"up", "down"}
    settings : HuntingSettings
    state : str
        The state measured.
    flange : bool
        Whether the piecewise-linear terms are on (a label).
    start : ndarray, shape (n,), optional
        The state to start from (default: the push).
    progress : callable(message), optional
        Called after each step.

    Returns
    -------
    branch : HuntingBranch
    final : ndarray or None
        The last step's final state, or None when the next step should start from the push.
    peaks : ndarray, shape (n,)
        Largest |x| of every state over the bounded steps (for the circuit's scaling).
    """
    from circuitsim.mechanics.solve import solve

    began = time.perf_counter()
    index = list(systems[0].states).index(state)
    span = (0.0, settings.settle + settings.record)
    amplitudes, statuses, pushed = [], [], []
    peaks = np.zeros(systems[0].n)
    x = start
    for system, speed in zip(systems, speeds, strict=True):
        pushed.append(x is None)
        result = solve(system, span, x0=x, max_step=settings.max_step)
        middle = settings.settle + settings.record / 2  # peaks from the dense output
        amplitude, status = classify(
            result.max_abs(state, settings.settle, middle),
            result.max_abs(state, middle, span[1]),
            settings,
        )
        amplitudes.append(amplitude)
        statuses.append(status)
        if status != "unbounded":
            peaks = np.maximum(peaks, np.max(np.abs(result.x), axis=1))
        x = None if _restart(amplitude, status, system.x0[index], settings) else result.x[:, -1]
        if progress:
            progress(f"ode {direction} {speed:g}: {status}")
    branch = HuntingBranch(
        "ode", direction, flange, np.asarray(speeds, dtype=float),
        np.array(amplitudes), statuses, np.array(pushed), time.perf_counter() - began,
    )  # fmt: skip
    return branch, x, peaks


def circuit_branch(
    circuits: Sequence,
    scale_map,
    speeds: np.ndarray,
    direction: str,
    settings: HuntingSettings,
    state: str,
    push: float,
    flange: bool,
    start=None,
    progress: Callable[[str], None] | None = None,
) -> tuple[HuntingBranch, object]:
    """One direction on the circuit path: each step the speed's circuit (its restamped
    resistors) started from every unknown the previous run ended with
    (:func:`circuitsim.solver.continuation.transient_from`).

    Parameters
    ----------
    circuits : sequence of Circuit
        One per speed, in the order run, of one wiring (a sweep's variants).
    scale_map : ScaleMap
        Maps the state's node back to physical units.
    start : SavedState, optional
        Where to start (default: the circuits' own start, the push).

    Returns
    -------
    branch : HuntingBranch
    final : SavedState or None
        The last run's end, or None when the next step should start from the push.
    """
    from circuitsim.compare.mapping import map_waveforms
    from circuitsim.solver.continuation import transient_from

    began = time.perf_counter()
    amplitudes, statuses, pushed = [], [], []
    saved = start
    for circuit, speed in zip(circuits, speeds, strict=True):
        pushed.append(saved is None)
        tran = circuit.transient
        waves, end = transient_from(circuit, tran.tstep, tran.tstop, tran.tmax, saved)
        t, y = map_waveforms(waves, scale_map, [state])[state]
        amplitude, status = measure(t, y, settings)
        amplitudes.append(amplitude)
        statuses.append(status)
        saved = None if _restart(amplitude, status, push, settings) else end
        if progress:
            progress(f"circuit {direction} {speed:g}: {status}")
    branch = HuntingBranch(
        "circuit", direction, flange, np.asarray(speeds, dtype=float), np.array(amplitudes),
        statuses, np.array(pushed), time.perf_counter() - began,
    )  # fmt: skip
    return branch, saved


def run_hunting(
    system_at: Callable[[float, bool], System],
    speeds: np.ndarray,
    parameter: str,
    unit: str = "",
    settings: HuntingSettings | None = None,
    flanges: Sequence[bool] = (True, False),
    circuit: bool = True,
    linear_critical: float | None = None,
    progress: Progress | None = None,
    state: str | None = None,
) -> HuntingResult:
    """The bifurcation diagram: every flange setting, up then down, ODE then circuit.

    Parameters
    ----------
    system_at : callable(speed, flange) -> System
        The free-response scenario at one speed with the piecewise-linear terms on or off;
        its ``x0`` is the push (``state``'s start value must not be 0 unless the system is
        forced: a stepped sine, :mod:`circuitsim.studies.stepped_sine`).
    speeds : ndarray, shape (k,)
        Increasing; the down sweep runs them in reverse from the up sweep's final state.
    parameter, unit : str
        The speed-like parameter's name and unit.
    settings : HuntingSettings, optional
        ``threshold`` 0 means the push; ``bound`` inf means 100 times the push.
    flanges : sequence of bool
        Flange (all piecewise-linear terms) on, off.
    circuit : bool
        Run the circuit path too (else the ODE path alone).
    linear_critical : float, optional
        The linear critical speed, carried into the result (for the figure).
    progress : callable(done, total, message), optional
    state : str, optional
        The state pushed and measured (default: the first).

    Returns
    -------
    HuntingResult

    Raises
    ------
    HuntingError
        Bad settings, an unknown state, a push of 0, or a model that cannot be built at one
        of the speeds.
    IntegrationError, SolverError, SynthesisError
        From the paths.
    """
    settings = settings or HuntingSettings()
    speeds = np.asarray(speeds, dtype=float)
    if speeds.size < 2 or np.any(np.diff(speeds) <= 0):
        raise HuntingError("the speeds must increase, at least two of them")
    probe = _system(system_at, float(speeds[0]), bool(flanges[0]), parameter, unit)
    state = probe.states[0] if state is None else state
    if state not in probe.states:
        raise HuntingError(f"unknown state {state!r} (states: {', '.join(probe.states)})")
    index = list(probe.states).index(state)
    state_unit = probe.units[index] if probe.units else ""
    push = 0.0 if probe.x0 is None else float(probe.x0[index])
    if push == 0 and not probe.forcing:
        started = [] if probe.x0 is None else [
            f"{s} = {v:g}" for s, v in zip(probe.states, probe.x0, strict=True) if v
        ]  # fmt: skip
        where = f" (the start: {', '.join(started)})" if started else ""
        raise HuntingError(
            f"the push is 0: start {state} away from rest (e.g. --y0 0.005, --state {state}) "
            f"for a free response{where}"
        )
    # a forced response (a stepped sine) may start from rest: no push sets the bounds then
    settings = replace(
        settings,
        threshold=settings.threshold or abs(push),
        bound=settings.bound if math.isfinite(settings.bound) or not push else 100 * abs(push),
    )
    settings.check()
    result = HuntingResult(parameter, unit, state, state_unit, push, settings, linear_critical)
    total = len(flanges) * 2 * speeds.size * (2 if circuit else 1)
    done = [0]

    def step(message: str) -> None:
        done[0] += 1
        if progress:
            progress(done[0], total, message)

    timings = {"ode": 0.0, "synthesis": 0.0, "circuit": 0.0}
    for flange in flanges:
        systems = [_system(system_at, float(v), flange, parameter, unit) for v in speeds]
        peaks = np.zeros(systems[0].n)
        final = None
        for direction in DIRECTIONS:
            order = slice(None) if direction == "up" else slice(None, None, -1)
            branch, final, found = ode_branch(
                systems[order], speeds[order], direction, settings, state, flange, final, step
            )
            peaks = np.maximum(peaks, found)
            result.branches.append(branch)
            timings["ode"] += branch.wall
        if circuit:
            _circuit_paths(result, systems, speeds, flange, peaks, timings, step)
    result.timings = {k: v for k, v in timings.items() if v or k != "kernels"}
    return result


def _circuit_paths(result, systems, speeds, flange, peaks, timings, step) -> None:
    """Both directions on the circuit path, scaled from the ODE path's peaks."""
    from circuitsim.compare.sweep import sweep_circuits
    from circuitsim.solver.compiled import warm_up
    from circuitsim.synthesis.options import SynthesisOptions

    settings = result.settings
    began = time.perf_counter()
    ranges = {s: float(p) if p > 0 else 1.0 for s, p in zip(systems[0].states, peaks, strict=True)}
    options = SynthesisOptions(t_stop=settings.settle + settings.record, ranges=ranges)
    variants = sweep_circuits(systems, options)
    timings["synthesis"] += time.perf_counter() - began
    result.changed[flange] = variants.changed
    ready = warm_up()
    if ready is not None:
        timings["kernels"] = timings.get("kernels", 0.0) + ready
    final = None
    for direction in DIRECTIONS:
        order = slice(None) if direction == "up" else slice(None, None, -1)
        branch, final = circuit_branch(
            variants.circuits[order], variants.scale_map, speeds[order], direction, settings,
            result.state, result.push, flange, final, step,
        )  # fmt: skip
        result.branches.append(branch)
        timings["circuit"] += branch.wall


def _system(system_at, speed: float, flange: bool, parameter: str, unit: str) -> System:
    from circuitsim.mechanics.errors import ModelError

    try:
        return system_at(speed, flange)
    except ModelError as exc:
        raise HuntingError(
            f"{parameter} = {speed:g} {unit}: the model cannot be built there ({exc})"
        ) from exc
