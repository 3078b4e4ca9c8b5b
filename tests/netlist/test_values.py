"""SPICE numbers: every suffix and unit form against the decimal value written out by hand."""

import math

import pytest

from circuitsim.netlist.values import format_value, parse_value

# (text, value written independently in exponent form)
CASES = [
    ("1", 1.0),
    ("-2.5", -2.5),
    ("+3", 3.0),
    (".5", 0.5),
    ("5.", 5.0),
    ("1e3", 1e3),
    ("1E-3", 1e-3),
    ("1.5e+3", 1.5e3),
    ("2f", 2e-15),
    ("2F", 2e-15),
    ("3p", 3e-12),
    ("3P", 3e-12),
    ("4n", 4e-9),
    ("4.7u", 4.7e-6),
    ("4.7U", 4.7e-6),
    ("5m", 5e-3),
    ("5M", 5e-3),
    ("6k", 6e3),
    ("6K", 6e3),
    ("1meg", 1e6),
    ("1MEG", 1e6),
    ("1Meg", 1e6),
    ("2.2g", 2.2e9),
    ("2.2G", 2.2e9),
    ("3t", 3e12),
    ("3T", 3e12),
    ("1mil", 25.4e-6),
    ("2MIL", 50.8e-6),
    ("10kOhm", 10e3),
    ("10kohm", 10e3),
    ("1uF", 1e-6),
    ("100nF", 100e-9),
    ("5V", 5.0),
    ("2A", 2.0),  # ngspice has no atto: trailing A is a unit
    ("1e3Hz", 1e3),
    ("10Hz", 10.0),
    ("1MegHz", 1e6),
    ("1mV", 1e-3),
    ("1e-3k", 1.0),
    ("  7k  ", 7e3),
]


@pytest.mark.parametrize(("text", "expected"), CASES)
def test_parse_value(text, expected):
    assert parse_value(text) == expected


@pytest.mark.parametrize(
    "text", ["", "abc", "k", "1.2.3", "4k7", "1k-", "--1", "1e400", "1 2", "1e+", "0x10", "1µ"]
)
def test_parse_value_rejects_junk(text):
    with pytest.raises(ValueError, match="number"):
        parse_value(text)


def test_parse_value_underflow_is_zero():
    assert parse_value("1e-400") == 0.0


@pytest.mark.parametrize(
    ("x", "text"),
    [
        (1000.0, "1k"),
        (4.7e-6, "4.7u"),
        (1e6, "1meg"),
        (-2.2e-9, "-2.2n"),
        (1e-15, "1f"),
        (0.0, "0"),
    ],
)
def test_format_value_engineering(x, text):
    assert format_value(x) == text


@pytest.mark.parametrize(
    "x", [1 / 3, math.pi * 1e-7, 123456.789, 1e-20, 1e300, 25.4e-6, 0.1 + 0.2, -5e-324, 2.0**-40]
)
def test_format_value_round_trips_exactly(x):
    assert parse_value(format_value(x)) == x


def test_format_value_refuses_infinity():
    with pytest.raises(ValueError):
        format_value(math.inf)
