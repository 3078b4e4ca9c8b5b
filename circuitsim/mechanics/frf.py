"""Frequency response of a model in one region of its piecewise-linear field.

Between kinks the field is affine: each ``|row . x + offset|`` equals ``side * (row . x +
offset)`` with the side it has at a state of the region. With every piecewise-linear term's
linear part and its kinks' sides folded in, the region's state matrix is

    A_region = A + sum_k direction_k (linear_k + sum_m gain_m side_m row_m)^T

and the response of the states to a harmonic input u_j = U e^(j omega t) entering along
``direction_j`` is X = (j omega I - A_region)^-1 direction_j U: the receptances (state units
per input unit) of the linearized model. For the wheelset inside the flange clearance the
flange force is zero, so A_region is the linear part A of the critical-speed analysis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from circuitsim.mechanics.errors import ModelError
from circuitsim.mechanics.stability import Mode
from circuitsim.mechanics.system import System


@dataclass(frozen=True)
class FrequencyResponse:
    """Transfer functions from each forcing input to each state.

    Attributes
    ----------
    frequencies : ndarray, shape (f,)
        Hz of the model's time.
    states, units : tuple of str
        The states and their units.
    inputs, input_units : tuple of str
        The forcing inputs' names (``"track"``, or ``"forcing1"`` ...) and units.
    response : ndarray of complex, shape (len(inputs), len(states), f)
        State per unit of input at each frequency.
    """

    frequencies: np.ndarray
    states: tuple[str, ...]
    units: tuple[str, ...]
    inputs: tuple[str, ...]
    input_units: tuple[str, ...]
    response: np.ndarray

    def of(self, input_name: str, state: str) -> np.ndarray:
        """The transfer function from ``input_name`` to ``state``, shape (f,), complex."""
        return self.response[self.inputs.index(input_name), self.states.index(state)]


def input_names(system: System) -> tuple[str, ...]:
    """Each forcing input's name: the model file's group name, else ``forcing<k>``."""
    return tuple(
        getattr(force, "name", "") or f"forcing{k}" for k, force in enumerate(system.forcing, 1)
    )


def region_matrix(system: System, x: np.ndarray | None = None) -> np.ndarray:
    """The state matrix (1/s, shape (n, n)) of the affine piece of the field around ``x``.

    Parameters
    ----------
    system : System
    x : array_like, shape (n,), optional
        A state inside the region (default: zeros, e.g. the wheelset centred in its clearance).
        Every piecewise-linear term counts as switched on.

    Raises
    ------
    ModelError
        ``x`` lies on a kink (an ``|.|`` argument is zero there, so no single region holds it),
        or has the wrong size.
    """
    n = system.n
    state = np.zeros(n) if x is None else np.asarray(x, dtype=float).reshape(-1)
    if state.shape != (n,):
        raise ModelError(f"the region's state needs {n} values, got {state.size}")
    A = np.array(system.A, dtype=float, copy=True)
    for term in system.nonlinear:
        row = np.array(term.linear, dtype=float, copy=True)
        for index, kink in enumerate(term.abs_terms):
            argument = float(kink.row @ state + kink.offset)
            if argument == 0.0:
                raise ModelError(
                    f"the state {state.tolist()} lies on kink {index} of the term "
                    f"{term.name!r}; give a state inside one region"
                )
            row += kink.gain * math.copysign(1.0, argument) * np.asarray(kink.row, dtype=float)
        A += np.outer(term.direction, row)
    return A


def frequency_response(
    system: System, frequencies: np.ndarray, x: np.ndarray | None = None
) -> FrequencyResponse:
    """Receptances of the region around ``x`` (:func:`region_matrix`) at ``frequencies`` (Hz).

    Raises
    ------
    ModelError
        The model has no forcing input, or ``x`` lies on a kink.
    """
    if not system.forcing:
        raise ModelError("the model has no forcing input, so it has no frequency response")
    A = region_matrix(system, x)
    f = np.asarray(frequencies, dtype=float).reshape(-1)
    directions = np.array([np.asarray(force.direction, dtype=float) for force in system.forcing])
    identity = np.eye(system.n)
    response = np.empty((len(system.forcing), system.n, f.size), dtype=complex)
    for k, frequency in enumerate(f):
        response[:, :, k] = np.linalg.solve(2j * math.pi * frequency * identity - A, directions.T).T
    units = tuple(system.units) if system.units else ("",) * system.n
    return FrequencyResponse(
        frequencies=f,
        states=tuple(system.states),
        units=units,
        inputs=input_names(system),
        input_units=tuple(getattr(force, "amplitude_unit", "") for force in system.forcing),
        response=response,
    )


def region_modes(system: System, x: np.ndarray | None = None) -> list[Mode]:
    """The oscillating modes (Im lambda > 0) of the region around ``x``, by frequency."""
    lam = np.linalg.eigvals(region_matrix(system, x))
    out = []
    for value in sorted((v for v in lam if v.imag > 0), key=lambda v: abs(v)):
        size = abs(value)
        out.append(
            Mode(
                complex(value),
                float(-value.real / size),
                size / (2 * math.pi),
                value.imag / (2 * math.pi),
            )  # fmt: skip
        )
    return out
