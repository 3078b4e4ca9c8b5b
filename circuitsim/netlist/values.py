"""SPICE numbers: ``4.7k``, ``1Meg``, ``10uF``, ``1e3Hz``, ``2mil`` to floats and back.

The rules follow ngspice 39 (checked with ``ngspice -b``):

- a decimal mantissa with an optional exponent (``1``, ``-2.5``, ``.5``, ``1e-3``, ``1.5E+3``);
- an optional scale suffix, case-insensitive: ``f`` 1e-15, ``p`` 1e-12, ``n`` 1e-9, ``u`` 1e-6,
  ``m`` 1e-3, ``k`` 1e3, ``meg`` 1e6, ``g`` 1e9, ``t`` 1e12, ``mil`` 25.4e-6 (so ``1M`` is one
  milli, ``1MEG`` one mega and ``1F`` one femto - SPICE's classic traps);
- any trailing letters after that are a unit and are ignored (``10kOhm``, ``1uF``, ``5V``,
  ``1e3Hz``, ``1A`` is one ampere: ngspice has no atto suffix).

One deliberate difference: ngspice reads ``4k7`` as 4000 (it ignores the ``7``) while LTspice
reads 4700. A value with digits after its suffix is ambiguous between tools, so it is refused
here with a ValueError instead of being read either way silently.

The scale is applied in decimal, so ``parse_value("4.7u") == 4.7e-6`` exactly (multiplying the
float 4.7 by 1e-6 would be one ulp off).
"""

from __future__ import annotations

import math
import re
from decimal import Context, Decimal, InvalidOperation

__all__ = ["parse_value", "format_value", "looks_numeric"]

_NUMBER = re.compile(
    r"""
    (?P<mantissa>[+-]?(?:\d+\.?\d*|\.\d+))
    (?:[eE](?P<exponent>[+-]?\d+))?
    (?P<rest>.*)
    """,
    re.VERBOSE | re.DOTALL | re.ASCII,  # ngspice reads ASCII digits only: not '１０' or '١٠'
)

# Decimal exponents of the scale suffixes; ``mil`` is handled apart (25.4e-6 is not a power).
_POWERS = {"f": -15, "p": -12, "n": -9, "u": -6, "m": -3, "k": 3, "g": 9, "t": 12}

# Exponent limit: far past float range either way, small enough to keep Decimal cheap.
_MAX_EXPONENT = 10_000


def looks_numeric(text: str) -> bool:
    """True if ``text`` starts like a SPICE number (a digit, or a sign or point then a digit)."""
    return _NUMBER.match(text.strip()) is not None


def parse_value(text: str) -> float:
    """Read a SPICE number with optional scale suffix and unit letters.

    Parameters
    ----------
    text : str
        For example ``"4.7k"``, ``"10uF"``, ``"1MEG"``, ``"-2.5e-3"``, ``"1e3Hz"``.

    Returns
    -------
    float
        The value in SI units (the unit letters themselves are not checked).

    Raises
    ------
    ValueError
        If ``text`` is not a SPICE number, has characters other than letters after the
        number (``"4k7"``, ``"1.2.3"``, ``"5V+"``), or is out of float range.
    """
    if not isinstance(text, str):
        raise ValueError(f"expected a SPICE number as text, got {type(text).__name__}")
    stripped = text.strip()
    match = _NUMBER.fullmatch(stripped)
    if match is None:
        raise ValueError(f"not a number: {text!r} (expected e.g. 1.5, 2e-3, 4.7k, 10uF)")
    rest = match["rest"]
    if rest and not (rest.isascii() and rest.isalpha()):
        # 4k7 means 4000 to ngspice and 4700 to LTspice: refuse rather than guess
        hint = (
            f"; write {match['mantissa']}.{rest[1:]}{rest[0]}, not {stripped}"
            if re.fullmatch(r"[a-zA-Z][0-9]+", rest) and rest[0].lower() in _POWERS
            else ""
        )
        raise ValueError(
            f"not a number: {text!r} (found {rest!r} after the number, where only a scale "
            f"suffix and unit letters may follow, e.g. 4.7k or 10uF{hint})"
        )
    exponent = int(match["exponent"] or 0)
    if abs(exponent) > _MAX_EXPONENT:
        raise ValueError(f"number out of range: {text!r}")
    suffix = rest.lower()
    try:
        mantissa = Decimal(match["mantissa"])
    except InvalidOperation:  # pragma: no cover - the pattern admits only decimal digits
        raise ValueError(f"not a number: {text!r}") from None
    if suffix.startswith("meg"):
        exponent += 6
        factor = Decimal(1)
    elif suffix.startswith("mil"):
        factor = Decimal("25.4e-6")
    elif suffix[:1] in _POWERS:
        exponent += _POWERS[suffix[:1]]
        factor = Decimal(1)
    else:
        factor = Decimal(1)  # no suffix, or unit letters only (V, A, Hz, Ohm)
    sign, digits, exp = mantissa.as_tuple()
    scaled = Decimal((sign, digits, exp + exponent))
    if factor != 1:
        # 25.4e-6 has three significant digits: exact in a wide enough context.
        scaled = scaled.fma(factor, Decimal(0), context=_wide_context(len(digits)))
    value = float(scaled)
    if not math.isfinite(value):
        raise ValueError(f"number out of range: {text!r} (beyond the float range)")
    return value


def _wide_context(digits: int) -> Context:
    return Context(prec=digits + 8, Emax=10 * _MAX_EXPONENT, Emin=-10 * _MAX_EXPONENT)


# Suffixes tried by format_value, most readable first.
_FORMAT_SUFFIXES = (
    ("", 0),
    ("k", 3),
    ("meg", 6),
    ("g", 9),
    ("t", 12),
    ("m", -3),
    ("u", -6),
    ("n", -9),
    ("p", -12),
    ("f", -15),
)


def format_value(x: float) -> str:
    """A short SPICE text for ``x`` that :func:`parse_value` reads back to the same float.

    Tries the engineering form with the suffix that puts the mantissa in [1, 1000)
    (``4.7k``, ``10u``, ``1meg``) using the fewest digits that round-trip exactly; falls back
    to ``repr(x)`` (``1e-20``) when that is shorter or no suffix fits.

    Parameters
    ----------
    x : float
        A finite number.

    Raises
    ------
    ValueError
        For infinity or NaN, which SPICE cannot write as a number.
    """
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write {x!r} as a SPICE number")
    plain = repr(x)
    if plain.endswith(".0"):
        plain = plain[:-2]
    if x == 0.0:
        return "0" if math.copysign(1.0, x) > 0 else "-0"
    best = plain
    magnitude = math.floor(math.log10(abs(x)))
    for suffix, power in _FORMAT_SUFFIXES:
        if not (power <= magnitude < power + 3) and power != 0:
            continue
        if power == 0 and not (-3 < magnitude < 3):
            continue
        for digits in range(1, 18):
            mantissa = f"{x / 10.0**power:.{digits}g}"
            if "e" in mantissa:
                continue
            candidate = mantissa + suffix
            if _reads_back(candidate, x):
                if len(candidate) < len(best):
                    best = candidate
                break
    return best


def _reads_back(text: str, x: float) -> bool:
    try:
        return parse_value(text) == x
    except ValueError:
        return False
