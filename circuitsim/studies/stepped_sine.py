"""Nonlinear response curves: a stepped-sine sweep up then down, on the ODE and the circuit.

As on a shaker, the forcing frequency steps up, each step starting from the previous step's
final state, then steps back down from the top's; each step runs ``settle + record`` model
seconds and its amplitude is max |state| over the last ``record`` seconds. This is the hunting
diagram's continuation (:func:`circuitsim.studies.hunting.run_hunting`) with the forcing
frequency as the stepped parameter: the ODE path hands its state on, the circuit path
restamps the generators and starts from every unknown the last run ended with.

A hardening system (the wheelset's flange contact, a Duffing spring) leans its resonance to
higher frequencies: sweeping up, the amplitude follows the upper branch and drops at a jump;
sweeping down it stays low and jumps up at a lower frequency. A jump is a step whose amplitude
is more than :data:`JUMP` times (or less than 1/JUMP times) the previous one's, where the up
and down sweeps disagree (:func:`jumps`); its frequency is the midpoint of the two steps.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from circuitsim.mechanics.system import System
from circuitsim.studies.hunting import Progress, run_hunting
from circuitsim.studies.hunting_result import (
    DIRECTIONS,
    PATHS,
    HuntingBranch,
    HuntingResult,
    HuntingSettings,
)

#: The amplitude ratio between consecutive steps that counts as a jump.
JUMP = 1.5
#: Where the up and down sweeps' amplitudes differ by more than this fraction, the response
#: depends on the sweep's direction (two steady states): jumps sit at that region's edges.
HYSTERESIS = 0.1


@dataclass(frozen=True)
class Jump:
    """A jump of one branch: between ``low`` and ``high`` Hz (consecutive steps), its
    frequency their midpoint, ``ratio`` the later step's amplitude over the earlier's."""

    low: float
    high: float
    ratio: float

    @property
    def frequency(self) -> float:
        """Hz, the midpoint of the two steps."""
        return 0.5 * (self.low + self.high)


def run_stepped_sine(
    system_at: Callable[[float, bool], System],
    frequencies: np.ndarray,
    settings: HuntingSettings | None = None,
    flanges: Sequence[bool] = (True,),
    circuit: bool = True,
    progress: Progress | None = None,
    state: str | None = None,
) -> HuntingResult:
    """The response curves: every flange setting, up then down, ODE then circuit.

    Parameters
    ----------
    system_at : callable(frequency, flange) -> System
        The forced scenario at one forcing frequency (Hz) with the piecewise-linear terms on
        or off; its ``x0`` is where the first step starts (rest is fine).
    frequencies : ndarray, shape (k,)
        Increasing, Hz; the down sweep runs them in reverse from the up sweep's end.
    settings : HuntingSettings, optional
        ``settle``/``record`` in model seconds; ``repush`` is not used (no push).
    state : str, optional
        The state measured (default: the first).

    Returns
    -------
    HuntingResult
        With ``parameter`` ``"f"``; its branches' ``speeds`` are the frequencies.
    """
    settings = settings or HuntingSettings(repush=0.0)
    return run_hunting(
        system_at, frequencies, "f", "Hz", settings, flanges, circuit, None, progress, state
    )


def jumps(
    branch: HuntingBranch, other: HuntingBranch | None = None, factor: float = JUMP
) -> list[Jump]:
    """The branch's jumps, in the order swept.

    A jump is a step whose amplitude is more than ``factor`` times (or less than 1/factor
    times) the previous one's, at the edge of the region where the sweep depends on its
    direction: ``other``, the same path swept the other way, differs there by more than
    :data:`HYSTERESIS` at one of the two steps. Without ``other`` every such step counts (a
    steep but single-valued resonance on a coarse grid then counts too).
    """
    a, f = branch.amplitude, branch.speeds
    twin = None
    if other is not None:
        at = {float(v): float(x) for v, x in zip(other.speeds, other.amplitude, strict=True)}
        twin = np.array([at.get(float(v), np.nan) for v in f])
    out = []
    for k in range(1, a.size):
        if not (a[k - 1] > 0 and a[k] > 0):
            continue
        ratio = float(a[k] / a[k - 1])
        if not (ratio > factor or ratio < 1 / factor):
            continue
        if twin is not None:
            pair = [k - 1, k]
            apart = np.abs(twin[pair] - a[pair]) > HYSTERESIS * np.maximum(twin[pair], a[pair])
            if not apart.any():
                continue
        low, high = sorted((float(f[k - 1]), float(f[k])))
        out.append(Jump(low, high, ratio))
    return out


def relative_difference(result: HuntingResult, direction: str, flange: bool) -> float:
    """The largest |circuit - ODE| / ODE amplitude over a branch's steps (NaN without both
    paths)."""
    ode, circuit = (result.branch(p, direction, flange) for p in PATHS)
    if ode is None or circuit is None:
        return math.nan
    return float(np.max(np.abs(circuit.amplitude - ode.amplitude) / np.abs(ode.amplitude)))


def summary(result: HuntingResult) -> dict:
    """Jumps per path and direction and the circuit's agreement, JSON-ready."""
    flanges = {}
    for flange in sorted({b.flange for b in result.branches}, reverse=True):
        entry: dict = {}
        for direction in DIRECTIONS:
            for path in PATHS:
                branch = result.branch(path, direction, flange)
                other = result.branch(path, "down" if direction == "up" else "up", flange)
                if branch is not None:
                    found = jumps(branch, other)
                    entry[f"{path}_{direction}_jumps_hz"] = [j.frequency for j in found]
            entry[f"circuit_vs_ode_{direction}"] = relative_difference(result, direction, flange)
        flanges["on" if flange else "off"] = entry
    return {
        "state": result.state,
        "unit": result.state_unit,
        "frequencies_hz": sorted({float(v) for b in result.branches for v in b.speeds}),
        "settle_s": result.settings.settle,
        "record_s": result.settings.record,
        "flange": flanges,
        "timings_s": dict(result.timings),
    }


def plot_response_curves(
    result: HuntingResult, path: str | os.PathLike, dpi: float | None = None
) -> None:
    """Amplitude against forcing frequency: ODE (lines) and circuit (markers), up (solid,
    upward triangles) and down (dashed, downward), one panel per flange setting, jumps
    marked. House style (:mod:`circuitsim.figure_style`: lengths in mm); ``dpi`` of a PNG
    (default the house style's)."""
    from circuitsim.figure_style import style_context

    with style_context():
        _plot_response_curves(result, path, dpi)


def _plot_response_curves(result: HuntingResult, path, dpi) -> None:
    from circuitsim.figure_style import DOUBLE_COLUMN, SERIES, display_unit, new_figure, save_figure

    flanges = sorted({b.flange for b in result.branches}, reverse=True)
    fig = new_figure(DOUBLE_COLUMN, 0.6 + 2.8 * len(flanges))
    axes = fig.subplots(len(flanges), 1, squeeze=False)[:, 0]
    shown, factor = display_unit(result.state_unit)
    unit = f" ({shown})" if shown else ""
    for ax, flange in zip(axes, flanges, strict=True):
        for b in (b for b in result.branches if b.flange == flange):
            up = b.direction == "up"
            color = SERIES[0 if up else 1]["color"]
            amplitude = np.asarray(b.amplitude, dtype=float) * factor
            if b.path == "ode":
                ax.plot(b.speeds, amplitude, "-" if up else "--", color=color,
                        label=f"ODE, {b.direction}")  # fmt: skip
            else:
                ax.plot(b.speeds, amplitude, "^" if up else "v", color=color, ms=5,
                        fillstyle="none", ls="none", label=f"circuit, {b.direction}")  # fmt: skip
            if b.path == "ode":
                other = result.branch(b.path, "down" if up else "up", flange)
                for jump in jumps(b, other):
                    ax.axvline(jump.frequency, color=color, lw=0.8, ls=":")
        ax.set_ylabel(f"amplitude of {result.state}{unit}")
        ax.set_title(f"piecewise-linear terms {'on' if flange else 'off'}")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1))
    axes[-1].set_xlabel("forcing frequency (Hz, model time)")
    fig.suptitle("stepped sine: steady amplitude, frequency swept up then down")
    save_figure(fig, path, dpi)
