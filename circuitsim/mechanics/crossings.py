"""Where a step of the direct solution leaves the side of a kink (mechanics.solve).

Between two crossings each ``|row . x + offset|`` argument has a side (+1 or -1). After every
accepted step, :meth:`KinkArguments.first_exit` looks at each argument's interpolant over the
step, a polynomial in t of the method's dense-output degree (:func:`dense_form`), for the first
time it goes beyond the rounding level on the other side:

1. For scipy's Runge-Kutta interpolants a bound read off their coefficients clears the step
   at once when every argument stays on its side (``_clear``).
2. Otherwise the interpolant is sampled at degree + 1 Chebyshev-Lobatto points; the
   polynomial through them is the interpolant (up to rounding). Its coefficients bound it,
   then a 32-interval grid bounds each interval by its chord less the most the polynomial can
   bend below it (``_exit``).
3. A crossing inside a grid interval on which the argument is monotonic is located there;
   anything else is settled exactly: the argument at the ends and at the real roots of its
   derivative, monotonic between two neighbours (``_lowest``).
4. The crossing is then located by Brent's method on the interpolant (``_root``).

The rounding level of an argument is 16 machine epsilons of its scale (``|row| . |x| +
|offset|``) plus its change over the step times the step's relative time resolution: what a
crossing located to the time's resolution may leave on the wrong side.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import chebyshev
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, Radau
from scipy.optimize import brentq

_EPS = float(np.finfo(float).eps)
_ROUNDING = 16.0 * _EPS
"""Rounding level of a kink argument, per unit of its scale (see the module docstring)."""

# the largest |x^a (1 - x)^b| on [0, 1] multiplying DOP853's interpolant terms F_1 ... F_6
# (term i carries a = ceil((i + 1) / 2) factors x and b = floor((i + 1) / 2) factors 1 - x)
_DOP853_WEIGHTS = np.array(
    [
        (a**a * b**b) / (a + b) ** (a + b)
        for a, b in ((math.ceil((i + 1) / 2), (i + 1) // 2) for i in range(1, 7))
    ]
)

# degree in t of each method's dense output (BDF and LSODA: their highest order)
_DENSE_DEGREE = ((DOP853, 7), (RK45, 4), (RK23, 3), (Radau, 3), (BDF, 5), (LSODA, 12))


def dense_form(method: type) -> tuple[int, str]:
    """Degree in t of an OdeSolver class's dense output (7 for an unknown one), and the form
    of its coefficients that :meth:`KinkArguments.first_exit` can bound (``"dop853"``, ``"rk"``, or
    ``""``: none, the interpolant is sampled)."""
    degree = next((degree for base, degree in _DENSE_DEGREE if issubclass(method, base)), 7)
    form = "dop853" if issubclass(method, DOP853) else ""
    form = "rk" if issubclass(method, (RK23, RK45)) else form
    return degree, form


@dataclass(frozen=True)
class _Chebyshev:
    """Chebyshev sampling of a step's interpolant, for a polynomial of ``degree`` in t.

    Attributes
    ----------
    points : ndarray, shape (degree + 1,)
        Chebyshev-Lobatto points as fractions of the step, increasing from 0 to 1.
    to_coefficients : ndarray, shape (degree + 1, degree + 1)
        ``values @ to_coefficients.T`` gives the Chebyshev coefficients (on s in [-1, 1])
        of the polynomial through ``values`` at ``points``.
    grid : ndarray, shape (GRID + 1, degree + 1)
        ``grid @ coefficients``: the polynomial at GRID + 1 evenly spaced s.
    bend : ndarray, shape (degree + 1,)
        ``bend @ |coefficients|`` bounds how far the polynomial falls below the chord
        between two neighbouring grid points (spacing d: d^2 / 8 times the largest second
        derivative, ``|T_i''| <= i^2 (i^2 - 1) / 3`` on [-1, 1]).
    start_slope : ndarray, shape (degree + 1,)
        ``start_slope @ coefficients``: the derivative at s = -1 (``T_i'(-1) = (-1)^(i+1)
        i^2``), which with 4 ``bend`` bounds the first interval from its start alone.
    """

    points: np.ndarray
    to_coefficients: np.ndarray
    grid: np.ndarray
    bend: np.ndarray
    start_slope: np.ndarray

    GRID = 32

    @classmethod
    @functools.cache
    def of_degree(cls, degree: int) -> _Chebyshev:
        """The sampling for polynomials of ``degree`` (cached)."""
        s = -np.cos(np.pi * np.arange(degree + 1) / degree)
        order = np.arange(degree + 1, dtype=float)
        spacing = 2.0 / cls.GRID
        return cls(
            points=(s + 1.0) / 2.0,
            to_coefficients=np.linalg.inv(chebyshev.chebvander(s, degree)),
            grid=chebyshev.chebvander(np.linspace(-1.0, 1.0, cls.GRID + 1), degree),
            bend=spacing**2 / 8.0 * order**2 * (order**2 - 1.0) / 3.0,
            start_slope=(-1.0) ** (order + 1) * order**2,
        )


class KinkArguments:
    """The kink arguments of one phase, ``R x + offsets``, with their sides.

    Parameters
    ----------
    R : ndarray, shape (k, n)
        One row per ``|.|`` argument.
    offsets : ndarray, shape (k,)
        Their offsets, in the arguments' units.
    form : (int, str)
        The integrator's dense output (:func:`dense_form`).

    Attributes
    ----------
    sides : ndarray, shape (k,)
        The side (+1 or -1) each argument is on in this phase; set by the phase.
    """

    def __init__(self, R: np.ndarray, offsets: np.ndarray, form: tuple[int, str]):
        self.R, self.offsets = R, offsets
        self.scale_rows, self.scale_offsets = np.abs(R), np.abs(offsets)
        degree, self.interpolant = form
        self.chebyshev = _Chebyshev.of_degree(degree)
        self.sides = np.ones(len(offsets))

    def rounding(self, x: np.ndarray, change: np.ndarray) -> np.ndarray:
        """Rounding level of every argument at state ``x``, shape (k,), argument units.

        ``change`` is how much each argument can move within the time resolution's worth
        of steps (its rate times the time, or its change over a step times the step count
        to reach t).
        """
        return _ROUNDING * (self.scale_rows @ np.abs(x) + self.scale_offsets + change)

    def first_exit(self, t_old: float, t_new: float, dense) -> tuple[float, int] | None:
        """The first time in a step at which an argument leaves its side, if any.

        Parameters
        ----------
        t_old, t_new : float
            The step, s.
        dense : callable
            The step's interpolant, ``dense(t)`` of shape (n,) or (n, p).

        Returns
        -------
        (float, int) or None
            The crossing time (s; ``t_old`` when the argument is beyond its side from the
            start) and the kink's index; None if every argument stays on its side.
        """
        if not len(self.offsets):
            return None
        h = t_new - t_old
        if self._clear(dense):
            return None
        basis = self.chebyshev
        samples = dense(t_old + h * basis.points)
        signed = self.sides[:, None] * (self.R @ samples + self.offsets[:, None])
        coefficients = signed @ basis.to_coefficients.T
        spread = np.abs(coefficients[:, 1:]).sum(axis=1)
        level = self.rounding(samples[:, -1], spread * (1.0 + abs(t_new) / h))
        first = None
        for j in np.flatnonzero(coefficients[:, 0] - spread < -level):
            found = self._exit(j, coefficients[j], level[j], t_old, h, dense)
            if found is not None and (first is None or found < first[0]):
                first = (found, int(j))
        return first

    def _exit(self, j, coefficients, level, t_old, h, dense) -> float | None:
        """When the signed argument ``j`` (Chebyshev ``coefficients`` over the step) first
        goes below ``-level``, back to its last zero; None if it never does.

        On a grid, each interval's chord less the bend bound clears most near approaches;
        a crossing inside an interval on which the argument is monotonic (its chord's slope
        beyond what the bend bound lets the derivative vary by) is located there; anything
        else goes to :meth:`_lowest`, the exact search.
        """
        basis = self.chebyshev
        values = basis.grid @ coefficients
        bend = basis.bend @ np.abs(coefficients)
        low = np.minimum(values[:-1], values[1:]) - bend
        # the first interval also from the start: value, slope and curvature bound (a
        # restart sits on the kink just crossed, moving away from it)
        slope = basis.start_slope @ coefficients * (2.0 / basis.GRID)
        low[0] = max(low[0], values[0] + min(0.0, slope - 4.0 * bend))
        suspect = np.flatnonzero(low <= -level)
        if not suspect.size:
            return None
        i = suspect[0]
        if values[i] > 0.0 and values[i + 1] < -level and values[i] - values[i + 1] > 8.0 * bend:
            return self._root(
                j, t_old + h * i / basis.GRID, t_old + h * (i + 1) / basis.GRID, dense
            )
        return self._lowest(j, coefficients, level, t_old, h, dense)

    def _clear(self, dense) -> bool:
        """True when a bound on the step's interpolant keeps every argument on its side.

        Only for the Runge-Kutta interpolants of scipy, whose coefficients bound the change
        over the step at once. DOP853's is ``y_old + x (F0 + (1 - x) (F1 + x (F2 + ...)))``
        with x in [0, 1]: the first term moves one way, and ``F_i`` for i >= 1 is multiplied
        by at most ``max x^a (1 - x)^b`` (``_DOP853_WEIGHTS``). RK45's and RK23's is
        ``y_old + h Q [x, x^2, ...]``: the first column moves one way, the others at most
        ``h |Q_i|``. False (sample the interpolant) otherwise, and when an argument may come
        within that bound of zero.
        """
        if self.interpolant == "dop853":
            terms = self.sides[:, None] * (self.R @ dense.F.T)  # (k, 7): signed, per term
            weights = _DOP853_WEIGHTS
        elif self.interpolant == "rk":
            terms = dense.h * self.sides[:, None] * (self.R @ dense.Q)
            weights = np.ones(terms.shape[1] - 1)
        else:
            return False
        start = self.sides * (self.R @ dense.y_old + self.offsets)
        low = start + np.minimum(terms[:, 0], 0.0) - np.abs(terms[:, 1:]) @ weights
        return bool(np.all(low > 0.0))

    def _lowest(self, j, coefficients, level, t_old, h, dense) -> float | None:
        """:meth:`_exit` exactly: the argument between the ends and the real roots of its
        derivative, monotonic between two neighbours."""
        critical = chebyshev.chebroots(chebyshev.chebder(coefficients))
        critical = critical.real[(np.abs(critical.imag) < 1e-6) & (np.abs(critical.real) < 1.0)]
        points = np.unique(np.concatenate(([-1.0, 1.0], critical)))
        values = chebyshev.chebval(points, coefficients)
        below = np.flatnonzero(values < -level)
        if not below.size:
            return None
        positive = np.flatnonzero(values[: below[0]] > 0.0)
        if not positive.size:
            return t_old  # beyond its side from the start of the step
        fraction = (points + 1.0) / 2.0
        last = positive[-1]
        return self._root(j, t_old + h * fraction[last], t_old + h * fraction[last + 1], dense,
                          t_old + h * fraction[below[0]])  # fmt: skip

    def _root(self, j, a: float, b: float, dense, beyond: float | None = None) -> float:
        """The zero of argument ``j`` in [a, b] (s) by Brent's method on the interpolant;
        ``beyond``, a time past b where it is surely beyond zero, widens a bracket that
        rounding closed."""
        side, row, offset = self.sides[j], self.R[j], self.offsets[j]

        def signed(t: float) -> float:
            return side * (float(row @ dense(t)) + offset)

        if beyond is not None and signed(b) > 0.0:
            b = beyond
        if signed(a) <= 0.0:
            return a
        if signed(b) >= 0.0:
            return b
        return brentq(signed, a, b, xtol=4 * _EPS * (b - a), rtol=4 * _EPS)
