"""Amplitude and time scaling: how many volts stand for one unit of each state.

With node voltage u_i = G_i x_i and circuit time tau = t / K, the model's

    dx_i/dt = sum_j A_ij x_j + ...

becomes du_i/dtau = sum_j (K G_i A_ij / G_j) u_j + ..., so every coefficient the circuit must
realize is the model's, multiplied by K G_i / G_j. ``auto`` scaling picks G_i so the state's
peak over the run (from the direct solution, or a user-given range) reaches the target swing;
``unity`` keeps G_i = 1 V per SI unit, the paper's mapping.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from circuitsim.mechanics.errors import IntegrationError
from circuitsim.mechanics.limits import Budget, BudgetExhausted, guarded_method
from circuitsim.mechanics.solve import solve
from circuitsim.mechanics.system import Sinusoid, System
from circuitsim.synthesis.bounds import fit_blocks, fit_spread
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.eseries import floor_to_series
from circuitsim.synthesis.options import SynthesisOptions


@dataclass(frozen=True)
class Scaling:
    """The chosen scales.

    Attributes
    ----------
    volts_per_unit : ndarray, shape (n,)
        G_i, volts per SI unit of state i (positive: the mapped node carries +x).
    peaks : ndarray, shape (n,)
        Peak magnitude of each state over the run (SI units) that the scales were set from.
    time_scale : float
        K.
    warnings : tuple of str
    """

    volts_per_unit: np.ndarray
    peaks: np.ndarray
    time_scale: float
    warnings: tuple[str, ...] = ()


def direct_solution(
    system: System, t_stop: float, max_wall_time: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate the model over [0, t_stop] for its peaks (not a reference-grade solution).

    At most :data:`MAX_SCALING_STEPS` steps and ``max_wall_time`` seconds (default
    :data:`MAX_SCALING_WALL_TIME`; :class:`SynthesisOptions` ``scaling_wall_time``), else a
    SynthesisError saying where it stopped.

    Returns
    -------
    t : ndarray, shape (m,)
        Seconds.
    x : ndarray, shape (n, m)
        States.
    """
    x0 = np.zeros(system.n) if system.x0 is None else np.asarray(system.x0, dtype=float)
    fastest = _fastest_frequency(system, t_stop)
    # peaks only: modest tolerances, but sampled densely enough (40 points per fastest period)
    # that a peak between samples is missed by less than 0.3 %
    samples = int(min(200_000, max(2_000, 40 * fastest * t_stop)))
    t = np.linspace(0.0, t_stop, samples)
    if any(not isinstance(f, Sinusoid) for f in system.forcing):
        # a step or time series: the solver that restarts at the input's corners, within the
        # same limits (its kink events cost more than a plain run on a model with many |x|
        # terms, so only here)
        try:
            result = solve(system, (0.0, t_stop), rtol=1e-6, atol=1e-12, method="RK45",
                           max_step=1.0 / (8.0 * fastest), x0=x0, max_steps=MAX_SCALING_STEPS,
                           max_wall_time=max_wall_time or MAX_SCALING_WALL_TIME)  # fmt: skip
        except IntegrationError as exc:
            raise SynthesisError(f"direct solution for the scaling failed: {exc}") from None
        return t, result.sol(t)
    # a piecewise-linear term far stiffer than the linear part (not in ``fastest``) makes the
    # adaptive steps tiny: the same limits as the direct solution's end it with a message
    budget = Budget(MAX_SCALING_STEPS, max_wall_time or MAX_SCALING_WALL_TIME)
    try:
        result = solve_ivp(
            _finite(system.rhs),
            (0.0, t_stop),
            x0,
            method=guarded_method("RK45", budget),
            rtol=1e-6,
            atol=1e-12,
            max_step=1.0 / (8.0 * fastest),
            t_eval=t,
        )
    except BudgetExhausted as exhausted:
        spent = (
            f"{budget.steps - 1:,} steps" if exhausted.limit == "steps"
            else f"{budget.elapsed:.3g} s"
        )  # fmt: skip
        raise SynthesisError(
            f"the direct solution that sets the scales stopped at t = {exhausted.t:.6g} s of "
            f"{t_stop:g} s after {spent} (steps of {exhausted.step:.3g} s: a stiff term, "
            "perhaps a piecewise-linear one far stiffer than the linear part): give every "
            "state's range (--range STATE=PEAK) or --scaling unity, or a shorter --tstop"
        ) from None
    if not result.success:
        raise SynthesisError(f"direct solution for the scaling failed: {result.message}")
    return result.t, result.y


def _finite(rhs):
    """``rhs`` refusing a non-finite derivative (scipy would step on with a NaN step size)."""

    def checked(t: float, x: np.ndarray) -> np.ndarray:
        dx = rhs(t, x)
        if not math.isfinite(float(np.sum(dx))):
            raise SynthesisError(
                f"the direct solution that sets the scales overflows at t = {t:.6g} s: give "
                "every state's range (--range STATE=PEAK) or --scaling unity"
            )
        return dx

    return checked


MAX_SCALING_STEPS = 200_000
"""Most steps the scaling's direct solution may take (refused at once when 8 per period of the
fastest frequency, over the run, exceed it): the wheelset's default run takes about 600. A
forcing of 1e300 Hz would otherwise keep it busy for ever."""

MAX_SCALING_WALL_TIME = 60.0
"""Default wall-time limit of the scaling's direct solution, s (a stiff piecewise-linear term
can make its explicit steps a billionth of the run)."""


def _fastest_frequency(system: System, t_stop: float) -> float:
    """The fastest frequency (Hz) the scaling's solution must resolve; refuses a run that
    would take more than MAX_SCALING_STEPS steps.

    A forcing of amplitude 0 (or entering no state) moves nothing and does not count.

    Raises
    ------
    SynthesisError
        Naming the frequency, its source and what to do instead.
    """
    sources = [
        (float(f.fastest), f"the forcing {f.name or ''} at {float(f.fastest):.3g} Hz")
        for f in system.forcing
        if f.peak != 0 and np.any(np.asarray(f.direction) != 0)
    ]
    eigen = np.linalg.eigvals(system.A) if system.n else np.zeros(0)
    if eigen.size:
        rate = float(np.max(np.abs(eigen))) / (2 * np.pi)
        sources.append((rate, f"an eigenvalue of the linear part at {rate:.3g} Hz"))
    fastest, source = max(sources + [(1.0 / t_stop, "the run's length")], key=lambda s: s[0])
    steps = 8.0 * fastest * t_stop
    if not steps <= MAX_SCALING_STEPS:
        raise SynthesisError(
            f"the direct solution that sets the scales would need about {steps:.3g} steps over "
            f"{t_stop:g} s ({source}; at most {MAX_SCALING_STEPS:,}): give every state's "
            "range (--range STATE=PEAK) or --scaling unity, or a shorter --tstop"
        )
    return fastest


def choose_scaling(
    system: System,
    options: SynthesisOptions,
    t_stop: float,
    trajectory: tuple[np.ndarray, np.ndarray] | None = None,
) -> Scaling:
    """Volts per unit for every state, from ``options.scaling`` and ``options.ranges``.

    ``trajectory`` is the direct solution (t, x) if already computed (else it is computed
    here when peaks are needed).
    """
    unknown = set(options.ranges) - set(system.states)
    if unknown:
        raise SynthesisError(
            f"ranges given for unknown state(s) {', '.join(sorted(unknown))}; "
            f"the model's states are {', '.join(system.states)}"
        )
    if options.scaling == "unity":
        ones = np.ones(system.n)
        return Scaling(ones, np.full(system.n, math.nan), options.time_scale)
    warnings: list[str] = []
    x = None  # the direct solution, when the scales need it
    if len(options.ranges) == system.n:
        peaks = np.array([options.ranges[s] for s in system.states], dtype=float)
    else:
        if trajectory is None:
            trajectory = direct_solution(system, t_stop, options.scaling_wall_time)
        _, x = trajectory
        peaks = np.max(np.abs(x), axis=1)
        for i, name in enumerate(system.states):
            if name in options.ranges:
                peaks[i] = options.ranges[name]
    gains = np.empty(system.n)
    for i, name in enumerate(system.states):
        if not math.isfinite(peaks[i]):
            raise SynthesisError(
                f"state {name} grows without bound in the direct solution over {t_stop:g} s "
                f"(peak {peaks[i]}): give its range (--range {name}=PEAK), or a shorter --tstop"
            )
        if not (peaks[i] > 0 and math.isfinite(options.swing / float(peaks[i]))):
            # a peak of 1e-320 is zero for every purpose: swing / peak is infinite
            warnings.append(
                f"state {name} stays at zero over the run (peak {peaks[i]:.3g}); scaled 1 V "
                "per unit (give its range to choose another scale)"
            )
            gains[i] = 1.0
            continue
        # a readable scale (E24 value) just below the one that reaches the swing exactly
        gains[i] = floor_to_series(options.swing / peaks[i], "E24")
    fit_blocks(system, options, gains, peaks, x, warnings)
    fit_spread(system, options, gains, warnings)
    return Scaling(gains, peaks, options.time_scale, tuple(warnings))
