"""The integrator against closed-form solutions: a forced damped oscillator and a particle
bouncing between two gap springs (kink crossing times known exactly)."""

import math
import textwrap

import numpy as np
import pytest

from circuitsim.mechanics import load_model, solve

OSCILLATOR = """
[model]
name = "forced_oscillator"
kind = "first_order"

[states]
names = ["x", "v"]
units = ["m", "m/s"]

[parameters]
m = 2.0
c = 0.6
k = 50.0
F0 = 3.0
Omega = 3.5
x0 = 0.02

[matrices]
A = [[0, 1], ["-k/m", "-c/m"]]

[forcing.push]
amplitude = "F0"
unit = "N"
frequency = "Omega / (2*pi)"
enters = { v = "1/m" }

[initial]
x = "x0"
"""

GAP = """
# a mass moving freely inside a gap |x| <= g, with a spring k beyond each side
[model]
name = "gap_oscillator"
kind = "second_order"

[coordinates]
names = ["x"]
units = ["m"]

[parameters]
m = 2.0
k = 50.0
g = 0.1
v0 = 0.5

[matrices]
M = [["m"]]
K = [[0]]

[nonlinear.gap]
enters = { x = 1 }
linear = { x = "k" }
abs = [
    { gain = "-k/2", row = { x = 1 }, offset = "g" },
    { gain = "k/2", row = { x = 1 }, offset = "-g" },
]

[initial]
x_dot = "v0"
"""


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def oscillator_exact(t, m, c, k, F0, Omega, x0):
    """m x'' + c x' + k x = F0 sin(Omega t), x(0) = x0, x'(0) = 0."""
    detuning = k - m * Omega**2
    denominator = detuning**2 + (c * Omega) ** 2
    P = F0 * detuning / denominator
    Q = -F0 * c * Omega / denominator
    omega = math.sqrt(k / m)
    zeta = c / (2 * math.sqrt(k * m))
    omega_d = omega * math.sqrt(1 - zeta**2)
    A = x0 - Q
    B = (0.0 - P * Omega + zeta * omega * A) / omega_d
    decay = np.exp(-zeta * omega * t)
    return decay * (A * np.cos(omega_d * t) + B * np.sin(omega_d * t)) + (
        P * np.sin(Omega * t) + Q * np.cos(Omega * t)
    )


def test_forced_damped_oscillator_matches_closed_form(tmp_path):
    model = load_model(write(tmp_path, "oscillator.toml", OSCILLATOR))
    system = model.system()
    result = solve(system, t_span=(0, 10))
    t = np.linspace(0, 10, 4001)
    exact = oscillator_exact(
        t, **{k: system.parameters[k] for k in ("m", "c", "k", "F0")}, Omega=3.5, x0=0.02
    )
    scale = np.max(np.abs(exact))
    assert np.max(np.abs(result.sol(t)[0] - exact)) < 1e-8 * scale
    # the solver points themselves, too
    exact_at_steps = oscillator_exact(result.t, 2.0, 0.6, 50.0, 3.0, 3.5, 0.02)
    assert np.max(np.abs(result.state("x") - exact_at_steps)) < 1e-8 * scale


def test_looser_tolerance_gives_larger_error(tmp_path):
    # the tolerance is actually used: 1e-4 is measurably worse than 1e-10 (but still close)
    model = load_model(write(tmp_path, "oscillator.toml", OSCILLATOR))
    t = np.linspace(0, 10, 2001)
    exact = oscillator_exact(t, 2.0, 0.6, 50.0, 3.0, 3.5, 0.02)
    loose = solve(model.system(), (0, 10), rtol=1e-4, atol=1e-8, method="RK45")
    tight = solve(model.system(), (0, 10))
    loose_error = np.max(np.abs(loose.sol(t)[0] - exact))
    tight_error = np.max(np.abs(tight.sol(t)[0] - exact))
    assert tight_error < loose_error / 100
    assert loose_error < 1e-3 * np.max(np.abs(exact))


def gap_exact(t, m=2.0, k=50.0, g=0.1, v0=0.5):
    """Kink times and x(t) of the gap oscillator from x=0, x'=v0 > 0."""
    omega = math.sqrt(k / m)
    free, contact = 2 * g / v0, math.pi / omega
    # first crossing at g/v0, then alternately a half-period in a spring and a free flight
    kinks = [g / v0]
    while kinks[-1] < t[-1]:
        kinks.append(kinks[-1] + (contact if len(kinks) % 2 else free))
    x = np.empty_like(t)
    for i, time in enumerate(t):
        if time < kinks[0]:
            x[i] = v0 * time
            continue
        j = np.searchsorted(kinks, time, side="right") - 1
        side = 1.0 if (j // 2) % 2 == 0 else -1.0  # +g wall first, then -g, ...
        tau = time - kinks[j]
        if j % 2 == 0:  # in contact with the spring at side*g
            x[i] = side * (g + (v0 / omega) * math.sin(omega * tau))
        else:  # free flight back across the gap
            x[i] = side * (g - v0 * tau)
    return np.array(kinks), x


def test_gap_oscillator_kink_times_and_trajectory(tmp_path):
    model = load_model(write(tmp_path, "gap.toml", GAP))
    assert model.states == ("x", "x_dot")
    result = solve(model.system(), t_span=(0, 3))
    t = np.linspace(0, 3, 3001)
    kinks, x = gap_exact(t)
    kinks = kinks[kinks < 3]
    assert len(result.kinks) == len(kinks)
    assert np.max(np.abs(result.kinks - kinks)) < 1e-9
    assert np.max(np.abs(result.sol(t)[0] - x)) < 1e-9
    # crossings alternate: |x - g| twice, then |x + g| twice (abs terms 1, 1, 0, 0, ...)
    assert [index for _, index in result.kink_terms[:4]] == [1, 1, 0, 0]


def test_gap_oscillator_switched_off_is_free_flight(tmp_path):
    model = load_model(write(tmp_path, "gap.toml", GAP))
    result = solve(model.system(nonlinear={"gap": False}), t_span=(0, 3))
    assert len(result.kinks) == 0
    assert result.sol(3.0)[0] == pytest.approx(1.5, rel=1e-12)


def test_start_exactly_on_a_kink_does_not_retrigger(tmp_path):
    # starting at x = g moving inwards-out: the crossing at t = 0 is not an event; the next one
    # is half a spring period later
    model = load_model(write(tmp_path, "gap.toml", GAP))
    result = solve(model.system(x0={"x": 0.1, "x_dot": 0.5}), t_span=(0, 1))
    assert result.kinks[0] == pytest.approx(math.pi / 5, abs=1e-9)
    assert result.sol(math.pi / 10)[0] == pytest.approx(0.1 + 0.5 / 5, rel=1e-9)


def test_grazing_start_on_a_kink_with_zero_rate(tmp_path):
    # at rest exactly on the kink with no force: nothing moves, no event storm
    model = load_model(write(tmp_path, "gap.toml", GAP))
    result = solve(model.system(x0={"x": 0.1, "x_dot": 0.0}), t_span=(0, 1))
    assert np.all(result.state("x") == pytest.approx(0.1, abs=1e-15))
    assert len(result.kinks) == 0


def test_dense_output_is_continuous_across_restarts(tmp_path):
    model = load_model(write(tmp_path, "gap.toml", GAP))
    result = solve(model.system(), t_span=(0, 3))
    for kink in result.kinks[:4]:
        before, after = result.sol(np.array([kink - 1e-9, kink + 1e-9])).T
        assert np.allclose(before, after, atol=1e-8)


def test_switch_on_time_ends_a_segment(tmp_path):
    # the gap springs only act from t_on: before it the mass flies freely past the wall
    text = GAP.replace("enters = { x = 1 }", "enters = { x = 1 }\nt_on = 0.5")
    model = load_model(write(tmp_path, "gap.toml", text))
    result = solve(model.system(), t_span=(0, 1))
    assert list(result.switches) == [0.5]
    assert result.sol(0.5)[0] == pytest.approx(0.25, rel=1e-12)
    # from t_on the spring at +g pushes back: x - g = 0.15 cos(5 (t - 0.5)) + 0.1 sin(5 (t - 0.5))
    tau = 0.2
    expected = 0.1 + 0.15 * math.cos(5 * tau) + (0.5 / 5) * math.sin(5 * tau)
    assert result.sol(0.5 + tau)[0] == pytest.approx(expected, rel=1e-9)


FIRST_ORDER_KINK = """
# x' = c - |x| from x(0) = -1: x = e^t - c for x < 0, crossing zero at t = ln(c) ...
[model]
name = "kinked_decay"
kind = "first_order"
[states]
names = ["x"]
[parameters]
c = 2.0
[matrices]
A = [[0]]
b = ["c"]
[nonlinear.v]
enters = { x = 1 }
abs = [{ gain = -1, row = [1] }]
[initial]
x = -1
"""


def test_first_order_kink_closed_form(tmp_path):
    model = load_model(write(tmp_path, "kink.toml", FIRST_ORDER_KINK))
    result = solve(model.system(), t_span=(0, 3))
    crossing = math.log(2.0)
    assert len(result.kinks) == 1
    assert result.kinks[0] == pytest.approx(crossing, abs=1e-10)  # rtol 1e-10, x ~ 1
    t = np.linspace(0, 3, 301)
    # ... then x' = c - x: x = c (1 - e^-(t - ln c))
    exact = np.where(t < crossing, np.exp(t) - 2.0, 2.0 * (1.0 - np.exp(-(t - crossing))))
    assert np.max(np.abs(result.sol(t)[0] - exact)) < 1e-9
