"""Shorthands of [nonlinear.NAME]: each compiled abs() form against the function it names."""

import numpy as np
import pytest

from circuitsim.mechanics import ModelError, load_model
from circuitsim.mechanics.pwlfit import FitError, fit_piecewise_linear
from circuitsim.synthesis.pwl import dead_zone_shape

BASE = """
[model]
name = "shapes"
kind = "second_order"

[coordinates]
names = ["x", "z"]
units = ["m", "m"]

[parameters]
m = 1.0
k = 4.0
eta = 0.01
L = 0.02
kc = 300.0
Fs = 2.0
u0 = 0.05

[matrices]
M = [["m", 0], [0, "m"]]
K = [["k", 0], [0, "k"]]

[nonlinear.term]
enters = { x = 1 }
"""

# states x, z, x_dot, z_dot; the shorthands' argument u = x - 2 z + 0.003 (a row and offset)
ROW = 'row = { x = 1, z = -2 }, offset = 0.003'


def term_of(tmp_path, shape: str):
    path = tmp_path / "shapes.toml"
    path.write_text(BASE + shape + "\n")
    return load_model(path).system().nonlinear[0]


def states_for(u: np.ndarray) -> np.ndarray:
    """States whose argument x - 2 z + 0.003 is u (z chosen nonzero so the row matters)."""
    z = 0.25 * np.sin(7 * u)
    x = u - 0.003 + 2 * z
    return np.vstack([x, z, np.zeros_like(u), np.zeros_like(u)])


U = np.linspace(-0.1, 0.1, 200_001)


def test_deadzone_is_zero_inside_and_slope_outside(tmp_path):
    term = term_of(tmp_path, f'deadzone = {{ {ROW}, eta = "eta", slope = "kc" }}')
    expected = 300.0 * np.where(np.abs(U) <= 0.01, 0.0, U - np.sign(U) * 0.01)
    assert np.max(np.abs(term.value(states_for(U)) - expected)) < 1e-12
    assert len(term.abs_terms) == 2
    # the form the translator's one-block dead zone recognizes (row, eta, slope)
    row, eta, slope = dead_zone_shape(term_of(tmp_path, 'deadzone = { row = { x = 1 }, '
                                               'eta = "eta", slope = "kc" }'))  # fmt: skip
    assert eta == pytest.approx(0.01) and slope == pytest.approx(300.0)


def test_saturation_clips_at_the_limit(tmp_path):
    term = term_of(tmp_path, f'saturation = {{ {ROW}, limit = "L", slope = "kc" }}')
    expected = 300.0 * np.clip(U, -0.02, 0.02)
    assert np.max(np.abs(term.value(states_for(U)) - expected)) < 1e-12


def test_breakpoint_table_has_the_given_slopes_and_passes_through_zero(tmp_path):
    breakpoints, slopes = [-0.05, -0.01, 0.02], [500.0, 0.0, 30.0, 900.0]
    term = term_of(
        tmp_path, f"table = {{ {ROW}, breakpoints = {breakpoints}, slopes = {slopes} }}"
    )

    def integral_of_slopes(u: float) -> float:  # f(u) = integral of the slope from 0 to u
        edges = [-np.inf, *breakpoints, np.inf]
        total = 0.0
        for low, high, slope in zip(edges[:-1], edges[1:], slopes, strict=True):
            a, b = max(min(0.0, u), low), min(max(0.0, u), high)
            if b > a:
                total += slope * (b - a) * (1 if u > 0 else -1)
        return total

    sample = U[::997]
    expected = np.array([integral_of_slopes(u) for u in sample])
    assert np.max(np.abs(term.value(states_for(sample)) - expected)) < 1e-12
    assert len(term.abs_terms) == 3


def test_fitted_function_is_within_its_bound_on_a_dense_grid(tmp_path):
    bound = 0.005 * 2.0
    term = term_of(
        tmp_path,
        f'fit = {{ {ROW}, function = "Fs*tanh(v/u0)", variable = "v", range = [-0.1, 0.1], '
        'max_error = "0.005*Fs" }',
    )
    (fit,) = term.fits
    error = np.max(np.abs(term.value(states_for(U)) - 2.0 * np.tanh(U / 0.05)))
    assert error <= bound
    assert error <= fit.max_error <= bound  # the reported figure is a bound, not a sample
    assert fit.max_error < 1.01 * error  # ... and a tight one
    assert len(term.abs_terms) == fit.segments - 1
    # outside the range the end slopes continue
    assert np.all(np.diff(term.value(states_for(np.array([0.1, 0.2, 0.3]))), 2) == pytest.approx(0))


@pytest.mark.parametrize(
    ("function", "lower", "upper", "bound"),
    [
        (lambda u: u**3, -1.0, 1.0, 1e-3),
        (np.exp, 0.0, 3.0, 1e-2),
        (lambda u: 1e5 * u * np.abs(u), -0.02, 0.03, 0.1),  # a progressive stop, asymmetric
        (lambda u: 2 * u + 1, -1.0, 1.0, 1e-9),  # a straight line needs one piece
    ],
)
def test_fit_error_on_a_dense_grid_is_within_the_bound(function, lower, upper, bound):
    fit = fit_piecewise_linear(function, lower, upper, bound)
    u = np.linspace(lower, upper, 1_000_001)
    assert np.max(np.abs(fit(u) - function(u))) <= fit.max_error <= bound


def test_fit_uses_fewer_pieces_than_chord_interpolation_needs():
    # tanh on [-3, 3] within 0.01: the chord interpolant needs h = sqrt(8 e / |f''|) per piece;
    # minimax values allow about sqrt(2) longer pieces
    fit = fit_piecewise_linear(np.tanh, -3.0, 3.0, 0.01)
    assert fit.segments <= 10


def test_a_fit_passes_through_the_function_at_zero_unless_told_otherwise(tmp_path):
    # a minimax fit of an odd function is otherwise off by up to its bound at rest
    text = 'fit = {{ row = {{ x = 1 }}, function = "Fs*tanh(u/u0)", range = [-0.1, 0.3], ' \
        'max_error = 0.01{extra} }}'  # fmt: skip
    at_rest = np.zeros((4, 1))
    term = term_of(tmp_path, text.format(extra=""))
    assert term.value(at_rest)[0] == pytest.approx(0.0, abs=1e-12) and 0.0 in term.fits[0].knots
    free = term_of(tmp_path, text.format(extra=", exact_at = []"))
    assert abs(free.value(at_rest)[0]) > 1e-4
    pinned = term_of(tmp_path, text.format(extra=", exact_at = [0.05, 0.2]"))
    x = np.zeros((4, 2))
    x[0] = [0.05, 0.2]
    assert pinned.value(x) == pytest.approx(2.0 * np.tanh(x[0] / 0.05), abs=1e-12)
    u = np.linspace(-0.1, 0.3, 400_001)
    for fitted in (term, free, pinned):
        states = np.vstack([u, np.zeros((3, u.size))])
        assert np.max(np.abs(fitted.value(states) - 2.0 * np.tanh(u / 0.05))) <= 0.01


def test_fit_refuses_what_it_cannot_do():
    with pytest.raises(FitError, match="at most 40 segments"):
        fit_piecewise_linear(np.sin, 0.0, 100.0, 1e-4)
    with pytest.raises(FitError, match="lower < upper"):
        fit_piecewise_linear(np.sin, 1.0, 1.0, 1e-4)


@pytest.mark.parametrize(
    ("shape", "key", "words"),
    [
        (f'deadzone = {{ {ROW}, eta = 0, slope = "kc" }}', "nonlinear.term.deadzone.eta", "> 0"),
        (f'deadzone = {{ {ROW}, slope = "kc" }}', "nonlinear.term.deadzone.eta", "missing key"),
        (f'saturation = {{ {ROW}, limit = "-L", slope = 1 }}', "nonlinear.term.saturation.limit",
         "> 0"),  # fmt: skip
        (f'saturation = {{ {ROW}, limit = "L", slope = 1, gain = 2 }}',
         "nonlinear.term.saturation.gain", "unknown key"),  # fmt: skip
        (f"table = {{ {ROW}, breakpoints = [0.1, 0.0], slopes = [1, 2, 3] }}",
         "nonlinear.term.table.breakpoints", "must increase strictly"),  # fmt: skip
        (f"table = {{ {ROW}, breakpoints = [0.1], slopes = [1, 2, 3] }}",
         "nonlinear.term.table.slopes", "1 breakpoints need 2 slopes"),  # fmt: skip
        (f"table = {{ {ROW}, breakpoints = 0.1, slopes = [1, 2] }}",
         "nonlinear.term.table.breakpoints", "expected a non-empty array"),  # fmt: skip
        ('table = { row = { q = 1 }, breakpoints = [0], slopes = [1, 2] }',
         "nonlinear.term.table.row.q", "unknown name"),  # fmt: skip
        (f'fit = {{ {ROW}, function = "sin(u)", range = [0, 100], max_error = 1e-4 }}',
         "nonlinear.term.fit", "at most 40 segments"),  # fmt: skip
        (f'fit = {{ {ROW}, function = "u", range = [0, 1], max_error = 1, variable = "k" }}',
         "nonlinear.term.fit.variable", "also a parameter"),  # fmt: skip
        (f'fit = {{ {ROW}, function = "q*u", range = [0, 1], max_error = 1 }}',
         "nonlinear.term.fit.function", "unknown name 'q'"),  # fmt: skip
        (f'fit = {{ {ROW}, function = "log(u)", range = [-1, 1], max_error = 1 }}',
         "nonlinear.term.fit.function", "not a finite real number at u = -1"),  # fmt: skip
        (f'fit = {{ {ROW}, function = "u**", range = [0, 1], max_error = 1 }}',
         "nonlinear.term.fit.function", "bad expression"),  # fmt: skip
        (f'fit = {{ {ROW}, function = "u", range = [0, 1], max_error = 1, exact_at = [2] }}',
         "nonlinear.term.fit", "outside the range"),  # fmt: skip
        (f'fit = {{ {ROW}, function = "u", range = [0, 1], max_error = 1, exact_at = 0 }}',
         "nonlinear.term.fit.exact_at", "expected an array"),  # fmt: skip
        (f'fit = {{ {ROW}, function = "u", range = [0], max_error = 1 }}',
         "nonlinear.term.fit.range", "wrong length"),  # fmt: skip
        (f'fit = {{ {ROW}, function = "u", range = [1, 0], max_error = 1 }}',
         "nonlinear.term.fit", "lower < upper"),  # fmt: skip
        (f'fit = {{ {ROW}, function = "u", range = [0, 1], max_error = 0 }}',
         "nonlinear.term.fit", "must be > 0"),  # fmt: skip
        (f'fit = {{ {ROW}, function = "u", range = [0, 1], max_error = 1, max_segments = 0 }}',
         "nonlinear.term.fit.max_segments", "integer"),  # fmt: skip
    ],
)
def test_shorthand_errors_name_file_key_and_fault(tmp_path, shape, key, words):
    with pytest.raises(ModelError, match=words) as caught:
        term_of(tmp_path, shape)
    assert caught.value.key == key
    assert str(caught.value).startswith(f"{tmp_path / 'shapes.toml'}: {key}: ")
