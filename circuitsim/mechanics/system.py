"""A model with numbers in it: the first-order form every other room works from.

    dx/dt = A x + b0 + sum_k direction_k * s_k(x)
                    + sum_j direction_j * amplitude_j * sin(2 pi f_j t + phase_j)

where each piecewise-linear term contributes a scalar

    s_k(x) = linear_k . x + constant_k + sum_m gain_m * |row_m . x + offset_m|

(switched in from ``t_on`` when given) along its ``direction`` vector. A second-order model
M q'' + C q' + K q + f_nl(q) = F(t) becomes this with x = [q, q'], the directions carrying
-M^-1. The translator realizes exactly these objects: one integrator per state, one resistor per
nonzero entry of A, one |x| block per AbsTerm, one source per Sinusoid.
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
    forcing : tuple of Sinusoid
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
    """

    name: str
    states: tuple[str, ...]
    units: tuple[str, ...]
    A: np.ndarray
    b0: np.ndarray
    nonlinear: tuple[PiecewiseLinearTerm, ...] = ()
    forcing: tuple[Sinusoid, ...] = ()
    x0: np.ndarray | None = None
    parameters: dict[str, float] = field(default_factory=dict)
    circuit_hints: dict = field(default_factory=dict)
    coefficients: dict[str, float] = field(default_factory=dict)
    coefficient_set: str = ""

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
        return dx
