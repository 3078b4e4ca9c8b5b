"""Linear stability against the reference results (docs/model.md) and against a 1-DOF
oscillator with negative damping."""

import math
import re
import textwrap

import numpy as np
import pytest

from circuitsim.mechanics import ModelError, critical_speed, eigenvalues, load_model


@pytest.fixture(scope="module")
def wheelset():
    return load_model()


def test_paper_set_critical_speed_and_hunting_frequency(wheelset):
    speed, frequency = critical_speed(wheelset, "paper")
    assert speed == pytest.approx(55.6455, abs=1e-4)
    assert frequency == pytest.approx(8.477, abs=1e-3)


def test_derived_set(wheelset):
    speed, frequency = critical_speed(wheelset, "derived")
    assert speed == pytest.approx(55.626, abs=1e-3)
    assert frequency == pytest.approx(8.470, abs=1e-3)


def test_eq2_set_is_much_more_stable(wheelset):
    speed, _ = critical_speed(wheelset, "eq2")
    assert 150 < speed < 200


def test_derived_coefficients_follow_equation_4(wheelset):
    # reference: the derived set reproduces equation (5)'s rounded numbers
    c = wheelset.system("derived", {"V": 1.0}).coefficients
    paper = wheelset.system("paper", {"V": 1.0}).coefficients
    for name in paper:
        assert c[name] == pytest.approx(paper[name], rel=3e-3), name


def test_growth_changes_sign_at_the_critical_speed(wheelset):
    lam = eigenvalues(wheelset, "V", [54.0, 55.6455, 57.0], "paper")
    assert lam.shape == (3, 4)
    assert lam[0, 0].real < 0 < lam[2, 0].real
    assert abs(lam[1, 0].real) < 1e-4
    # conjugate pairs: the state matrix is real
    assert np.allclose(np.sort_complex(lam[0]), np.sort_complex(lam[0].conj()))


def test_flange_is_excluded_from_the_linear_part(wheelset):
    with_flange = eigenvalues(wheelset, "V", [55.0], "paper")
    A = wheelset.system(nonlinear={"flange": False}, parameters={"V": 55.0}).A
    assert np.allclose(np.sort_complex(with_flange[0]), np.sort_complex(np.linalg.eigvals(A)))


NEGATIVE_DAMPING = """
[model]
name = "van_der_pol_linear"
kind = "second_order"
[coordinates]
names = ["x"]
[parameters]
mu = 0.0
c = 0.3
k = 16.0
[matrices]
M = [[1]]
C = [["c - mu"]]
K = [["k"]]
"""


def test_oscillator_with_negative_damping_closed_form(tmp_path):
    # x'' + (c - mu) x' + k x = 0 loses stability at mu = c, oscillating at sqrt(k)/(2 pi) Hz
    path = tmp_path / "osc.toml"
    path.write_text(textwrap.dedent(NEGATIVE_DAMPING))
    model = load_model(path)
    value, frequency = critical_speed(model, parameter="mu", bracket=(0.01, 10.0))
    assert value == pytest.approx(0.3, rel=1e-10)
    assert frequency == pytest.approx(4.0 / (2 * math.pi), rel=1e-10)
    with pytest.raises(ModelError, match=r"is stable over the whole bracket, mu in \[0.01, 0.2\]"):
        critical_speed(model, parameter="mu", bracket=(0.01, 0.2))
    # unstable from mu = 0.3 on: a bracket above it is unstable all along, not "stable"
    with pytest.raises(ModelError, match=r"is unstable over the whole bracket, mu in \[1, 10\]"):
        critical_speed(model, parameter="mu", bracket=(1.0, 10.0))
    with pytest.raises(ModelError, match="unknown parameter 'V'"):
        critical_speed(model)


def test_bracket_messages_name_the_bracket(wheelset):
    # the wheelset's coefficients divide by V: a bracket holding V = 0 is the bracket's fault
    with pytest.raises(ModelError, match=r"bracket \[0, 100\]: at V = 0 the model cannot be"):
        critical_speed(wheelset, bracket=(0.0, 100.0))
    # below the critical speed (55.6 m/s) the largest real part stays negative: the message
    # gives it at each end of the bracket, in that order
    with pytest.raises(ModelError) as caught:
        critical_speed(wheelset, bracket=(10.0, 50.0))
    message = str(caught.value)
    at_lo, at_hi = (float(x) for x in re.findall(r"(-?[\d.e+-]+) 1/s at ", message))
    rate = lambda v: max(np.linalg.eigvals(wheelset.system(parameters={"V": v}).A).real)  # noqa: E731
    assert at_lo == pytest.approx(rate(10.0), rel=1e-3)
    assert at_hi == pytest.approx(rate(50.0), rel=1e-3)


def test_a_bracket_that_regains_stability_says_so_in_the_models_time_unit(tmp_path):
    """Damping (mu - 1)(mu - 3) is negative between 1 and 3: from 2 to 5 the linear part is
    unstable at first and stable from 3 on; a dimensionless time gives rates per unit time."""
    path = tmp_path / "band.toml"
    text = textwrap.dedent(NEGATIVE_DAMPING).replace('"c - mu"', '"(mu - 1)*(mu - 3)"')
    path.write_text(text.replace('kind = "second_order"', 'kind = "second_order"\ntime_unit = "1"'))
    model = load_model(path)
    with pytest.raises(ModelError) as caught:
        critical_speed(model, parameter="mu", bracket=(2.0, 5.0))
    message = str(caught.value)
    assert "unstable at the bracket's low end and stable from about mu = 3." in message
    assert "per unit time" in message and "1/s" not in message
