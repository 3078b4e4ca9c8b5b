"""A smooth one-argument function as a continuous piecewise-linear curve within a stated error.

The circuit realizes only piecewise-linear functions (sums of |x| blocks), so a smooth term
``f(u)`` (a progressive spring, a saturating creep force) is replaced by a continuous
piecewise-linear curve ``p(u)`` with ``max |f - p| <= bound`` over a stated range of ``u``;
outside the range ``p`` continues with its end slopes.

The breakpoints are chosen by the fit, in two steps repeated with a tightening target:

1. greedy segmentation: from the left end, each segment is the longest whose chord
   (interpolating f at both ends) stays within the target on the fit grid;
2. with those breakpoints fixed, the values at the breakpoints are chosen to minimize the
   largest error on the grid (a small linear program, scipy's HiGHS): for a convex or concave
   piece this halves the chord's error, so the first target tried is about twice the bound.

The first target whose result is within the bound on the check grid wins. Points where the
curve must equal the function (``exact_at``, by default the argument 0 of a model file's fit)
split the range; each part is fitted so, with its pinned ends fixed in the linear program.
The check grid refines the fit grid eight times (so it holds every breakpoint), and the error
reported adds the largest possible excursion between its points, max |f''| h^2 / 8 (f''
estimated from the grid's second differences): the figure is a bound for the whole range,
not a sample.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.optimize import linprog

FIT_INTERVALS = 2048  # fit grid: FIT_INTERVALS + 1 points over the range
CHECK_REFINEMENT = 8  # check grid: this many intervals per fit-grid interval
MAX_SEGMENTS = 40
_ATTEMPTS = 40
_SHRINK = 0.85


class FitError(ValueError):
    """The function cannot be fitted as asked (message says why)."""


@dataclass(frozen=True)
class PiecewiseLinearFit:
    """A continuous piecewise-linear curve through ``(knots, values)``.

    Attributes
    ----------
    knots : ndarray, shape (K + 1,)
        Range ends and the breakpoints between them, increasing, in the argument's unit.
    values : ndarray, shape (K + 1,)
        The curve's values there, in the function's unit.
    max_error : float
        Bound on ``max |f - p|`` over the range (check grid plus the curvature term).
    bound : float
        The error that was asked for.
    check_points : int
        Points of the check grid.
    function : str
        What was fitted, for reports (the model file's expression; may be empty).
    """

    knots: np.ndarray
    values: np.ndarray
    max_error: float
    bound: float
    check_points: int
    function: str = ""

    def summary(self) -> str:
        """One line: what, over which range, how many pieces, the error and its bound."""
        what = f"{self.function!r} " if self.function else ""
        return (
            f"{what}over [{self.knots[0]:.6g}, {self.knots[-1]:.6g}]: {self.segments} pieces, "
            f"max error {self.max_error:.3g} (allowed {self.bound:.3g})"
        )

    @property
    def segments(self) -> int:
        """Number of linear pieces inside the range."""
        return len(self.knots) - 1

    @property
    def breakpoints(self) -> np.ndarray:
        """The interior knots (where the slope changes), shape (K - 1,)."""
        return self.knots[1:-1]

    @property
    def slopes(self) -> np.ndarray:
        """Slope of each piece, shape (K,); the first and last continue outside the range."""
        return np.diff(self.values) / np.diff(self.knots)

    def __call__(self, u: np.ndarray | float) -> np.ndarray:
        """p(u), extended beyond the range with the end slopes."""
        u = np.asarray(u, dtype=float)
        slopes = self.slopes
        inside = np.interp(u, self.knots, self.values)
        below = self.values[0] + slopes[0] * (u - self.knots[0])
        above = self.values[-1] + slopes[-1] * (u - self.knots[-1])
        return np.where(u < self.knots[0], below, np.where(u > self.knots[-1], above, inside))


def fit_piecewise_linear(
    function: Callable[[np.ndarray], np.ndarray],
    lower: float,
    upper: float,
    bound: float,
    max_segments: int = MAX_SEGMENTS,
    exact_at: tuple[float, ...] = (),
) -> PiecewiseLinearFit:
    """Fit ``function`` on ``[lower, upper]`` within ``bound`` (module docstring).

    Parameters
    ----------
    function : callable
        Vectorized: an array of arguments to an array of values (finite).
    lower, upper : float
        The range of the argument, lower < upper.
    bound : float
        Largest allowed ``|f - p|``, in the function's unit (> 0).
    max_segments : int
        Refuse fits that need more pieces than this (each breakpoint costs an |x| block of
        two op-amps in the circuit).
    exact_at : tuple of float
        Arguments in the range where the curve equals the function exactly (each becomes a
        breakpoint; the range is fitted piece by piece between them). The model file pins
        u = 0 by default: a minimax fit is otherwise off by up to ``bound`` at rest, a
        spurious force at the equilibrium.

    Raises
    ------
    FitError
        Bad range, bound or exact point, or no fit within ``max_segments`` pieces.
    """
    if not (np.isfinite(lower) and np.isfinite(upper) and lower < upper):
        raise FitError(f"the range needs lower < upper, got [{lower:g}, {upper:g}]")
    if not (np.isfinite(bound) and bound > 0):
        raise FitError(f"the maximum error must be > 0, got {bound:g}")
    for point in exact_at:
        if not lower <= point <= upper:
            raise FitError(f"exact point {point:g} is outside the range [{lower:g}, {upper:g}]")
    pinned = {float(point) for point in exact_at}
    edges = sorted(pinned | {float(lower), float(upper)})
    knots, values, errors, points = [], [], [], 0
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        piece = _fit_range(function, a, b, bound, max_segments, a in pinned, b in pinned)
        start = 1 if knots else 0  # a joint is the previous piece's last knot
        knots += list(piece[0][start:])
        values += list(piece[1][start:])
        errors.append(piece[2])
        points += piece[3]
    if len(knots) - 1 > max_segments:
        raise FitError(
            f"no piecewise-linear fit within {bound:.3g} with at most {max_segments} segments "
            f"(the pieces between the exact points need {len(knots) - 1}): raise max_error or "
            "max_segments, or narrow the range"
        )
    return PiecewiseLinearFit(np.array(knots), np.array(values), max(errors), bound, points)


def _fit_range(function, lower, upper, bound, max_segments, pin_left, pin_right):
    """(knots, values, error bound, check points) of one range; pinned ends equal f."""
    check = np.linspace(lower, upper, FIT_INTERVALS * CHECK_REFINEMENT + 1)
    f_check = np.asarray(function(check), dtype=float)
    grid, f_grid = check[::CHECK_REFINEMENT], f_check[::CHECK_REFINEMENT]
    h = check[1] - check[0]
    curvature = np.max(np.abs(np.diff(f_check, 2))) / h**2 if len(check) > 2 else 0.0
    between = curvature * h**2 / 8.0
    target = 2.0 * bound
    best = None
    for _ in range(_ATTEMPTS):
        target *= _SHRINK
        knots = _greedy_knots(grid, f_grid, target, max_segments)
        if knots is None:
            break
        values = _minimax_values(grid, f_grid, knots, pin_left, pin_right)
        error = float(np.max(np.abs(np.interp(check, grid[knots], values) - f_check))) + between
        if error <= bound:
            return grid[knots], values, error, len(check)
        best = error if best is None else min(best, error)
    reached = f" (best {best:.3g})" if best is not None else ""
    raise FitError(
        f"no piecewise-linear fit within {bound:.3g} with at most {max_segments} segments"
        f"{reached}: raise max_error or max_segments, or narrow the range"
    )


def _greedy_knots(u: np.ndarray, f: np.ndarray, target: float, limit: int) -> np.ndarray | None:
    """Indices of the knots: from each knot, the farthest next one whose chord is within."""

    def within(i: int, j: int) -> bool:
        piece = slice(i, j + 1)
        chord = f[i] + (f[j] - f[i]) * (u[piece] - u[i]) / (u[j] - u[i])
        return bool(np.max(np.abs(f[piece] - chord)) <= target)

    last = len(u) - 1
    knots = [0]
    while knots[-1] < last:
        i = knots[-1]
        good, step = i + 1, 1
        while good < last and within(i, min(good + step, last)):  # gallop out ...
            good = min(good + step, last)
            step *= 2
        bad = min(good + step, last + 1)
        while bad - good > 1:  # ... then bisect between the last good and the first bad
            middle = (good + bad) // 2
            if within(i, middle):
                good = middle
            else:
                bad = middle
        knots.append(good)
        if len(knots) - 1 > limit:
            return None
    return np.array(knots)


def _minimax_values(
    u: np.ndarray, f: np.ndarray, knots: np.ndarray, pin_left: bool, pin_right: bool
) -> np.ndarray:
    """Values at ``u[knots]`` that minimize max |p - f| over the grid (a linear program);
    a pinned end keeps the function's value."""
    count = len(knots)
    points = len(u)
    # hat-function basis: p(u_i) = (1 - w) v_k + w v_{k+1} on the piece k holding u_i
    piece = np.clip(np.searchsorted(knots, np.arange(points), side="right") - 1, 0, count - 2)
    left, right = u[knots[piece]], u[knots[piece + 1]]
    weight = (u - left) / (right - left)
    rows = np.concatenate([np.arange(points)] * 2)
    columns = np.concatenate([piece, piece + 1])
    basis = sparse.csr_matrix(
        (np.concatenate([1.0 - weight, weight]), (rows, columns)), shape=(points, count)
    )
    ones = sparse.csr_matrix(np.ones((points, 1)))
    # p - f <= e and f - p <= e; minimize e
    a_ub = sparse.vstack([sparse.hstack([basis, -ones]), sparse.hstack([-basis, -ones])])
    b_ub = np.concatenate([f, -f])
    cost = np.zeros(count + 1)
    cost[-1] = 1.0
    bounds = [(None, None)] * count + [(0, None)]
    if pin_left:
        bounds[0] = (f[knots[0]], f[knots[0]])
    if pin_right:
        bounds[count - 1] = (f[knots[-1]], f[knots[-1]])
    result = linprog(cost, A_ub=a_ub.tocsr(), b_ub=b_ub, bounds=bounds, method="highs")
    if not result.success:  # cannot happen for a feasible LP; keep the interpolant then
        return f[knots].copy()
    values = np.array(result.x[:count])
    # exactly the function's value at a pinned end (the solver meets bounds to ~1e-9)
    if pin_left:
        values[0] = f[knots[0]]
    if pin_right:
        values[-1] = f[knots[-1]]
    return values
