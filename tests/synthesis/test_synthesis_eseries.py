"""Standard values: rounding against the IEC 60063 tables and the half-step error bound."""

import math

import numpy as np
import pytest

from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.eseries import E24, E96, floor_to_series, round_to_series


def test_tables_are_the_standard_series():
    # E-series are geometric: E_N has N members per decade, member k close to 10**(k/N)
    for table, count, spread in ((E24, 24, 0.045), (E96, 96, 0.011)):
        assert len(table) == count
        ideal = 10 ** (np.arange(count) / count)
        assert np.max(np.abs(np.array(table) / ideal - 1)) < spread


@pytest.mark.parametrize(
    ("value", "series", "expected"),
    [
        (31.4e3, "E96", 31.6e3),
        (3118.5, "E96", 3090.0),
        (3118.5, "E24", 3000.0),
        (1000.0, "E96", 1000.0),
        (9.9e3, "E96", 10e3),
        (4.6e3, "E24", 4.7e3),
        (113950.0, "E96", 113e3),
        (881.35, "E96", 887.0),
    ],
)
def test_nearest_member(value, series, expected):
    assert round_to_series(value, series) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize(("series", "table"), [("E24", E24), ("E96", E96)])
def test_rounding_error_is_at_most_half_a_step(series, table):
    rng = np.random.default_rng(1)
    members = [*table, 10.0]
    widest = max(b / a for a, b in zip(members, members[1:], strict=False))
    bound = math.sqrt(widest) - 1  # half the widest log step of the table
    for value in 10 ** rng.uniform(2, 7, 500):
        assert abs(round_to_series(value, series) / value - 1) <= bound


def test_exact_keeps_the_value_and_bad_series_is_an_error():
    assert round_to_series(123.456789, "exact") == 123.456789
    with pytest.raises(SynthesisError, match="E12"):
        round_to_series(100.0, "E12")


def test_floor_to_series():
    assert floor_to_series(234.7, "E24") == 220.0
    assert floor_to_series(9.06, "E24") == 8.2
    assert floor_to_series(1.0, "E24") == 1.0
