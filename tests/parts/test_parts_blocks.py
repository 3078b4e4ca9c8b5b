"""Precision |x| and dead-zone blocks: names, errors, and transfer curves on ngspice.

References are the mathematical functions themselves (|x|, the dead zone, the flange force
identity k y - (k/2)(|y + eta| - |y - eta|) = k deadzone(y)); a slow ramp over +/-10 V must
follow them within 1 % of full scale (0.1 V).
"""

import numpy as np
import partbench
import pytest

from circuitsim.interop.ngspice import run_ngspice
from circuitsim.netlist.circuit import Circuit, Diode, Resistor, SubcircuitCall, VoltageSource
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.nonlinear import add_dead_zone, add_precision_abs
from circuitsim.synthesis.opamps import OPAMP_KINDS, add_opamp

R = partbench.BLOCK_R


def test_abs_names_follow_the_prefix():
    circuit = Circuit("t")
    used = add_precision_abs(circuit, "ABS1", "y", "f", R, "ideal", offset_volts=0.5)
    assert used == ["XABS1A", "XABS1B"]
    names = [e.name for e in circuit.elements]
    assert names == [
        "RABS1_1", "RABS1_2", "DABS1_1", "DABS1_2", "XABS1A",
        "RABS1_3", "RABS1_4", "RABS1_5", "VABS1_B", "RABS1_6", "RABS1_7", "XABS1B",
    ]  # fmt: skip
    values = {e.name: e.resistance for e in circuit.elements if isinstance(e, Resistor)}
    assert values["RABS1_4"] == R / 2 and values["RABS1_1"] == R
    assert circuit.element("VABS1_B").dc == 0.5
    assert all(e.model.lower() == "d1n4148" for e in circuit.elements if isinstance(e, Diode))


def test_dead_zone_names_and_supply_bias():
    circuit = Circuit("t")
    used = add_dead_zone(circuit, "DZ", "y", "f", 0.5, R, "tl074", bias="supplies")
    assert used == ["XDZA", "XDZB", "XDZC"]
    assert all(circuit.element(n).connections[2:4] == ("vcc", "vee") for n in used)
    assert circuit.element("RDZ_2").positive == "vee"
    assert circuit.element("RDZ_2").resistance == pytest.approx(R * 15 / 0.5)
    assert circuit.element("RDZ_5").positive == "vcc"
    sources = [e.name for e in circuit.elements if isinstance(e, VoltageSource)]
    assert sources == ["VCC", "VEE"]


def test_blocks_leave_names_of_other_sections_alone():
    circuit = Circuit("t")
    add_opamp(circuit, "XU1A", "0", "s", "y1", "tl074")
    add_precision_abs(circuit, "ABS1", "y1", "f1", R, "tl074")
    add_precision_abs(circuit, "ABS2", "y1", "f2", R, "tl074", sign=-1)
    calls = [e.name for e in circuit.elements if isinstance(e, SubcircuitCall)]
    assert calls == ["XU1A", "XABS1A", "XABS1B", "XABS2A", "XABS2B"]
    assert sum(isinstance(e, VoltageSource) for e in circuit.elements) == 2  # VCC, VEE once


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda c: add_precision_abs(c, "A B", "y", "f", R, "ideal"), "prefix"),
        (lambda c: add_precision_abs(c, "A", "y", "f", -1.0, "ideal"), "resistance"),
        (lambda c: add_precision_abs(c, "A", "y", "f", R, "ideal", sign=2), "sign"),
        (lambda c: add_precision_abs(c, "A", "y", "f", R, "opa"), "kind"),
        (lambda c: add_dead_zone(c, "D", "y", "f", 0.0, R, "ideal"), "half-width"),
        (lambda c: add_dead_zone(c, "D", "y", "f", 1.0, R, "ideal", bias="supplies"), "tl074"),
        (lambda c: add_dead_zone(c, "D", "y", "f", 1.0, R, "ideal", bias="zener"), "bias"),
    ],
)
def test_bad_block_requests(call, match):
    with pytest.raises(SynthesisError, match=match):
        call(Circuit("t"))


ENGINES = [
    pytest.param("ngspice", marks=partbench.requires_ngspice),
    pytest.param("builtin"),
]
RUN = {"ngspice": run_ngspice, "builtin": partbench.run_builtin}


# The supply-biased dead zone takes its bias from the +/-15 V pins, which only real op-amps have.
BLOCK_KINDS = [
    (block, kind)
    for block in partbench.BLOCKS
    for kind in OPAMP_KINDS
    if not (block == "dead_zone_supplies" and kind != "tl074")
]


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize(("block", "kind"), BLOCK_KINDS)
def test_transfer_curve_from_slow_ramp(block, kind, engine):
    x, y, reference = partbench.transfer_curve(RUN[engine], block, kind)
    assert np.ptp(x) == pytest.approx(2 * partbench.FULL_SCALE)
    assert np.max(np.abs(y - reference)) < 0.01 * partbench.FULL_SCALE


@partbench.requires_ngspice
def test_glitch_grows_with_frequency_and_is_small_at_the_papers_rates():
    peaks = [partbench.glitch(run_ngspice, "tl074", f)[0] for f in (10.0, 1e3, 1e4)]
    assert peaks[0] < peaks[1] < peaks[2]
    # 10 Hz (the paper's excitation range, real time): under 0.5 % of the 5 V amplitude
    assert peaks[0] < 0.005 * 5.0


@partbench.requires_ngspice
def test_glitch_same_on_both_engines():
    # 1000 steps a period (the report uses 4000); the engines see the same grid
    ours = partbench.glitch(partbench.run_builtin, "tl074", 1e3, points=1000)
    theirs = partbench.glitch(run_ngspice, "tl074", 1e3, points=1000)
    assert ours[0] == pytest.approx(theirs[0], rel=0.02)  # peak error
    assert ours[2] == pytest.approx(theirs[2], rel=0.05)  # mean error ratio
