"""Expression evaluation against the same arithmetic written directly in Python's math."""

import math

import pytest

from circuitsim.netlist.expressions import check_syntax, evaluate, names_in

P = {"rbase": 10e3, "C1": 100e-9, "gain": 2.0, "x": -3.0}

CASES = [
    ("1+2*3", 7.0),
    ("(1+2)*3", 9.0),
    ("10/4", 2.5),
    ("2**10", 1024.0),
    ("2^10", 1024.0),
    ("2^3^2", 2.0 ** (3.0**2)),  # right-associative
    ("-2^2", -4.0),  # power binds tighter than unary minus
    ("--3", 3.0),
    ("+3", 3.0),
    ("2*-3", -6.0),
    ("1k*2", 2000.0),
    ("10u/4", 10e-6 / 4),
    ("1meg + 1MEG", 2e6),
    ("2*rbase", 20e3),
    ("2*RBASE", 20e3),  # names are case-insensitive
    ("c1*rbase", 1e-3),
    ("1/(2*pi*rbase*c1)", 1 / (2 * math.pi * 10e3 * 100e-9)),
    ("pi()", math.pi),
    ("sqrt(16)", 4.0),
    ("exp(1)", math.e),
    ("ln(10)", math.log(10)),
    ("log(10)", math.log(10)),  # natural, as ngspice
    ("log10(1000)", 3.0),
    ("sin(pi/2)", 1.0),
    ("cos(0)", 1.0),
    ("tan(pi/4)", math.tan(math.pi / 4)),
    ("atan(1)*4", math.pi),
    ("abs(x)", 3.0),
    ("min(4, x, 2)", -3.0),
    ("max(4,x,2)", 4.0),
    ("pow(2, 0.5)", math.sqrt(2)),
    ("pow(x, 2)", 9.0),
    ("x^3", -27.0),
    ("  gain * ( 1 + 1 ) ", 4.0),
    ("1e3", 1000.0),
    (".5e1", 5.0),
]


@pytest.mark.parametrize(("text", "expected"), CASES)
def test_evaluate(text, expected):
    assert evaluate(text, P) == pytest.approx(expected, rel=1e-15, abs=1e-300)


def test_param_named_pi_wins_over_constant():
    assert evaluate("pi*2", {"PI": 3.0}) == 6.0


ERRORS = [
    ("", "empty expression"),
    ("1+", "unexpected end of the expression at column 3 in '1+'"),
    ("(1+2", "expected ')' but found the end at column 5 in '(1+2'"),
    ("1+2)", "unexpected ')' at column 4 in '1+2)'"),
    ("2*q", "undefined parameter 'q' in '2*q'"),
    ("foo(1)", "unknown function 'foo' in 'foo(1)'"),
    ("sqrt(1, 2)", "sqrt() takes 1 argument(s), got 2 in 'sqrt(1, 2)'"),
    ("sqrt", "function 'sqrt' needs its arguments in parentheses"),
    ("1 $ 2", "unexpected character '$' at column 3 in '1 $ 2'"),
    ("1 2", "unexpected '2' at column 3 in '1 2'"),
    ("1/0", "division by zero in '1/0'"),
    ("sqrt(-1)", "square root of a negative number (-1.0)"),
    ("ln(0)", "logarithm of a non-positive number (0.0)"),
    ("(-8)^(1/3)", "negative number -8.0 raised to the non-integer power"),
    ("10^400", "10.0 ** 400.0 is beyond the float range"),
    ("exp(1000)", "exp(1000.0) is beyond the float range"),
    ("1e308*10", "beyond the float range"),
    ("4k7", "bad number '4k7'"),
    ("a >= 1", "unexpected character '>'"),
]


@pytest.mark.parametrize(("text", "message"), ERRORS)
def test_evaluate_errors_name_the_culprit(text, message):
    with pytest.raises(ValueError) as info:
        evaluate(text, {"a": 1.0})
    assert message in str(info.value)


@pytest.mark.parametrize(
    "text", ["(" * 5000 + "1" + ")" * 5000, "-" * 5000 + "1", "2^" * 3000 + "2"]
)
def test_deep_nesting_is_a_value_error_not_a_recursion_error(text):
    with pytest.raises(ValueError, match="nested deeper than 100 levels"):
        evaluate(text, {})


def test_check_syntax_does_not_need_values():
    check_syntax("a/(b-1) + sqrt(c)")  # names unknown, b-1 would be 0 with dummy values
    with pytest.raises(ValueError, match="unknown function 'foo'"):
        check_syntax("foo(1)")
    with pytest.raises(ValueError, match="unexpected end"):
        check_syntax("a*")


def test_names_in():
    assert names_in("2*Rbase + sqrt(c1) + max(a, rbase)") == ["rbase", "c1", "a"]


def test_never_uses_python_eval():
    with pytest.raises(ValueError):
        evaluate("__import__('os')", {})
