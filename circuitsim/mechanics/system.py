"""A model with numbers in it: the first-order form every other room works from.

    dx/dt = A x + b0 + sum_k direction_k * s_k(x)
                    + sum_j direction_j * u_j(t)

where each piecewise-linear term contributes a scalar

    s_k(x) = linear_k . x + constant_k + sum_m gain_m * |row_m . x + offset_m|

(switched in from ``t_on`` when given) along its ``direction`` vector. A second-order model
M q'' + C q' + K q + f_nl(q) = F(t) becomes this with x = [q, q'], the directions carrying
-M^-1. The translator realizes exactly these objects: one integrator per state, one resistor per
nonzero entry of A, one |x| block per AbsTerm, one source per forcing input u_j(t): a
sinusoid (SIN), a piecewise-linear time series or step (PWL), a smooth bump (sampled PWL).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class AbsTerm:
    """``gain * |row . x + offset|``.

    Attributes
    ----------
    gain : float
        Units of the owning term's scalar per unit of the argument.
    row : ndarray, shape (n,)
        Weights on the states.
    offset : float
        Added inside the absolute value, in the argument's units (the wheelset: metres).
    """

    gain: float
    row: np.ndarray
    offset: float

    def argument(self, x: np.ndarray) -> np.ndarray:
        """``row . x + offset``; x of shape (n,) or (n, m) gives a scalar or shape (m,)."""
        return self.row @ x + self.offset


@dataclass(frozen=True)
class PiecewiseLinearTerm:
    """A switchable piecewise-linear term, e.g. the flange force F_t(y).

    Attributes
    ----------
    name : str
        Identifier, e.g. ``"flange"``.
    direction : ndarray, shape (n,)
        How the scalar enters dx/dt (the wheelset flange: -1/m on y').
    linear : ndarray, shape (n,)
        Linear part of the scalar (flange: k on y).
    abs_terms : tuple of AbsTerm
        The kinks.
    constant : float
        Constant part of the scalar.
    t_on : float or None
        Time (s) from which the term acts (the paper's switch S1 closing); None: always.
    fits : tuple
        For smooth functions the model file asked to fit (``[nonlinear.NAME.fit]``): the
        :class:`~circuitsim.mechanics.pwlfit.PiecewiseLinearFit` each was replaced by, with
        its breakpoints and error bound (their kinks are among ``abs_terms``).
    """

    name: str
    direction: np.ndarray
    linear: np.ndarray
    abs_terms: tuple[AbsTerm, ...]
    constant: float = 0.0
    t_on: float | None = None
    fits: tuple = ()

    def value(self, x: np.ndarray) -> np.ndarray | float:
        """The scalar s(x) (ignores ``t_on``); x of shape (n,) or (n, m)."""
        total = self.linear @ x + self.constant
        for term in self.abs_terms:
            total = total + term.gain * np.abs(term.argument(x))
        return total


@dataclass(frozen=True)
class Sinusoid:
    """Forcing ``direction * amplitude * sin(2 pi frequency t + phase)``.

    Attributes
    ----------
    direction : ndarray, shape (n,)
        Per unit of amplitude (wheelset: k_y/m on y', so the amplitude is the track
        displacement a in metres and enters like the y term, the paper's R17 = R31).
    amplitude : float
        In the model's forcing unit (``amplitude_unit``).
    frequency : float
        Hz.
    phase : float
        Radians.
    amplitude_unit : str
        Unit of ``amplitude`` (``"m"`` for the wheelset).
    name : str
        The model file's name for this forcing group (``"track"``); may be empty.
    """

    direction: np.ndarray
    amplitude: float
    frequency: float
    phase: float = 0.0
    amplitude_unit: str = ""
    name: str = ""

    def value(self, t: float | np.ndarray) -> float | np.ndarray:
        """``amplitude * sin(2 pi f t + phase)`` (without the direction)."""
        return self.amplitude * np.sin(2.0 * np.pi * self.frequency * t + self.phase)

    def corners(self) -> np.ndarray:
        """Times (s) where the input or its slope jumps: none for a sinusoid."""
        return np.empty(0)

    def piece(self, t: float):
        """The input as a smooth function of time from ``t`` to the next corner (all of it)."""
        return self.value

    @property
    def fastest(self) -> float:
        """The highest frequency (Hz) the circuit's time step must resolve."""
        return abs(self.frequency)

    @property
    def peak(self) -> float:
        """max |value| over all time (amplitude unit)."""
        return abs(self.amplitude)

    def same_as(self, other) -> bool:
        """Whether ``other`` is the same input (equal numbers, equal direction)."""
        return (
            isinstance(other, Sinusoid)
            and (self.amplitude, self.frequency, self.phase) == (
                other.amplitude, other.frequency, other.phase)
            and np.array_equal(self.direction, other.direction)
        )  # fmt: skip


@dataclass(frozen=True)
class PiecewiseLinearInput:
    """Forcing ``direction * u(t)``, u interpolated linearly between given points.

    Before the first point u holds the first value, after the last the last value. Two points
    at the same time make a jump (a step); the direct solution restarts at every point
    (:func:`circuitsim.mechanics.solve.solve`), the translator writes a PWL source.

    Attributes
    ----------
    direction : ndarray, shape (n,)
        Per unit of u.
    times : ndarray, shape (p,)
        Seconds, non-decreasing.
    values : ndarray, shape (p,)
        u at ``times``, in ``amplitude_unit``.
    amplitude_unit : str
    name : str
    kind : str
        What the model file called it (``"series"``, ``"step"`` ...), for messages.
    """

    direction: np.ndarray
    times: np.ndarray
    values: np.ndarray
    amplitude_unit: str = ""
    name: str = ""
    kind: str = "series"

    def value(self, t: float | np.ndarray) -> float | np.ndarray:
        """u(t) (without the direction); at a jump, the value after it."""
        times, values = self.times, self.values
        index = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 1)
        upper = np.minimum(index + 1, len(times) - 1)
        span = times[upper] - times[index]
        safe = np.where(span > 0, span, 1.0)
        weight = np.where(span > 0, np.clip((t - times[index]) / safe, 0.0, 1.0), 0.0)
        out = values[index] + weight * (values[upper] - values[index])
        return float(out) if np.ndim(out) == 0 else out

    def corners(self) -> np.ndarray:
        """The points' times, s (each once)."""
        return np.unique(self.times)

    def piece(self, t: float):
        """u on the segment that starts at or before ``t``, extended as a straight line."""
        times, values = self.times, self.values
        k = int(np.searchsorted(times, t, side="right")) - 1
        if k < 0 or k >= len(times) - 1:
            constant = float(values[0] if k < 0 else values[-1])
            return lambda time: constant
        t0, v0 = float(times[k]), float(values[k])
        slope = float((values[k + 1] - v0) / (times[k + 1] - t0))
        return lambda time: v0 + slope * (time - t0)

    @property
    def fastest(self) -> float:
        """0: the input is exact between its corners, which the engines step onto."""
        return 0.0

    @property
    def peak(self) -> float:
        """max |u| (amplitude unit)."""
        return float(np.max(np.abs(self.values)))

    def same_as(self, other) -> bool:
        """Whether ``other`` is the same input (equal points, equal direction)."""
        return (
            isinstance(other, PiecewiseLinearInput)
            and np.array_equal(self.times, other.times)
            and np.array_equal(self.values, other.values)
            and np.array_equal(self.direction, other.direction)
        )


#: The smooth bump shapes: u(s) on s = (t - start) / duration in [0, 1].
BUMP_SHAPES = ("haversine", "half_sine")


@dataclass(frozen=True)
class Bump:
    """Forcing ``direction * u(t)``: one smooth bump of ``duration`` from ``start``, else 0.

    ``haversine``: u = amplitude (1 - cos(2 pi s)) / 2 (value and slope continuous at both
    ends); ``half_sine``: u = amplitude sin(pi s) (slope jumps at both ends), s = (t - start) /
    duration.

    Attributes
    ----------
    direction : ndarray, shape (n,)
    amplitude : float
        Peak of u, in ``amplitude_unit``.
    start, duration : float
        Seconds.
    shape : str
        One of ``BUMP_SHAPES``.
    amplitude_unit, name : str
    """

    direction: np.ndarray
    amplitude: float
    start: float
    duration: float
    shape: str = "haversine"
    amplitude_unit: str = ""
    name: str = ""
    kind: str = "bump"

    def _inside(self, t):
        s = (np.asarray(t, dtype=float) - self.start) / self.duration
        if self.shape == "haversine":
            return self.amplitude * 0.5 * (1.0 - np.cos(2.0 * np.pi * s))
        return self.amplitude * np.sin(np.pi * s)

    def value(self, t: float | np.ndarray) -> float | np.ndarray:
        """u(t) (without the direction)."""
        inside = (t >= self.start) & (t <= self.start + self.duration)
        out = np.where(inside, self._inside(t), 0.0)
        return float(out) if np.ndim(out) == 0 else out

    def corners(self) -> np.ndarray:
        """Start and end of the bump, s."""
        return np.array([self.start, self.start + self.duration])

    def piece(self, t: float):
        """The bump's formula inside it, 0 outside."""
        if self.start <= t < self.start + self.duration:
            return self._inside
        return lambda time: 0.0

    @property
    def fastest(self) -> float:
        """1 / duration, Hz (the haversine's cosine; the half-sine's is half of it)."""
        return 1.0 / self.duration

    @property
    def peak(self) -> float:
        """|amplitude|."""
        return abs(self.amplitude)

    def same_as(self, other) -> bool:
        """Whether ``other`` is the same input."""
        return (
            isinstance(other, Bump)
            and (self.amplitude, self.start, self.duration, self.shape)
            == (other.amplitude, other.start, other.duration, other.shape)
            and np.array_equal(self.direction, other.direction)
        )


#: Any forcing a System may carry.
Forcing = Sinusoid | PiecewiseLinearInput | Bump


@dataclass(frozen=True)
class Factor:
    """One factor of a :class:`ProductTerm`: ``row . x + offset``, or an input signal u(t).

    Attributes
    ----------
    row : ndarray, shape (n,)
        Weights on the states (all zero for a signal factor).
    offset : float
        Added to ``row . x``, in the factor's units.
    signal : Sinusoid, PiecewiseLinearInput, Bump or None
        When given, the factor is this input's u(t) (a time-varying coefficient, e.g. 1/V(t)
        of a speed run-up) and ``row``/``offset`` are unused; the signal's own ``direction``
        is unused too (it drives nothing by itself).
    """

    row: np.ndarray
    offset: float = 0.0
    signal: Forcing | None = None

    def value(self, t: float | np.ndarray, x: np.ndarray) -> float | np.ndarray:
        """The factor at time t (s) and state x, shape (n,) or (n, m)."""
        if self.signal is not None:
            return self.signal.value(t)
        return self.row @ x + self.offset


@dataclass(frozen=True)
class ProductTerm:
    """``direction * coefficient * prod_i factor_i``: a product of states (and inputs).

    A monomial of a polynomial term: x*y is two factors, x**3 three equal ones, u(t)*y a
    signal factor and a state factor.

    Attributes
    ----------
    name : str
        Identifier (the model file's term name, with a suffix per monomial).
    direction : ndarray, shape (n,)
        How the product enters dx/dt.
    coefficient : float
        Scalar multiplying the product, in the units that make direction * product a rate.
    factors : tuple of Factor
        At least two (a single factor is linear and belongs in ``A``).
    t_on : float or None
        Time (s) from which the term acts; None: always.
    """

    name: str
    direction: np.ndarray
    coefficient: float
    factors: tuple[Factor, ...]
    t_on: float | None = None

    def value(self, t: float | np.ndarray, x: np.ndarray) -> float | np.ndarray:
        """The scalar ``coefficient * prod_i factor_i`` (ignores ``t_on``)."""
        total = self.coefficient
        for factor in self.factors:
            total = total * factor.value(t, x)
        return total


@dataclass(frozen=True)
class System:
    """A model evaluated at given parameter values, in first-order form.

    Attributes
    ----------
    name : str
        Model name (``"wheelset"``).
    states : tuple of str
        State names in order (wheelset: ``("y", "psi", "y_dot", "psi_dot")``).
    units : tuple of str
        SI unit of each state (``("m", "rad", "m/s", "rad/s")``).
    A : ndarray, shape (n, n)
        Linear part, 1/s.
    b0 : ndarray, shape (n,)
        Constant part.
    nonlinear : tuple of PiecewiseLinearTerm
        Enabled piecewise-linear terms only (a switched-off flange is absent).
    forcing : tuple of Sinusoid, PiecewiseLinearInput or Bump
        Enabled forcing terms.
    x0 : ndarray, shape (n,)
        Initial state.
    parameters : dict of str to float
        The parameter values this system was built with (``V``, ``f``, ``a`` ...).
    circuit_hints : dict
        The model file's free-form ``[circuit]`` table, passed through for the translator
        (part names for the paper's circuit, preferred ranges ...).
    coefficients : dict of str to float
        The named coefficients of the chosen set at these parameters (wheelset: ``c_y``,
        ``k_y`` ... in SI units); empty for hand-built systems.
    coefficient_set : str
        Name of that coefficient set (``"paper"``); empty for hand-built systems.
    products : tuple of ProductTerm
        Enabled product (polynomial) terms: the multiplier blocks of the circuit.
    """

    name: str
    states: tuple[str, ...]
    units: tuple[str, ...]
    A: np.ndarray
    b0: np.ndarray
    nonlinear: tuple[PiecewiseLinearTerm, ...] = ()
    forcing: tuple[Forcing, ...] = ()
    x0: np.ndarray | None = None
    parameters: dict[str, float] = field(default_factory=dict)
    circuit_hints: dict = field(default_factory=dict)
    coefficients: dict[str, float] = field(default_factory=dict)
    coefficient_set: str = ""
    products: tuple[ProductTerm, ...] = ()

    @property
    def n(self) -> int:
        """Number of states."""
        return len(self.states)

    def rhs(self, t: float, x: np.ndarray) -> np.ndarray:
        """dx/dt at time t (s) and state x, shape (n,)."""
        dx = self.A @ x + self.b0
        for term in self.nonlinear:
            if term.t_on is None or t >= term.t_on:
                dx = dx + term.direction * term.value(x)
        for force in self.forcing:
            dx = dx + force.direction * force.value(t)
        for product in self.products:
            if product.t_on is None or t >= product.t_on:
                dx = dx + product.direction * product.value(t, x)
        return dx
