"""Standard component values: the IEC 60063 E24 and E96 series and capacitor decades.

A resistor value is rounded to the nearest member of a series in the logarithmic sense (the
series are spaced evenly in log R), which keeps the relative coefficient error at most half a
step: about 5 % for E24 and 1.2 % for E96. ``exact`` keeps the computed value.
"""

from __future__ import annotations

import math

from circuitsim.synthesis.errors import SynthesisError

E24 = (
    1.0, 1.1, 1.2, 1.3, 1.5, 1.6, 1.8, 2.0, 2.2, 2.4, 2.7, 3.0,
    3.3, 3.6, 3.9, 4.3, 4.7, 5.1, 5.6, 6.2, 6.8, 7.5, 8.2, 9.1,
)  # fmt: skip

E96 = (
    1.00, 1.02, 1.05, 1.07, 1.10, 1.13, 1.15, 1.18, 1.21, 1.24, 1.27, 1.30,
    1.33, 1.37, 1.40, 1.43, 1.47, 1.50, 1.54, 1.58, 1.62, 1.65, 1.69, 1.74,
    1.78, 1.82, 1.87, 1.91, 1.96, 2.00, 2.05, 2.10, 2.15, 2.21, 2.26, 2.32,
    2.37, 2.43, 2.49, 2.55, 2.61, 2.67, 2.74, 2.80, 2.87, 2.94, 3.01, 3.09,
    3.16, 3.24, 3.32, 3.40, 3.48, 3.57, 3.65, 3.74, 3.83, 3.92, 4.02, 4.12,
    4.22, 4.32, 4.42, 4.53, 4.64, 4.75, 4.87, 4.99, 5.11, 5.23, 5.36, 5.49,
    5.62, 5.76, 5.90, 6.04, 6.19, 6.34, 6.49, 6.65, 6.81, 6.98, 7.15, 7.32,
    7.50, 7.68, 7.87, 8.06, 8.25, 8.45, 8.66, 8.87, 9.09, 9.31, 9.53, 9.76,
)  # fmt: skip

SERIES = {"E24": E24, "E96": E96}

#: Integrator capacitor choices (farads): the decades 1 nF ... 10 uF.
CAPACITOR_DECADES = (1e-9, 1e-8, 1e-7, 1e-6, 1e-5)


def series_names() -> tuple[str, ...]:
    """Accepted ``series`` option values."""
    return ("E96", "E24", "exact")


def round_to_series(value: float, series: str) -> float:
    """The member of ``series`` nearest to ``value`` in log scale (``"exact"``: value itself).

    Parameters
    ----------
    value : float
        Positive component value (ohms).
    series : str
        ``"E96"``, ``"E24"`` or ``"exact"`` (case-insensitive).

    Returns
    -------
    float
        The standard value, with the decade applied (e.g. 31.6e3 for 31.4e3 in E96).
    """
    key = series.upper() if series.lower() != "exact" else "exact"
    if key == "exact":
        # 12 significant digits: drops binary noise (99999.99999999999), keeps the value
        return float(f"{value:.12g}")
    if key not in SERIES:
        raise SynthesisError(
            f"unknown series {series!r}; choose one of {', '.join(series_names())}"
        )
    if not (value > 0 and math.isfinite(value)):
        raise SynthesisError(f"cannot round a non-positive or infinite value {value!r}")
    decade, mantissa = _decade(value)
    # candidates include the next decade's 1.0 so 9.9 can round up to 10
    candidates = [*SERIES[key], 10.0]
    best = min(candidates, key=lambda m: abs(math.log(m / mantissa)))
    # round away binary noise (e.g. 3.16 * 1e3 = 3160.0000000000005)
    return _standard(best, decade, value)


def series_pair(
    value: float, series: str, tolerance: float, smallest: float = 0.0
) -> tuple[float, ...]:
    """One standard value for ``value``, or two in series where one misses by more than
    ``tolerance``.

    The pair is the one with the smallest error among: each member of ``series`` between
    ``value / 2`` and ``value`` plus the member nearest the remainder. The floor member alone
    leaves a remainder of at most one step (about 2.4 % of ``value`` in E96), rounded to within
    half a step of itself, so the pair is within about 0.03 % (E96).

    Parameters
    ----------
    value : float
        Positive resistance (ohms).
    series : str
        ``"E96"``, ``"E24"`` or ``"exact"`` (always one value).
    tolerance : float
        Largest relative error |R/value - 1| accepted from one resistor (``inf``: never a pair).
    smallest : float
        No part of a pair below this (ohms): a pair that needs one is not considered.

    Returns
    -------
    tuple of float
        ``(R,)`` or ``(R_large, R_small)`` in ohms.
    """
    single = round_to_series(value, series)
    if series.lower() == "exact" or abs(single / value - 1.0) <= tolerance:
        return (single,)
    decade, _ = _decade(value)
    best = (single,)
    for shift in (-1, 0):  # members of this decade and the one below, down to value / 2
        for member in SERIES[series.upper()]:
            large = _standard(member, decade + shift, value)
            if not value / 2 <= large < value:
                continue
            pair = (large, round_to_series(value - large, series))
            if pair[1] >= smallest and abs(sum(pair) / value - 1.0) < abs(sum(best) / value - 1.0):
                best = pair
    return best


def parallel_pair(value: float, series: str, smallest: float = 0.0) -> tuple[float, float] | None:
    """The two members of ``series`` whose parallel combination is nearest ``value``.

    Tried: each member R1 in (``value``, 2 ``value``] with R2 the member nearest the rest,
    1 / (1/value - 1/R1). Parallel pairs reach values a series pair misses: with E24, a series
    pair is up to 0.58 % off (one part near value, the other a rounded remainder), the better
    of the two kinds up to 0.29 %.

    Parameters
    ----------
    value : float
        Positive resistance (ohms).
    series : str
        ``"E96"`` or ``"E24"``.
    smallest : float
        No part below this (ohms).

    Returns
    -------
    tuple of float or None
        ``(R1, R2)`` in ohms (R1 <= R2 not implied), None for ``exact`` or when none fits.
    """
    if series.lower() == "exact":
        return None
    decade, _ = _decade(value)
    best, error = None, math.inf
    for shift in (0, 1):
        for member in SERIES[series.upper()]:
            first = _standard(member, decade + shift, value)
            if not value < first <= 2 * value:
                continue
            second = round_to_series(1.0 / (1.0 / value - 1.0 / first), series)
            combined = first * second / (first + second)
            if min(first, second) >= smallest and abs(combined / value - 1.0) < error:
                best, error = (first, second), abs(combined / value - 1.0)
    return best


def parallel_value(pair: tuple[float, float]) -> float:
    """Ohms of two resistors in parallel."""
    return pair[0] * pair[1] / (pair[0] + pair[1])


def floor_to_series(value: float, series: str = "E24") -> float:
    """The largest member of ``series`` not above ``value`` (for readable volts-per-unit).

    Raises
    ------
    SynthesisError
        ``value`` is not a positive finite number, or its standard value is not one.
    """
    if not (value > 0 and math.isfinite(value)):
        raise SynthesisError(f"no standard value for a non-positive or infinite {value!r}")
    decade, mantissa = _decade(value)
    members = [m for m in SERIES[series] if m <= mantissa * (1 + 1e-12)]
    return _standard(members[-1], decade, value)


def _decade(value: float) -> tuple[int, float]:
    """``value`` (positive, finite) as (decade, mantissa in [1, 10)).

    Near the ends of the float range (1e-320, 1e308) the power of ten is itself out of range
    or denormal: there the mantissa comes from the logarithm.
    """
    exponent = math.log10(value)
    decade = math.floor(exponent)
    if abs(decade) < 300:
        return decade, value / 10.0**decade
    return decade, min(max(10.0 ** (exponent - decade), 1.0), 10.0)


def _standard(member: float, decade: int, value: float) -> float:
    """``member * 10**decade`` with 6 significant digits (binary noise rounded away); a
    result beyond the float range is a SynthesisError naming ``value``."""
    try:
        result = float(f"{member * 10.0**decade:.6g}")
    except OverflowError:
        result = math.inf
    if not (math.isfinite(result) and result > 0):
        raise SynthesisError(f"no standard value for {value!r}: beyond the float range")
    return result
