"""Models that crashed ``generate`` (issue 21) end in a clean run or a named error."""

import math
import textwrap

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.mechanics import ModelError, load_model
from circuitsim.synthesis import synthesize
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.eseries import floor_to_series, round_to_series
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.scaling import MAX_SCALING_STEPS, choose_scaling


def model(tmp_path, body: str):
    path = tmp_path / "m.toml"
    path.write_text(
        '[model]\nname = "m"\nkind = "first_order"\n[states]\nnames = ["x"]\n'
        + textwrap.dedent(body)
    )
    return load_model(path)


def test_a_coefficient_of_1e_320_is_refused_by_name(tmp_path):
    system = model(tmp_path, "[matrices]\nA = [[-1e-320]]\n").system()
    with pytest.raises(SynthesisError, match=r"A\[x, x\]\): the coefficient -1e-320 becomes"):
        synthesize(system)


def test_a_tiny_coefficient_still_in_the_float_range_is_refused_by_name(tmp_path):
    # 1e-290 1/s: a 1e295 ohm resistor, which no part builds: refused naming it (synthesis/
    # bounds.py), not a crash; unity scaling (the paper's mapping, taken as asked) builds it
    system = model(tmp_path, "[matrices]\nA = [[-1e-290]]\n[initial]\nx = 1\n").system()
    with pytest.raises(SynthesisError, match=r"R11 would be 1e\+295 ohm \(x -> x integrator"):
        synthesize(system)
    result = synthesize(system, SynthesisOptions(scaling="unity"))
    resistors = [e for e in result.bom if e.unit == "ohm" and "A[x, x]" in e.role]
    assert resistors and math.isclose(resistors[0].value, 1e295, rel_tol=0.02)
    assert any("is outside" in w for w in result.warnings)


def test_an_abs_term_of_gain_0_adds_nothing(tmp_path):
    body = """
    [matrices]
    A = [[-1]]
    [nonlinear.n]
    enters = { x = 1 }
    abs = [ { gain = 0, row = { x = 1 }, offset = 0.1 } ]
    [initial]
    x = 1
    """
    out = tmp_path / "zero.cir"
    assert main(["generate", "--model", str(model(tmp_path, body).file), "-o", str(out)]) == 0
    assert "ABS" not in out.read_text().upper().replace("ABSTOL", "")


def test_a_forcing_of_1e300_hz_with_amplitude_0_does_not_count(tmp_path):
    body = """
    [matrices]
    A = [[-1]]
    [forcing.f]
    amplitude = 0
    frequency = 1e300
    enters = { x = 1 }
    [initial]
    x = 1
    """
    scaling = choose_scaling(model(tmp_path, body).system(), SynthesisOptions(), 5.0)
    assert scaling.peaks[0] == pytest.approx(1.0)


def test_a_forcing_too_fast_for_the_scaling_solve_is_refused_at_once(tmp_path):
    body = """
    [matrices]
    A = [[-1]]
    [forcing.f]
    amplitude = 1
    frequency = 1e300
    enters = { x = 1 }
    """
    with pytest.raises(SynthesisError, match=f"at most {MAX_SCALING_STEPS:,}") as caught:
        choose_scaling(model(tmp_path, body).system(), SynthesisOptions(), 5.0)
    assert "the forcing f at 1e+300 Hz" in str(caught.value) and "--range" in str(caught.value)


def test_a_state_that_blows_up_in_the_scaling_solve_is_named(tmp_path):
    system = model(tmp_path, "[matrices]\nA = [[300]]\n[initial]\nx = 1\n").system()
    with pytest.raises(SynthesisError, match="sets the scales overflows at t = "):
        with np.errstate(all="ignore"):
            choose_scaling(system, SynthesisOptions(), 5.0)
    # a trajectory that overflowed without failing gives an infinite peak: named, not a crash
    t = np.array([0.0, 1.0])
    with pytest.raises(SynthesisError, match="state x grows without bound"):
        choose_scaling(system, SynthesisOptions(), 1.0, trajectory=(t, np.array([[1.0, np.inf]])))


def test_a_denormal_peak_counts_as_zero(tmp_path):
    system = model(tmp_path, "[matrices]\nA = [[-1]]\n[initial]\nx = 1e-320\n").system()
    scaling = choose_scaling(system, SynthesisOptions(), 1.0)
    assert scaling.volts_per_unit[0] == 1.0
    assert "stays at zero" in scaling.warnings[0]


def test_a_product_that_overflows_is_a_model_error_not_a_linalg_error(tmp_path):
    path = tmp_path / "inf.toml"
    path.write_text(
        '[model]\nname = "t"\nkind = "second_order"\n[coordinates]\nnames = ["x"]\n'
        "[matrices]\nM = [[1e-300]]\nK = [[1e300]]\n"
    )
    with pytest.raises(ModelError, match="the state matrix is not finite") as caught:
        load_model(path)
    assert caught.value.key == "matrices"


@pytest.mark.parametrize("value", [1e308, 1.7e308, 1e-320, 5e-310])
def test_e_series_rounding_at_the_ends_of_the_float_range(value):
    for rounded in (round_to_series(value, "E96"), floor_to_series(value, "E24")):
        assert math.isfinite(rounded) and rounded > 0
        assert abs(math.log10(rounded / value)) < 0.1


@pytest.mark.parametrize("value", [0.0, -1.0, math.inf, math.nan])
def test_e_series_refuses_what_has_no_standard_value(value):
    with pytest.raises(SynthesisError):
        floor_to_series(value)
    with pytest.raises(SynthesisError):
        round_to_series(value, "E96")


def test_rounding_up_past_the_largest_float_is_refused():
    with pytest.raises(SynthesisError, match="beyond the float range"):
        round_to_series(1.79e308, "E24")  # rounds to 1.8e308, past the largest float


def test_a_200_state_chain_with_extreme_scales_generates_or_refuses_cleanly(tmp_path):
    n = 200
    rows = []
    for i in range(n):
        row = ["0"] * n
        row[i] = "-1"
        row[(i + 1) % n] = "1e150" if i % 2 else "1e-150"
        rows.append("[" + ", ".join(row) + "]")
    names = ", ".join(f'"x{i}"' for i in range(n))
    path = tmp_path / "chain.toml"
    path.write_text(
        f'[model]\nname = "chain"\nkind = "first_order"\n[states]\nnames = [{names}]\n'
        f"[matrices]\nA = [{', '.join(rows)}]\n[initial]\nx0 = 1\n"
    )
    code = main(["generate", "--model", str(path), "-o", str(tmp_path / "c.cir")])
    assert code in (0, 1, 2)
    assert np.isfinite(load_model(path).system().A).all()


def test_a_forcing_whose_amplitude_times_direction_overflows_is_a_model_error(tmp_path):
    # found by gen_models (seed 4): enters = { x = 1e308 } with F0 = 4 made scipy step with a
    # NaN step size for ever
    body = """
    [matrices]
    A = [[-1]]
    [forcing.drive]
    amplitude = 4
    frequency = 1
    enters = { x = 1e308 }
    """
    with pytest.raises(ModelError, match="direction times amplitude is not finite") as caught:
        model(tmp_path, body)
    assert caught.value.key == "forcing.drive"
