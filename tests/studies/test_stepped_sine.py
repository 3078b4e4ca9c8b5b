"""Stepped-sine response curves: the steady amplitude against an analytic receptance, the
jumps of a hardening contact on the ODE and circuit paths against a plain scipy stepped sine
of the same equations typed again here, and the CLI verb.

The oscillator: m x'' + c x' + k x + F_c(x) = F0 sin(2 pi f t), with F_c the contact of a
stiff stop beyond a clearance g on either side (kf (x - g) beyond g, kf (x + g) below -g, 0
between), written as kf x - kf/2 |x + g| + kf/2 |x - g|.
"""

import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from circuitsim.cli import main
from circuitsim.mechanics import load_model
from circuitsim.studies.hunting_result import HuntingSettings
from circuitsim.studies.stepped_sine import jumps, relative_difference, run_stepped_sine

M, K, KF, G, F0 = 1.0, 157.9, 600.0, 0.01, 0.5  # kg, N/m, N/m, m, N

MODEL = """
[model]
name = "hardening"
kind = "second_order"

[coordinates]
names = ["x"]
units = ["m"]

[parameters]
m = {{ value = {m}, unit = "kg" }}
k = {{ value = {k}, unit = "N/m" }}
c = {{ value = {c}, unit = "N s/m" }}
kf = {{ value = {kf}, unit = "N/m" }}
g = {{ value = {g}, unit = "m" }}
f = {{ value = 2.0, unit = "Hz" }}
F0 = {{ value = {f0}, unit = "N" }}

[options]
freq = "f"

[matrices]
M = [["m"]]
C = [["c"]]
K = [["k"]]

[nonlinear.contact]
enters = {{ x = 1 }}
linear = {{ x = "kf" }}
abs = [
    {{ gain = "-kf / 2", row = {{ x = 1 }}, offset = "g" }},
    {{ gain = "kf / 2", row = {{ x = 1 }}, offset = "-g" }},
]

[forcing.push]
amplitude = "F0"
unit = "N"
frequency = "f"
enters = {{ x = 1 }}
"""


def _model(tmp_path, c: float):
    path = tmp_path / "hardening.toml"
    path.write_text(MODEL.format(m=M, k=K, c=c, kf=KF, g=G, f0=F0))
    return path, load_model(path)


def _system_at(model):
    def system_at(frequency: float, contact: bool):
        return model.system(
            None, model.option_parameters({"freq": frequency}), {"contact": contact}
        )

    return system_at


def test_the_steady_amplitude_of_the_linear_oscillator_is_its_receptance(tmp_path):
    c = 1.2  # zeta 0.048: transients die out e^-12 within the settling time
    _, model = _model(tmp_path, c)
    frequencies = np.array([1.0, 1.8, 2.0, 2.2, 3.0])
    settings = HuntingSettings(settle=20.0, record=2.0, repush=0.0)
    result = run_stepped_sine(_system_at(model), frequencies, settings, (False,), circuit=False)
    w = 2 * np.pi * frequencies
    exact = F0 / np.abs(K - M * w**2 + 1j * c * w)
    up = result.branch("ode", "up", False)
    down = result.branch("ode", "down", False)
    assert np.allclose(up.amplitude, exact, rtol=1e-3)
    assert np.allclose(down.amplitude[::-1], exact, rtol=1e-3)
    assert not jumps(up, down) and not jumps(down, up)
    assert jumps(up)  # a steep single-valued peak: only the direction test tells it apart


def _scipy_stepped_sine(c: float, frequencies, settle: float, record: float) -> np.ndarray:
    """The same protocol on the typed equation: each step from the last state, max |x| over
    the record window, solve_ivp with a step bound far below the contact's duration."""

    def contact(x):
        return KF * x - KF / 2 * abs(x + G) + KF / 2 * abs(x - G)

    state, out = np.zeros(2), []
    for f in frequencies:
        w = 2 * np.pi * f

        def rhs(t, y, w=w):
            x, v = y
            return [v, (F0 * np.sin(w * t) - c * v - K * x - contact(x)) / M]

        t = np.linspace(settle, settle + record, 2001)
        sol = solve_ivp(rhs, (0.0, settle + record), state, rtol=1e-10, atol=1e-13,
                        max_step=2e-3, dense_output=True)  # fmt: skip
        out.append(float(np.max(np.abs(sol.sol(t)[0]))))
        state = sol.y[:, -1]
    return np.array(out)


@pytest.mark.slow
def test_a_hardening_contact_jumps_at_the_same_frequencies_on_both_paths(tmp_path):
    c = 0.5  # zeta 0.02
    _, model = _model(tmp_path, c)
    # from below the bistable range, so that the up sweep climbs the upper branch
    frequencies = np.array([1.5, 2.0, 2.3, 2.5, 2.6, 2.65, 2.7, 2.75, 2.8, 2.9])
    settings = HuntingSettings(settle=20.0, record=2.0, repush=0.0)
    result = run_stepped_sine(_system_at(model), frequencies, settings, (True,))
    reference_up = _scipy_stepped_sine(c, frequencies, 20.0, 2.0)
    reference_down = _scipy_stepped_sine(c, frequencies[::-1], 20.0, 2.0)
    ode_up, ode_down = (result.branch("ode", d, True) for d in ("up", "down"))
    assert np.allclose(ode_up.amplitude, reference_up, rtol=1e-3)
    assert np.allclose(ode_down.amplitude[::-1], reference_down[::-1], rtol=1e-3)
    for direction in ("up", "down"):
        assert relative_difference(result, direction, True) < 0.01
    found = {
        (path, d): [
            j.frequency
            for j in jumps(
                result.branch(path, d, True),
                result.branch(path, "down" if d == "up" else "up", True),
            )
        ]
        for path in ("ode", "circuit")
        for d in ("up", "down")
    }
    (up,) = found["ode", "up"]
    (down,) = found["ode", "down"]
    assert found["circuit", "up"] == [up] and found["circuit", "down"] == [down]
    assert down < up  # the hysteresis of a hardening system: it jumps down later going up
    ratios = reference_up[1:] / reference_up[:-1]
    jump_index = int(np.argmin(ratios))  # scipy's jump down, sweeping up
    assert ratios[jump_index] < 1 / 1.5
    assert up == pytest.approx(frequencies[jump_index : jump_index + 2].mean(), rel=1e-9)


def test_cli_stepped_sine_writes_the_curves(tmp_path, capsys):
    path, _ = _model(tmp_path, 1.2)
    out = tmp_path / "out"
    args = ["stepped-sine", "--model", str(path), "--freqs", "1.5,2,2.5", "--settle", "5",
            "--record", "1", "--no-circuit", "--out", str(out)]  # fmt: skip
    assert main([*args, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["frequencies_hz"] == [1.5, 2.0, 2.5] and data["state"] == "x"
    assert data["flange"]["on"]["ode_up_jumps_hz"] == []
    lines = (out / "stepped_sine.csv").read_text().splitlines()
    assert lines[0].startswith("f (Hz),direction,path,flange,amplitude_x (m)")
    assert len(lines) == 1 + 6 and (out / "stepped_sine.png").stat().st_size > 10_000
    assert main([*args[:-2], "--freq", "2", "--out", str(out)]) == 2
