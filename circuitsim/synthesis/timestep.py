"""The netlist's ``.tran`` step: from the fastest mode of any segment, and from the forcing.

A piecewise-linear term is linear on each region its ``|row . x + offset|`` arguments can be
in, with slope ``linear + sum_m side_m gain_m row_m``. A stiff stop is slow while open and fast
in contact; a step taken from the linear part alone (the stop open) leaves the contact mode
with a few points per period (an impact stop 500 times stiffer than the spring: 11 % NRMSD,
docs/translator.md). So the eigenvalues of every region are computed - each combination of
sides that some state can reach (a linear-programming feasibility test, so a dead zone's
impossible "below -eta and above +eta" is not counted) - and the step resolves the fastest of
them. Past ``MAX_REGIONS`` combinations the spectral radius of every region is bounded at once
(Perron-Frobenius: ``rho(A_r) <= rho(|A_r|) <= rho(B)`` for the entrywise bound ``B >= |A_r|``
of all regions), which errs on the short side.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog

from circuitsim.mechanics.system import System

#: Side combinations enumerated one by one; beyond, the Perron-Frobenius bound.
MAX_REGIONS = 256


@dataclass(frozen=True)
class StepChoice:
    """The ``.tran`` maximum step and what set it.

    Attributes
    ----------
    tmax : float
        Circuit seconds (rounded to 2 significant digits).
    frequency : float
        Model Hz resolved with ``points_per_period`` points: the fastest mode (|lambda| / 2 pi)
        or forcing frequency.
    source : str
        In words: ``"mode of the linear part"``, ``"mode of region stop: |x| 1 > 0"``,
        ``"forcing drive"``, ``"bound over 1024 regions"`` or ``"the run length"``.
    """

    tmax: float
    frequency: float
    source: str

    def describe(self, time_scale: float = 1.0) -> str:
        """One line for ``generate`` and ``compare``."""
        scaled = "" if time_scale == 1 else f" (model {self.tmax * time_scale:.3g} s)"
        return (
            f"time step {self.tmax:.2g} s{scaled} set by the {self.source} at "
            f"{self.frequency:.4g} Hz"
        )


def _acting(system: System) -> list:
    """The piecewise-linear terms that act at some time (``t_on`` not infinite)."""
    return [t for t in system.nonlinear if t.t_on is None or math.isfinite(t.t_on)]


def _pieces(system: System) -> list[tuple[str, int, np.ndarray, np.ndarray, float, float]]:
    """(term name, abs index, direction, row, gain, offset) of every acting |x| argument."""
    return [
        (term.name, m, np.asarray(term.direction, float), np.asarray(piece.row, float),
         float(piece.gain), float(piece.offset))
        for term in _acting(system)
        for m, piece in enumerate(term.abs_terms, start=1)
        if piece.gain != 0 and np.any(piece.row)
    ]  # fmt: skip


def _reachable(rows: np.ndarray, offsets: np.ndarray, sides: np.ndarray) -> bool:
    """Whether some x has side_m (row_m . x + offset_m) > 0 for every m (an LP)."""
    n = rows.shape[1]
    # maximize s subject to -side_m (row_m . x + offset_m) + s <= 0, s <= 1
    a_ub = np.hstack((-(sides[:, None] * rows), np.ones((len(sides), 1))))
    b_ub = sides * offsets
    cost = np.zeros(n + 1)
    cost[-1] = -1.0
    bounds = [(None, None)] * n + [(None, 1.0)]
    result = linprog(cost, A_ub=a_ub, b_ub=b_ub, bounds=bounds, method="highs")
    return result.status == 0 and -result.fun > 1e-12 * (1.0 + np.max(np.abs(offsets)))


def _radius(A: np.ndarray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0


def fastest_mode(system: System) -> tuple[float, str]:
    """The largest |eigenvalue| (1/s) of the model without its terms and in every region.

    Returns
    -------
    rate : float
        max |lambda|, 1/s (0 for an empty system).
    source : str
        Which region (or bound) it comes from, in words.
    """
    rate, source = _radius(np.asarray(system.A, dtype=float)), "mode of the linear part"
    terms = _acting(system)
    if not terms:
        return rate, source
    base = np.array(system.A, dtype=float, copy=True)
    for term in terms:
        base += np.outer(term.direction, term.linear)
    pieces = _pieces(system)
    if not pieces:
        region = _radius(base)
        if region > rate:
            rate, source = region, f"mode with {', '.join(t.name for t in terms)} on"
        return rate, source
    if 2 ** len(pieces) > MAX_REGIONS:
        bound = np.abs(base)
        for _, _, direction, row, gain, _ in pieces:
            bound += abs(gain) * np.outer(np.abs(direction), np.abs(row))
        region = _radius(bound)
        if region > rate:
            rate, source = region, f"bound over the 2^{len(pieces)} regions of the |x| terms"
        return rate, source
    rows = np.array([p[3] for p in pieces])
    offsets = np.array([p[5] for p in pieces])
    for sides in itertools.product((1.0, -1.0), repeat=len(pieces)):
        sides = np.array(sides)
        A = base.copy()
        for side, (_, _, direction, row, gain, _) in zip(sides, pieces, strict=True):
            A += side * gain * np.outer(direction, row)
        region = _radius(A)
        if region <= rate * (1 + 1e-9) or not _reachable(rows, offsets, sides):
            continue
        rate = region
        where = ", ".join(
            f"{name} |x| {m} {'>' if side > 0 else '<'} 0"
            for side, (name, m, *_) in zip(sides, pieces, strict=True)
        )
        source = f"mode of the region {where}"
    return rate, source


def choose_step(
    system: System, time_scale: float, t_stop: float, points_per_period: int
) -> StepChoice:
    """``.tran`` maximum step (circuit seconds): the fastest period / ``points_per_period``.

    The fastest period is the shortest of: the fastest mode over all regions
    (:func:`fastest_mode`, |lambda| / 2 pi), each forcing's fastest frequency (a sinusoid's,
    a bump's 1 / duration; a time series is exact between its points, which the engines step
    onto), and t_stop / 20.
    """
    rate, source = fastest_mode(system)
    candidates = [(rate / (2 * np.pi), source), (20.0 / t_stop, "length of the run")]
    for force in system.forcing:
        label = force.name or "input"
        candidates.append((float(force.fastest), f"forcing {label}"))
    frequency, source = max(candidates, key=lambda c: c[0])
    step = 1.0 / (points_per_period * frequency * time_scale)
    # a round number of steps, 2 significant digits, for a readable .tran line
    return StepChoice(float(f"{step:.2g}"), frequency, source)


def bump_spacing(force, error: float) -> float:
    """Sample spacing (model s) of a bump so linear interpolation is within ``error`` of
    its peak: the interpolation error is at most h^2/8 max|u''|."""
    # written as duration * sqrt(...) so a bump of any finite duration gives a finite spacing
    # (pi^2 / duration^2 overflows for a duration past ~1e154 s)
    shape_factor = (2.0 if force.shape == "haversine" else 1.0) * math.pi**2
    return force.duration * math.sqrt(8.0 * error / shape_factor)
