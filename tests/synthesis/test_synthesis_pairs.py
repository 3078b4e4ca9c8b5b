"""Series pairs of standard resistors: coefficients within 0.1 % with E96 parts.

The coefficient errors come from the mapping check reading the written netlist back (it knows
nothing of the generator), plus, in unity scaling, a hand recomputation 1/((RA + RB) C) = |A|
from the file's values; one E96 scenario is simulated and compared with the ODE.
"""

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from circuitsim.compare.case import run_case
from circuitsim.mechanics import load_model
from circuitsim.netlist.circuit import Resistor
from circuitsim.netlist.reader import read_netlist
from circuitsim.synthesis.check import check_mapping
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.eseries import E24, E96, series_pair
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.options import SynthesisOptions

MODELS = Path(__file__).parent / "models"


def _member(ohms: float, series: tuple[float, ...]) -> bool:
    mantissa = ohms / 10.0 ** math.floor(math.log10(ohms))
    return any(abs(mantissa / m - 1) < 1e-9 for m in (*series, 10.0))


@pytest.mark.parametrize(("name", "series", "bound"), [("E96", E96, 1e-3), ("E24", E24, 6e-3)])
def test_series_pair_error_and_members(name, series, bound):
    # E96: within the 0.1 % tolerance everywhere; E24 pairs reach 0.58 % at worst (20000 values)
    rng = np.random.default_rng(7)
    worst = 0.0
    for value in 10 ** rng.uniform(2, 7, 20000):
        pair = series_pair(value, name, 1e-3)
        assert all(_member(p, series) for p in pair) and len(pair) in (1, 2)
        worst = max(worst, abs(sum(pair) / value - 1))
    assert worst <= bound
    assert series_pair(30100.0, "E96", 1e-3) == (30100.0,)  # a member stays one part
    assert series_pair(30400.0, "E96", math.inf) == (30100.0,)  # inf: never a pair
    assert series_pair(30400.0, "E96", 1e-3, smallest=1e6) == (30100.0,)  # no part that small


def test_pair_tolerance_is_validated():
    for bad in (-1e-3, math.nan, "0.1"):
        with pytest.raises(SynthesisError, match="pair_tolerance"):
            SynthesisOptions(pair_tolerance=bad).validated()


def _check_file(result, system):
    report = check_mapping(result.netlist, result.scale_file, system, bom=result.bom_file)
    assert report.ok, report.problems
    errors = [abs(e.error) for e in report.entries if e.model != 0]
    assert errors and max(errors) <= 1e-3, [(e.what, e.error) for e in report.entries]
    return report


WHEELSET_OPTIONS = [
    SynthesisOptions(series="E96", opamp="tl074"),
    SynthesisOptions(series="E96", nonlinear="deadzone"),
    SynthesisOptions(series="E96", scaling="unity"),
    SynthesisOptions(series="E96", time_scale=100.0),
]


@pytest.mark.parametrize("options", WHEELSET_OPTIONS)
@pytest.mark.parametrize("flange", [False, True])
def test_wheelset_e96_coefficients_within_a_tenth_percent(tmp_path, options, flange):
    system = load_model().system(parameters={"V": 55.0, "f": 3.0}, nonlinear={"flange": flange})
    result = generate(system, tmp_path / "w.cir", options)
    report = _check_file(result, system)
    assert any(isinstance(e, Resistor) and e.name.upper().endswith("A")
               and e.name.upper()[:-1] + "B" in {x.name.upper() for x in
                                                  read_netlist(result.netlist).elements}
               for e in read_netlist(result.netlist).elements)  # fmt: skip
    # the realized critical speed (one E96 value each: 55.54-56.45 m/s; model 55.6455)
    assert abs(report.critical_speed_realized - 55.6455) < 0.02


def test_wheelset_unity_pairs_recomputed_by_hand(tmp_path):
    """Unity scaling: 1/(R C) = |A entry|, with R the sum of a pair's parts in the file."""
    system = load_model().system(parameters={"V": 55.0, "f": 3.0}, nonlinear={"flange": False})
    result = generate(system, tmp_path / "w.cir", SynthesisOptions(scaling="unity"))
    c = read_netlist(result.netlist)
    names = {e.name.upper() for e in c.elements}

    def ohms(r):
        if r in names:
            return float(c.element(r).resistance)
        return float(c.element(r + "A").resistance) + float(c.element(r + "B").resistance)

    pairs = 0
    A = np.asarray(system.A)
    for i, j, r in [(0, 2, "R1"), (1, 3, "R2"), (2, 0, "R31"), (2, 1, "R32"), (2, 2, "R33"),
                    (3, 0, "R41"), (3, 1, "R42"), (3, 3, "R44")]:  # fmt: skip
        pairs += r not in names
        realized = 1.0 / (ohms(r) * float(c.element(f"C{i + 1}").capacitance))
        assert realized == pytest.approx(abs(A[i, j]), rel=1e-3), r
    assert pairs >= 4  # most of them need a pair (one E96 value is up to 1.3 % off)


@pytest.mark.parametrize("name", sorted(p.stem for p in MODELS.glob("*.toml")))
def test_other_models_e96_coefficients_within_a_tenth_percent(tmp_path, name):
    system = load_model(MODELS / f"{name}.toml").system()
    result = generate(system, tmp_path / "m.cir", SynthesisOptions(series="E96"))
    _check_file(result, system)


@pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)
def test_e96_wheelset_scenario_passes_the_exact_thresholds(tmp_path):
    """f = 3 Hz, flange on, E96 with pairs, simulated by ngspice: passes the thresholds the
    exact-valued circuit is held to (the default ones of the op-amp kind)."""
    system = load_model().system(parameters={"V": 55.0, "f": 3.0}, nonlinear={"flange": True})
    case = run_case(system, SynthesisOptions(series="E96", t_stop=5.0), engine="ngspice",
                    netlist=tmp_path / "w.cir")  # fmt: skip
    assert case.report.ok
    assert case.comparison.passed, case.comparison


def test_parallel_pairs_reach_what_series_pairs_miss():
    """E24: a series pair is up to 0.58 % off (20000 values); the better of a series and a
    parallel pair up to 0.3 %; E96 needs no parallel pair (series within 0.1 %)."""
    from circuitsim.synthesis.eseries import parallel_pair, parallel_value

    rng = np.random.default_rng(7)
    worst_series = worst_best = 0.0
    for value in 10 ** rng.uniform(2, 7, 20000):
        pair = parallel_pair(value, "E24")
        assert all(_member(p, E24) for p in pair) and value < max(pair)
        series = abs(sum(series_pair(value, "E24", 1e-3)) / value - 1)
        worst_series = max(worst_series, series)
        worst_best = max(worst_best, min(series, abs(parallel_value(pair) / value - 1)))
    assert 4e-3 < worst_series <= 6e-3 and worst_best <= 3e-3
    assert parallel_pair(1000.0, "exact") is None


def test_wheelset_e24_with_parallel_pairs_by_hand(tmp_path):
    """E24 wheelset (auto scaling): parallel pairs (both parts between the same nodes) where
    a series pair misses 0.1 %; every A entry, recomputed by hand from the file's values and
    scales (|A_ij| = G_j / (K G_i R C_i)), is what the mapping check reads, and within 0.2 %
    (two E24 parts cannot always reach 0.1 %: R32 = 56k || 240k is 0.16 % off, the best pair)."""
    from circuitsim.synthesis.scalemap import ScaleMap

    system = load_model().system(parameters={"V": 55.0, "f": 3.0}, nonlinear={"flange": False})
    result = generate(system, tmp_path / "w.cir", SynthesisOptions(series="E24"))
    scale = ScaleMap.load(result.scale_file)
    G = [scale.states[s].volts_per_unit for s in system.states]
    c = read_netlist(result.netlist)
    names = {e.name.upper() for e in c.elements}
    kinds = set()

    def ohms(r):
        if r in names:
            return float(c.element(r).resistance)
        a, b = c.element(r + "A"), c.element(r + "B")
        ra, rb = float(a.resistance), float(b.resistance)
        if a.nodes == b.nodes:
            kinds.add("parallel")
            return ra * rb / (ra + rb)
        kinds.add("series")
        return ra + rb

    A = np.asarray(system.A)
    for i, j, r in [(0, 2, "R1"), (1, 3, "R2"), (2, 0, "R31"), (2, 1, "R32"), (2, 2, "R33"),
                    (3, 0, "R41"), (3, 1, "R42"), (3, 3, "R44")]:  # fmt: skip
        capacitance = float(c.element(f"C{i + 1}").capacitance)
        realized = G[j] / (scale.time_scale * G[i] * ohms(r) * capacitance)
        assert realized == pytest.approx(abs(A[i, j]), rel=2e-3), r
        (entry,) = [e for e in result.report.entries
                    if e.what == f"A[{system.states[i]}, {system.states[j]}]"]  # fmt: skip
        assert abs(entry.realized) == pytest.approx(realized, rel=1e-9)
    assert kinds == {"series", "parallel"}
    assert result.report.ok



def test_quarter_car_e96_every_coefficient_within_a_tenth_percent(tmp_path):
    """quarter_car (two nonlinear terms whose constants, -404 and +1000, partly cancel into
    zu_dot): the summers of its |x| blocks and its switched resistors take series pairs at a
    quarter of the pair tolerance, so every coefficient the mapping check reads back from the
    file is within 0.1 % (one E96 part each on that path: 0.135 % on the zu_dot constant)."""
    system = load_model("quarter_car").system()
    result = generate(system, tmp_path / "q.cir", SynthesisOptions(series="E96"))
    c = read_netlist(result.netlist)
    names = {e.name.upper() for e in c.elements}
    assert any(n.startswith("RPROGRESSION_SUM_") and n.endswith("A") for n in names)
    _check_file(result, system)


def test_summer_series_pair_is_read_back_as_its_sum():
    """A summer input made of a series pair through its _mid node: the readback gives the
    weight Rf / (RA + RB), computed here by hand from the two parts."""
    from circuitsim.netlist.circuit import Circuit
    from circuitsim.synthesis.blocks import Builder
    from circuitsim.synthesis.readback import Affine, CircuitReader

    builder = Builder(Circuit("pair"), "E96", "ideal", pair_tolerance=1e-3)
    weight = 10_000.0 / 30_400.0  # 30.4 kOhm: E96's 30.1k is 1 % off, so a pair
    builder.summer("S", "S", "out", [("X", "x", weight, weight, "test")], 10_000.0,
                   builder.chain_tolerance)  # fmt: skip
    ra = float(builder.circuit.element("RS_XA").resistance)
    rb = float(builder.circuit.element("RS_XB").resistance)
    assert builder.circuit.element("RS_XA").nodes[1].lower() == "rs_x_mid"
    assert abs((ra + rb) / 30_400.0 - 1) <= builder.chain_tolerance
    reader = CircuitReader(builder.circuit, 1)
    reader.state_expr["x"] = Affine(np.ones(1))
    signal = reader.signal("out")
    assert signal.vec[0] == pytest.approx(-10_000.0 / (ra + rb), rel=1e-12)
    assert {"RS_XA", "RS_XB"} <= {p.upper() for p in signal.parts}
