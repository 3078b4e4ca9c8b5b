"""Inputs beyond one sinusoid: a step, a time series, a bump, a sum of sines.

Each is solved by :func:`circuitsim.mechanics.solve` (restarted at every corner) and compared
with an independent solution: the closed form of an undamped oscillator's step response, and
for the first-order system x' = -a x + u(t) the convolution x(t) = x0 e^{-at} + int_0^t
e^{-a(t-s)} u(s) ds evaluated by scipy's quad with the corners as break points.
"""

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from circuitsim.mechanics import load_model, solve
from circuitsim.mechanics.system import Bump, PiecewiseLinearInput, Sinusoid

FIRST_ORDER = """
[model]
name = "lag"
kind = "first_order"
[states]
names = ["x"]
units = ["m"]
[parameters]
a = 3.0
[matrices]
A = [["-a"]]
"""


def write(tmp_path: Path, forcing: str, header: str = FIRST_ORDER) -> Path:
    path = tmp_path / "model.toml"
    path.write_text(header + forcing)
    return path


def convolution(u, a: float, t: np.ndarray, corners) -> np.ndarray:
    """x(t) of x' = -a x + u(t), x(0) = 0, by quadrature."""
    out = []
    for time in t:
        inside = [c for c in corners if 0 < c < time]
        value, _ = quad(lambda s, time=time: math.exp(-a * (time - s)) * u(s), 0, time,
                        points=inside or None, limit=400, epsabs=1e-13, epsrel=1e-11)  # fmt: skip
        out.append(value)
    return np.array(out)


def test_step_on_an_oscillator_is_the_closed_form(tmp_path):
    header = """
[model]
name = "osc"
kind = "second_order"
[coordinates]
names = ["x"]
units = ["m"]
[parameters]
m = 2.0
k = 50.0
[matrices]
M = [["m"]]
K = [["k"]]
"""
    forcing = """
[forcing.push]
kind = "step"
amplitude = 3.0
start = 0.3
unit = "N"
enters = { x = 1 }
"""
    system = load_model(write(tmp_path, forcing, header)).system()
    (step,) = system.forcing
    assert isinstance(step, PiecewiseLinearInput) and step.kind == "step"
    result = solve(system, (0.0, 2.0))
    t = np.linspace(0.0, 2.0, 801)
    omega = math.sqrt(50.0 / 2.0)
    exact = np.where(t > 0.3, 3.0 / 50.0 * (1 - np.cos(omega * (t - 0.3))), 0.0)
    assert np.max(np.abs(result.sol(t)[0] - exact)) < 1e-9
    assert 0.3 in result._starts  # the run restarted at the step


def test_time_series_from_csv_with_units(tmp_path):
    # distances in mm along the track, travelled at 20 m/s: t = s / V
    (tmp_path / "profile.csv").write_text(
        "# a made-up profile\ndistance_m,z_mm\n0, 0\n4, 2.5\n10, -1.5\n12, -1.5\n20, 0\n"
    )
    forcing = """
[forcing.road]
kind = "series"
file = "profile.csv"
speed = "V"
value_unit = "mm"
unit = "m"
amplitude = 2.0
enters = { x = "a" }
"""
    header = FIRST_ORDER.replace("a = 3.0", "a = 3.0\nV = 20.0")
    system = load_model(write(tmp_path, forcing, header)).system()
    (road,) = system.forcing
    np.testing.assert_allclose(road.times, [0.0, 0.2, 0.5, 0.6, 1.0])
    np.testing.assert_allclose(road.values, [0.0, 5e-3, -3e-3, -3e-3, 0.0])
    result = solve(system, (0.0, 1.5))
    t = np.linspace(0.05, 1.5, 30)
    exact = convolution(lambda s: 3.0 * road.value(s), 3.0, t, road.times)
    assert np.max(np.abs(result.sol(t)[0] - exact)) < 1e-9
    assert set(np.round(road.times[1:], 12)) <= set(np.round(result._starts, 12))


def test_inline_points_hold_their_ends(tmp_path):
    forcing = """
[forcing.u]
kind = "series"
points = [[0.5, 1.0], [1.0, 3.0], [1.0, -1.0], [2.0, 0.0]]
enters = { x = 1 }
"""
    system = load_model(write(tmp_path, forcing)).system()
    (u,) = system.forcing
    assert u.value(0.0) == 1.0 and u.value(0.75) == 2.0 and u.value(3.0) == 0.0
    assert u.value(1.0) == -1.0  # after the jump
    result = solve(system, (0.0, 2.5))
    t = np.linspace(0.1, 2.5, 25)
    exact = convolution(u.value, 3.0, t, [0.5, 1.0, 2.0])
    assert np.max(np.abs(result.sol(t)[0] - exact)) < 1e-9


@pytest.mark.parametrize("shape", ["haversine", "half_sine"])
def test_bump(tmp_path, shape):
    forcing = f"""
[forcing.bump]
kind = "bump"
shape = "{shape}"
amplitude = 0.5
start = 0.2
duration = 0.4
enters = {{ x = 1 }}
"""
    system = load_model(write(tmp_path, forcing)).system()
    (bump,) = system.forcing
    assert isinstance(bump, Bump)
    middle = 0.5 if shape == "haversine" else 0.5
    assert bump.value(0.4) == pytest.approx(middle)  # the peak at the middle
    assert bump.value(0.1) == 0.0 and bump.value(0.7) == 0.0
    result = solve(system, (0.0, 1.0))
    t = np.linspace(0.05, 1.0, 20)
    exact = convolution(bump.value, 3.0, t, [0.2, 0.6])
    assert np.max(np.abs(result.sol(t)[0] - exact)) < 1e-9


def test_sum_of_sines_is_one_sinusoid_each(tmp_path):
    forcing = """
[forcing.track]
kind = "sines"
amplitudes = [1.0, "a / 6"]
frequencies = [0.5, 2.0]
phases = [0, 1.0]
enters = { x = 1 }
"""
    system = load_model(write(tmp_path, forcing)).system()
    assert [type(f) for f in system.forcing] == [Sinusoid, Sinusoid]
    assert [f.name for f in system.forcing] == ["track1", "track2"]
    assert system.forcing[1].amplitude == 0.5 and system.forcing[1].phase == 1.0

    def u(s):
        return math.sin(math.pi * s) + 0.5 * math.sin(4 * math.pi * s + 1.0)

    result = solve(system, (0.0, 2.0))
    t = np.linspace(0.1, 2.0, 20)
    assert np.max(np.abs(result.sol(t)[0] - convolution(u, 3.0, t, []))) < 1e-9
