"""The mapping proof: netlists read back from disk realize the model, and tampering is caught."""

import math
import re

import numpy as np
import pytest

from circuitsim.mechanics import load_model
from circuitsim.netlist.reader import read_netlist
from circuitsim.synthesis.check import check_mapping
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.options import SynthesisOptions

MODEL_CRITICAL_SPEED = 55.6455  # reference, paper set


def wheelset(V=55.0, flange=True):
    return load_model().system(parameters={"V": V, "f": 3.0}, nonlinear={"flange": flange})


@pytest.mark.parametrize(
    ("options", "dialect"),
    [
        (SynthesisOptions(series="exact"), "ngspice"),
        (SynthesisOptions(series="E96", opamp="tl074"), "multisim"),
        (SynthesisOptions(series="E24", scaling="unity"), "ltspice"),
        (SynthesisOptions(series="E96", nonlinear="deadzone", opamp="tl074"), "ngspice"),
        (SynthesisOptions(series="exact", nonlinear="deadzone", scaling="unity"), "multisim"),
        (SynthesisOptions(series="E96", time_scale=100.0), "ngspice"),
    ],
)
def test_generated_wheelset_passes(tmp_path, options, dialect):
    system = wheelset()
    result = generate(system, tmp_path / "w.cir", options, dialect)
    report = result.report
    assert report.ok, report.summary()
    # 8 A entries, the forcing's gain and frequency, the flange's linear part, and gain and
    # offset of its two kinks
    assert len(report.entries) == 15
    if options.series == "exact":
        assert report.max_error < 1e-9
        assert report.critical_speed_realized == pytest.approx(MODEL_CRITICAL_SPEED, abs=1e-3)
    assert report.critical_speed_model == pytest.approx(MODEL_CRITICAL_SPEED, abs=1e-3)


def test_rounded_values_need_the_bom(tmp_path):
    system = wheelset()
    result = generate(system, tmp_path / "w.cir", SynthesisOptions(series="E96"))
    assert result.report.ok
    bare = check_mapping(result.netlist, result.scale_file, system)  # no BOM: exact expected
    assert not bare.ok
    assert any("R31" in p for p in bare.problems)


def _rewrite(path, pattern, replacement):
    text = path.read_text()
    new, count = re.subn(pattern, replacement, text, count=1, flags=re.MULTILINE)
    assert count == 1
    path.write_text(new)


def test_a_changed_resistor_is_caught(tmp_path):
    system = wheelset()
    result = generate(system, tmp_path / "w.cir", SynthesisOptions(series="exact"))
    value = float(read_netlist(result.netlist).element("R31").resistance)
    _rewrite(result.netlist, r"^R31 (\S+) (\S+) \S+$", rf"R31 \1 \2 {value * 1.02!r}")
    report = check_mapping(result.netlist, result.scale_file, system, bom=result.bom_file)
    assert not report.ok
    (problem,) = report.problems
    assert "A[y_dot, y]" in problem and "R31" in problem


def test_a_wrong_sign_is_caught(tmp_path):
    system = wheelset()
    result = generate(system, tmp_path / "w.cir", SynthesisOptions(series="exact"))
    _rewrite(result.netlist, r"^R32 psi ", "R32 psi_neg ")
    report = check_mapping(result.netlist, result.scale_file, system, bom=result.bom_file)
    assert any("A[y_dot, psi]" in p for p in report.problems)


def test_an_open_switch_is_caught(tmp_path):
    system = wheelset()
    result = generate(system, tmp_path / "w.cir", SynthesisOptions(series="exact"))
    _rewrite(result.netlist, r"^VFLANGE_CTL flange_ctl 0 DC 1$", "VFLANGE_CTL flange_ctl 0 DC 0")
    report = check_mapping(result.netlist, result.scale_file, system, bom=result.bom_file)
    assert any("S1 closing time" in p for p in report.problems)


def test_switch_closing_time_is_realized(tmp_path):
    from circuitsim.synthesis.generate import switch_at

    system = switch_at(wheelset(), 1.5)
    result = generate(system, tmp_path / "w.cir", SynthesisOptions(time_scale=10.0))
    assert result.report.ok, result.report.summary()
    closing = [e for e in result.report.entries if "closing time" in e.what]
    assert closing and closing[0].realized == pytest.approx(1.5, rel=1e-3)


def test_rounding_across_the_critical_speed_is_warned(tmp_path):
    # V = 55.5 m/s is 0.15 m/s below the model's critical speed; E96 values in unity scaling
    # move the circuit's own critical speed below 55.5 (its linear part is then unstable) when
    # each coefficient is one rounded value (no series pairs)
    system = wheelset(V=55.5, flange=False)
    options = SynthesisOptions(scaling="unity", pair_tolerance=math.inf)
    result = generate(system, tmp_path / "w.cir", options)
    report = result.report
    assert report.ok
    assert report.critical_speed_realized < 55.5 < report.critical_speed_model
    assert any("critical speed" in w for w in report.warnings)
    # independent recomputation from the file's values (unity: 1/(R C) = |A entry|)
    c = read_netlist(result.netlist)

    def g(r, cap):
        return 1.0 / (float(c.element(r).resistance) * float(c.element(cap).capacitance))

    def rate(speed):
        A = np.array(
            [
                [0, 0, g("R1", "C1"), 0],
                [0, 0, 0, g("R2", "C2")],
                [-g("R31", "C3"), g("R32", "C3"), -g("R33", "C3") * 55.5 / speed, 0],
                [-g("R41", "C4"), -g("R42", "C4"), 0, -g("R44", "C4") * 55.5 / speed],
            ]
        )
        return np.max(np.linalg.eigvals(A).real)

    speeds = np.linspace(50, 60, 20001)
    rates = np.array([rate(v) for v in speeds[::100]])
    first = np.argmax(rates >= 0) * 100
    fine = speeds[max(first - 100, 0) : first + 1]
    crossing = fine[np.argmax(np.array([rate(v) for v in fine]) >= 0)]
    assert report.critical_speed_realized == pytest.approx(crossing, abs=1e-3)


def test_other_models_pass(tmp_path):
    folder = "tests/synthesis/models"
    for name in ("gap_oscillator", "two_mass_stop", "chua_diode"):
        system = load_model(f"{folder}/{name}.toml").system()
        for series in ("exact", "E24"):
            result = generate(system, tmp_path / f"{name}.cir", SynthesisOptions(series=series))
            assert result.report.ok, (name, series, result.report.summary())
            assert result.report.critical_speed_model is None  # no speed parameter named


@pytest.mark.parametrize("series", ["E96", "E24"])
def test_critical_speed_warning_names_the_series_and_both_spellings(tmp_path, series):
    system = load_model().system(parameters={"V": 55.5, "f": 3.0}, nonlinear={"flange": False})
    # one rounded value per coefficient: series pairs would keep the critical speed above 55.5
    options = SynthesisOptions(scaling="unity", series=series, pair_tolerance=math.inf)
    result = generate(system, tmp_path / "w.cir", options)
    (warning,) = [w for w in result.report.warnings if "critical speed" in w]
    # independent: at 55.5 the model's linear part decays and the rounded circuit's grows
    assert np.max(np.linalg.eigvals(result.report.A_model).real) < 0
    assert np.max(np.linalg.eigvals(result.report.A_realized).real) > 0
    assert f"the model is stable but the circuit with {series} resistors is not" in warning
    assert "--series exact" in warning and "series='exact'" in warning
    assert ("--series E96" in warning) == (series != "E96")  # no advice to use what is in use
    exact = generate(system, tmp_path / "x.cir", SynthesisOptions(scaling="unity", series="exact"))
    assert not any("critical speed" in w for w in exact.report.warnings)
