"""The coefficient expression language against Python's own arithmetic."""

import math

import pytest

from circuitsim.mechanics.expressions import ExpressionError, parse

CASES = [
    ("7.24e6 / V", {"V": 55.0}, 7.24e6 / 55.0),
    ("-k / 2", {"k": 1.7e7}, -1.7e7 / 2),
    ("-2**2", {}, -4.0),
    ("2**3**2", {}, 512.0),
    ("2**-1", {}, 0.5),
    ("(1 + 2) * 3 - 4 / 8", {}, 8.5),
    ("1 - 2 - 3", {}, -4.0),
    ("8 / 4 / 2", {}, 1.0),
    ("2 * f11 * b**2 / V", {"f11": 3.98e6, "b": 0.74, "V": 55.0}, 2 * 3.98e6 * 0.74**2 / 55),
    ("sqrt(k / m) / (2*pi)", {"k": 50.0, "m": 2.0}, math.sqrt(25.0) / (2 * math.pi)),
    ("max(a, -a) + abs(-3) + exp(0) + log(1) + cos(0)", {"a": -2.0}, 2 + 3 + 1 + 0 + 1),
    ("+.5e1", {}, 5.0),
    (3, {}, 3.0),
    (2.5, {}, 2.5),
]


@pytest.mark.parametrize(("text", "env", "expected"), CASES)
def test_value(text, env, expected):
    assert parse(text)(env) == pytest.approx(expected, rel=1e-15)


def test_names_exclude_functions_and_pi():
    assert parse("sqrt(k / m) * pi + lambda").names == {"k", "m", "lambda"}


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("", "empty"),
        ("1 +", "expected a number"),
        ("(1 + 2", "expected '\\)'"),
        ("1 2", "unexpected"),
        ("a ^ 2", "use \\*\\*"),
        ("__import__(os)", "unknown function"),
        ("__import__('os')", "unexpected character"),
        ("sqrt", "needs arguments"),
        ("x[0]", "unexpected character"),
        (True, "expected a number"),
        ([1], "expected a number"),
    ],
)
def test_syntax_errors(text, words):
    with pytest.raises(ExpressionError, match=words):
        parse(text)


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("1 / 0", "division by zero"),
        ("q + 1", "unknown name 'q'"),
        ("sqrt(-1)", "cannot evaluate"),
        ("(-8) ** 0.5", "not real"),
        ("10 ** 400", "cannot evaluate"),
    ],
)
def test_evaluation_errors(text, words):
    with pytest.raises(ExpressionError, match=words):
        parse(text)({})
