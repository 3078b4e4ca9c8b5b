"""Linear stability: eigenvalues of the linear part versus a parameter, and where they cross.

The linear part is ``System.A``: piecewise-linear terms (the flange) are left out, as in the
paper's hunting analysis. The critical value of a parameter is where the largest real part of
the eigenvalues crosses zero; the hunting frequency is the imaginary part there over 2 pi.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from circuitsim.mechanics.errors import ModelError
from circuitsim.mechanics.model import Model


def state_matrix(
    model: Model,
    coefficients: str | None = None,
    parameters: Mapping[str, float] | None = None,
) -> np.ndarray:
    """The linear part A (shape (n, n), 1/s) at the given parameters, nonlinear terms off."""
    off = {name: False for name in model.nonlinear_terms}
    return model.system(coefficients=coefficients, parameters=parameters, nonlinear=off).A


def eigenvalues(
    model: Model,
    parameter: str = "V",
    values: Iterable[float] = (),
    coefficients: str | None = None,
    parameters: Mapping[str, float] | None = None,
) -> np.ndarray:
    """Eigenvalues of the linear part for each value of one parameter.

    Parameters
    ----------
    model : Model
    parameter : str
        The parameter swept (wheelset: ``"V"``, m/s).
    values : iterable of float
        Its values.
    coefficients : str, optional
        Coefficient set (default: the model's default).
    parameters : dict, optional
        Other parameter overrides.

    Returns
    -------
    ndarray of complex, shape (len(values), n)
        1/s; each row sorted by decreasing real part (then decreasing imaginary part).
    """
    _check_parameter(model, parameter)
    rows = []
    for value in np.atleast_1d(np.asarray(list(values), dtype=float)):
        A = state_matrix(model, coefficients, {**dict(parameters or {}), parameter: value})
        lam = np.linalg.eigvals(A)
        rows.append(lam[np.lexsort((-lam.imag, -lam.real))])
    return np.array(rows).reshape(-1, model.n)


def growth_rate(
    model: Model,
    value: float,
    parameter: str = "V",
    coefficients: str | None = None,
    parameters: Mapping[str, float] | None = None,
) -> float:
    """Largest real part of the linear part's eigenvalues (1/s) at ``parameter = value``."""
    return float(eigenvalues(model, parameter, [value], coefficients, parameters)[0, 0].real)


def critical_speed(
    model: Model,
    coefficients: str | None = None,
    parameter: str = "V",
    bracket: tuple[float, float] = (1.0, 1000.0),
    parameters: Mapping[str, float] | None = None,
    scan: int = 200,
) -> tuple[float, float]:
    """The parameter value where the linear part first loses stability, and the frequency.

    The bracket is scanned on a logarithmic grid (linear if it includes 0 or negative values)
    for the first change from stable to unstable, then brentq refines it to ~1e-12 relative.

    Parameters
    ----------
    model : Model
    coefficients : str, optional
        Coefficient set.
    parameter : str
        The parameter (wheelset: forward speed ``"V"``, m/s).
    bracket : (float, float)
        Search interval in the parameter's units.
    parameters : dict, optional
        Other parameter overrides.
    scan : int
        Grid points of the scan.

    Returns
    -------
    value : float
        Critical value (m/s for V).
    hunting_frequency : float
        |Im| / 2 pi of the critical eigenvalue, Hz (0 for a real eigenvalue).

    Raises
    ------
    ModelError
        When the largest real part does not change sign from negative to positive inside the
        bracket.
    """
    _check_parameter(model, parameter)
    lo, hi = (float(v) for v in bracket)
    if not hi > lo:
        raise ModelError(f"bracket must increase, got ({lo}, {hi})", file=model.file)
    if lo > 0:
        grid = np.geomspace(lo, hi, scan)
    else:
        grid = np.linspace(lo, hi, scan)

    def rate(value: float) -> float:
        try:
            return growth_rate(model, value, parameter, coefficients, parameters)
        except ModelError as exc:  # the bracket reached a value the model is not defined at
            raise ModelError(
                f"bracket [{lo:g}, {hi:g}]: at {parameter} = {value:g} the model cannot be "
                f"evaluated ({exc}); choose a bracket without that value"
            ) from exc

    rates = np.array([rate(v) for v in grid])
    crossing = np.nonzero((rates[:-1] < 0) & (rates[1:] >= 0))[0]
    if crossing.size == 0:
        raise ModelError(
            _no_crossing(parameter, lo, hi, grid, rates, _rate_unit(model)),
            file=model.file,
            key=f"parameters.{parameter}",
        )
    i = crossing[0]
    value = brentq(rate, grid[i], grid[i + 1], xtol=1e-12 * abs(grid[i + 1]), rtol=1e-13)
    lam = eigenvalues(model, parameter, [value], coefficients, parameters)[0, 0]
    return float(value), float(abs(lam.imag) / (2.0 * np.pi))


def _rate_unit(model: Model) -> str:
    """The unit of an eigenvalue: 1/s, or per the model's time unit (dimensionless: "")."""
    unit = getattr(model, "time_unit", "s")
    return f"1/{unit}" if unit else "per unit time"


def _no_crossing(parameter, lo, hi, grid, rates, unit: str) -> str:
    """Why a bracket holds no loss of stability, in words that fit the scan: stable all
    along, unstable all along, or unstable at the low end and stable further on."""
    where = f"{parameter} in [{lo:g}, {hi:g}]"
    extent = (
        f"largest real part {rates[0]:.4g} {unit} at {lo:g}, {rates[-1]:.4g} {unit} at "
        f"{hi:g}; between {rates.min():.4g} and {rates.max():.4g} {unit}"
    )
    if np.all(rates < 0):
        return f"the linear part is stable over the whole bracket, {where} ({extent})"
    if np.all(rates >= 0):
        return (
            f"the linear part is unstable over the whole bracket, {where} ({extent}): it loses "
            "stability below the bracket, if at all"
        )
    regains = grid[int(np.nonzero((rates[:-1] >= 0) & (rates[1:] < 0))[0][0]) + 1]
    return (
        f"the linear part is unstable at the bracket's low end and stable from about "
        f"{parameter} = {regains:.4g} on: it gains stability there and does not lose it in "
        f"{where} ({extent})"
    )


@dataclass(frozen=True)
class Mode:
    """One eigenvalue of the linear part and what it means for a vibration.

    Attributes
    ----------
    eigenvalue : complex
        lambda, 1/s (per unit of the model's time).
    damping_ratio : float
        zeta = -Re(lambda) / |lambda| (negative: the mode grows); NaN for lambda = 0.
    natural_frequency : float
        |lambda| / (2 pi), Hz.
    damped_frequency : float
        |Im(lambda)| / (2 pi), Hz (0 for a real eigenvalue).
    """

    eigenvalue: complex
    damping_ratio: float
    natural_frequency: float
    damped_frequency: float

    @property
    def stable(self) -> bool:
        """True when the mode decays (Re(lambda) < 0)."""
        return self.eigenvalue.real < 0


def modes(
    model: Model,
    coefficients: str | None = None,
    parameters: Mapping[str, float] | None = None,
) -> list[Mode]:
    """The modes of the linear part at the given parameters, any model (no speed needed).

    Parameters
    ----------
    model : Model
    coefficients : str, optional
        Coefficient set (default: the model's default).
    parameters : dict, optional
        Parameter overrides, in their units.

    Returns
    -------
    list of Mode
        One per eigenvalue, by decreasing real part (then decreasing imaginary part).
    """
    A = state_matrix(model, coefficients, parameters)
    lam = np.linalg.eigvals(A) if A.size else np.zeros(0, dtype=complex)
    out = []
    for value in lam[np.lexsort((-lam.imag, -lam.real))]:
        size = abs(value)
        zeta = -value.real / size if size > 0 else math.nan
        out.append(Mode(complex(value), float(zeta), size / (2 * math.pi),
                        abs(value.imag) / (2 * math.pi)))  # fmt: skip
    return out


def _check_parameter(model: Model, parameter: str) -> None:
    if parameter not in model.parameters:
        known = ", ".join(model.parameters) or "none"
        raise ModelError(
            f"unknown parameter {parameter!r} (known: {known})",
            file=model.file,
            key=f"parameters.{parameter}",
        )
