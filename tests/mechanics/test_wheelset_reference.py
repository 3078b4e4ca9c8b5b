"""The wheelset against the reference results of docs/model.md (computed independently,
rtol 1e-11)."""

import numpy as np
import pytest

from circuitsim.mechanics import load_model, solve

# docs/model.md, "Reference results": f (Hz), flange -> max|y| (mm), y(5 s) (mm), max|y'| (m/s)
FORCED = {
    (3, False): (21.339, 1.2725, 0.5526),
    (3, True): (14.265, 0.8557, 0.4772),
    (5, False): (34.053, 3.9377, 1.3162),
    (5, True): (16.599, -0.0154, 0.6703),
    (10, False): (89.035, -23.9568, 5.1443),
    (10, True): (26.706, -10.0155, 1.5942),
}


@pytest.fixture(scope="module")
def wheelset():
    return load_model()


@pytest.mark.parametrize(("frequency", "flange"), sorted(FORCED))
def test_forced_response_matches_model_md(wheelset, frequency, flange):
    system = wheelset.system(
        coefficients="paper",
        parameters={"V": 55, "f": frequency, "a": 0.040},
        nonlinear={"flange": flange},
    )
    result = solve(system, t_span=(0, 5), rtol=1e-10, atol=1e-12)
    max_y, y_end, max_rate = FORCED[(frequency, flange)]
    assert result.max_abs("y") * 1e3 == pytest.approx(max_y, rel=1e-3)
    assert result.sol(5.0)[0] * 1e3 == pytest.approx(y_end, rel=1e-3)
    assert result.max_abs("y_dot") == pytest.approx(max_rate, rel=1e-3)
    if flange:
        # the wheelset keeps striking the rail: kinks at |y| = eta, and only there
        y_at_kinks = result.sol(result.kinks)[0]
        assert len(result.kinks) > 10
        assert abs(y_at_kinks) == pytest.approx(0.009, abs=1e-12)
    else:
        assert len(result.kinks) == 0


@pytest.mark.parametrize(("speed", "expected"), [(54, 4.14e-6), (57, 1.223)])
def test_free_response_decays_below_and_grows_above_critical_speed(wheelset, speed, expected):
    system = wheelset.system(
        parameters={"V": speed},
        nonlinear={"flange": False},
        forcing={"track": False},
        x0={"y": 0.005},
    )
    result = solve(system, t_span=(0, 10))
    assert result.max_abs("y", 9.0, 10.0) == pytest.approx(expected, rel=1e-2)


def test_plain_force_equals_track_displacement_times_k_y(wheelset):
    # reference: F0 = k_y * a; the 'force' group written with F0 must give the same motion
    track = wheelset.system(parameters={"f": 5, "a": 0.01})
    force = wheelset.system(
        parameters={"f": 5, "F0": 4.81e6 * 0.01}, forcing={"track": False, "force": True}
    )
    assert np.allclose(track.forcing[0].direction * 0.01, force.forcing[0].direction * 4.81e4)
    t = np.linspace(0, 1, 201)
    a, b = solve(track, (0, 1)).sol(t), solve(force, (0, 1)).sol(t)
    assert np.max(np.abs(a - b)) < 1e-9 * np.max(np.abs(a))


def test_wheelset_state_matrix_is_equation_5(wheelset):
    # equation (5) written out by hand at V = 55 m/s
    V = 55.0
    expected = np.array(
        [
            [0, 0, 1, 0],
            [0, 0, 0, 1],
            [-4.81e6 / 1500, 7.24e6 / 1500, -7.24e6 / V / 1500, 0],
            [-4.02e6 / 1200, -3.07e6 / 1200, 0, -4.36e6 / V / 1200],
        ]
    )
    system = wheelset.system(parameters={"V": V})
    assert np.allclose(system.A, expected, rtol=1e-14, atol=0)
    flange = system.nonlinear[0]
    # F_t(y) = k y - (k/2)(|y + eta| - |y - eta|) on the left of the lateral equation
    for y, expected_force in [
        (0.0, 0.0),
        (0.005, 0.0),
        (0.012, 1.7e7 * 0.003),
        (-0.02, -1.7e7 * 0.011),
    ]:
        x = np.array([y, 0, 0, 0])
        assert flange.value(x) == pytest.approx(expected_force, abs=1e-6)
    assert np.allclose(flange.direction, [0, 0, -1 / 1500, 0])


def test_no_step_straddles_a_kink(wheelset):
    # between consecutive kinks every solver point lies on one side of each |y -+ eta|
    result = solve(wheelset.system(parameters={"f": 5}), t_span=(0, 2))
    edges = np.concatenate(([0.0], result.kinks, [2.0]))
    y = result.state("y")
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        inside = (result.t > lo) & (result.t < hi)
        for offset in (0.009, -0.009):
            signs = np.sign(y[inside] + offset)
            assert np.all(signs == signs[0])


def test_circuit_table_is_passed_through(tmp_path):
    text = (
        '[model]\nname = "s"\nkind = "first_order"\n[states]\nnames = ["x"]\n'
        "[matrices]\nA = [[-1]]\n"
        '[circuit]\nintegrators = { x = "U1A" }\nnotes = ["R1 sets 1/RC"]\n'
    )
    path = tmp_path / "s.toml"
    path.write_text(text)
    system = load_model(path).system()
    assert system.circuit_hints == {"integrators": {"x": "U1A"}, "notes": ["R1 sets 1/RC"]}
