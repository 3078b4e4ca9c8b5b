"""The speed knob: R33 and R44 as a fixed standard resistor plus a potentiometer.

The references are analytic: the paper's c_y = 7.24e6 / V and c_psi = 4.36e6 / V over m and I
give the integrator gain each dial setting must realize, 1 / (R C K) = |A(V)| (a diagonal entry:
the state's volts-per-unit cancels), read with the capacitor and time scale of the written files.
"""

import csv
import functools
import math

import pytest

from circuitsim.mechanics import load_model
from circuitsim.netlist.circuit import Capacitor
from circuitsim.netlist.reader import read_netlist
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.knob import POT_SERIES, KnobRequest, knob_entries
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.scalemap import ScaleMap

# the paper's equation (5): A[y_dot, y_dot] = -7.24e6 / (1500 V), A[psi_dot, psi_dot] likewise
PAPER = {"R33": ("y_dot", 7.24e6 / 1500), "R44": ("psi_dot", 4.36e6 / 1200)}


def _request(model, low=40.0, high=70.0, coefficients=None, **kw):
    @functools.cache
    def linear_part(v):
        return model.system(coefficients, parameters={"V": v}).A

    return KnobRequest("V", low, high, linear_part, "m/s", **kw)


@pytest.fixture(scope="module")
def wheelset_knob(tmp_path_factory):
    model = load_model()
    out = tmp_path_factory.mktemp("knob") / "w.cir"
    return generate(model.system(), out, SynthesisOptions(series="E96"), knob=_request(model))


def test_each_dial_setting_realizes_the_paper_coefficient_exactly(wheelset_knob):
    result = wheelset_knob
    circuit = read_netlist(result.netlist)
    scale = ScaleMap.load(result.scale_file)
    assert [k.resistor for k in result.knobs] == ["R33", "R44"]
    for knob in result.knobs:
        state, numerator = PAPER[knob.resistor]
        (cap,) = [e for e in circuit.elements
                  if isinstance(e, Capacitor) and e.positive == f"{state}_neg"]  # fmt: skip
        c = float(cap.capacitance)
        for s in knob.settings:
            assert knob.fixed + s.fraction * knob.pot == pytest.approx(s.resistance, rel=1e-14)
            gain = 1.0 / (s.resistance * c * scale.time_scale)
            assert gain == pytest.approx(numerator / s.value, rel=1e-12)
        # the netlist holds the simulated speed's setting: fixed + pot = R(55)
        fixed = float(circuit.element(knob.fixed_part).resistance)
        setting = float(circuit.element(knob.pot_part).resistance)
        assert fixed == knob.fixed
        assert 1.0 / ((fixed + setting) * c) == pytest.approx(numerator / 55.0, rel=1e-11)
    assert not any(e.name.upper() in ("R33", "R44") for e in circuit.elements)
    report = result.report
    assert report.ok
    for entry in report.entries:
        if "y_dot, y_dot" in entry.what or "psi_dot, psi_dot" in entry.what:
            assert abs(entry.error) < 1e-9, entry


def test_range_ends_inside_the_rotation_and_parts_standard(wheelset_knob):
    for knob in wheelset_knob.knobs:
        first, last = knob.settings[0], knob.settings[-1]
        assert (first.value, last.value) == (40.0, 70.0)
        # R grows with V (R proportional to V): the ends are the rotation's margins
        assert 0.0 < first.fraction < last.fraction < 1.0
        fractions = [s.fraction for s in knob.settings]
        assert fractions == sorted(fractions)
        # the rheostat is linear in R, R is proportional to V: the dial is linear in V
        slope = (last.fraction - first.fraction) / 30.0
        for s in knob.settings:
            assert s.fraction == pytest.approx(first.fraction + slope * (s.value - 40), abs=1e-12)
        # the smallest E6 potentiometer spanning the range
        span = last.resistance - first.resistance
        decade = 10 ** math.floor(math.log10(knob.pot))
        assert knob.pot >= span
        smaller = [m * decade for m in (*POT_SERIES["E6"], 10) if m * decade < knob.pot]
        smaller += [m * decade / 10 for m in POT_SERIES["E6"]]
        assert all(v < span for v in smaller)
        mantissa = knob.fixed / 10 ** math.floor(math.log10(knob.fixed))
        from circuitsim.synthesis.eseries import E96

        assert any(abs(mantissa / m - 1) < 1e-9 for m in E96)


def test_knob_files(wheelset_knob):
    with open(wheelset_knob.knob_file) as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["resistor", "potentiometer (ohm)", "fixed (ohm)", "V (m/s)",
                       "resistance (ohm)", "fraction"]  # fmt: skip
    r33 = [r for r in rows[1:] if r[0] == "R33"]
    assert [float(r[3]) for r in r33][:3] == [40.0, 42.0, 44.0] and float(r33[-1][3]) == 70.0
    for r in r33:
        assert float(r[2]) + float(r[5]) * float(r[1]) == pytest.approx(float(r[4]), rel=1e-14)
    with open(wheelset_knob.bom_file) as handle:
        bom = {row["part"]: row for row in csv.DictReader(handle)}
    assert bom["R33P"]["kind"] == "potentiometer" and bom["R33P"]["series"] == "E6"
    assert bom["R33A"]["kind"] == "resistor"
    with open(wheelset_knob.order_file) as handle:
        order = [r for r in csv.DictReader(handle) if "potentiometer" in r["description"]]
    assert sorted(r["designators"] for r in order) == ["R33P", "R44P"]


def test_entries_come_from_the_model():
    """Which resistors follow V is read from the model: the same two in the affine 'eq2' set
    (c_y = 2 Cy + 2 f22 / V), none when the parameter moves no entry of A."""
    model = load_model()
    system = model.system("eq2")
    assert knob_entries(system, _request(model, coefficients="eq2")) == [(2, 2), (3, 3)]

    def frequency(v):
        return model.system(parameters={"f": v}).A

    assert knob_entries(model.system(), KnobRequest("f", 1.0, 10.0, frequency)) == []


def test_bad_ranges_are_refused(tmp_path):
    model = load_model()
    with pytest.raises(SynthesisError, match=r"V = 55 m/s is outside the knob's range 60:70"):
        generate(model.system(), tmp_path / "a.cir", knob=_request(model, 60.0, 70.0))
    assert not list(tmp_path.iterdir())

    def flips(v):
        A = model.system(parameters={"V": 55.0}).A.copy()
        A[2, 2] *= v - 50.0
        return A

    with pytest.raises(SynthesisError, match=r"A\[y_dot, y_dot\] changes sign"):
        knob_entries(model.system(), KnobRequest("V", 40.0, 70.0, flips))


def test_generate_cli_knob(tmp_path, capsys):
    from circuitsim.cli import main

    out = tmp_path / "w.cir"
    assert main(["generate", "--speed-range", "45:65", "--pot-series", "E3", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "knob R33 = R33A" in text and "V 45..65 m/s" in text
    assert (tmp_path / "w.knob.csv").exists()
    assert main(["generate", "--knob", "V", "-o", str(out)]) == 2
    assert "--knob needs --speed-range" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:  # argparse refuses the option value
        main(["generate", "--speed-range", "70:40", "-o", str(out)])
    assert exit_info.value.code == 2
    assert "expected LO:HI" in capsys.readouterr().err


def test_the_bogies_speed_knob_follows_its_derived_parameters(tmp_path):
    """The bogie's speed enters only through c_y = 2 f22 / V and c_psi = 2 f11 b^2 / V
    (derived parameters): the knob turns the four damping resistors of the wheelsets, each
    dial realizing the typed coefficient over the mass, proportional to V."""
    model = load_model("bogie")

    @functools.cache
    def linear_part(v):
        return model.system(parameters={"V": v}).A

    request = KnobRequest("V", 20.0, 60.0, linear_part, "m/s")
    result = generate(model.system(), tmp_path / "b.cir", knob=request)
    assert sorted(k.entry for k in result.knobs) == sorted(
        (f"{q}_dot", f"{q}_dot") for q in ("y1", "psi1", "y2", "psi2")
    )
    per_speed = {"y": 2 * 3.62e6 / 1500.0, "p": 2 * 3.98e6 * 0.74**2 / 1200.0}  # |A| V
    for knob in result.knobs:
        for s in knob.settings:
            assert knob.scale / s.resistance == pytest.approx(
                per_speed[knob.entry[0][0]] / s.value, rel=1e-12
            )


def test_a_knob_that_moves_no_resistor_is_refused(tmp_path, capsys):
    from circuitsim.cli import main

    out = tmp_path / "w.cir"
    code = main(["generate", "--speed-range", "1:10", "--knob", "f", "-o", str(out)])
    assert code == 2
    assert "no resistor follows f: no entry of the linear part changes" in capsys.readouterr().err
    assert not out.exists()
