"""A switch model with negative VH: what ngspice 39 does with it, and that we say so.

ngspice (``swload.c``) reads VH < 0 as reversed hysteresis; the builtin engine refuses it.
The reader warns and ``check`` reports a ``negative-hysteresis`` finding whose thresholds are
the ones ngspice switches at, measured here on a control ramp 0 -> 1 -> 0 V.
"""

import warnings

import numpy as np
import pytest

from circuitsim.netlist.reader import NetlistWarning, parse_netlist
from circuitsim.netlist.topology import check_circuit
from tests.conftest import requires_ngspice

RAMP = """switch with hysteresis VH={vh}
Vc c 0 PWL(0 0 1m 1 2m 0)
Vdd dd 0 1
R1 dd out 1k
S1 out 0 c 0 swm
.model swm SW(VT=0.5 VH={vh} RON=1 ROFF=1meg)
.tran 1u 2m 0 1u
.end
"""


def switching_levels(waves) -> tuple[float, float]:
    """Control voltages where the switch turned on (rising ramp) and off (falling), V."""
    out = np.asarray(waves["v(out)"])
    control = np.asarray(waves["v(c)"])
    on = out < 0.5
    edges = np.flatnonzero(np.diff(on.astype(int))) + 1
    assert len(edges) == 2 and on[edges[0]] and not on[edges[1]]
    return float(control[edges[0]]), float(control[edges[1]])


@requires_ngspice
@pytest.mark.parametrize(("vh", "on_at", "off_at"), [(0.2, 0.7, 0.3), (-0.2, 0.3, 0.7)])
def test_ngspice_reverses_the_hysteresis_for_negative_vh(vh, on_at, off_at):
    from circuitsim.interop.ngspice import run_ngspice

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NetlistWarning)
        waves = run_ngspice(RAMP.format(vh=vh))
    on, off = switching_levels(waves)
    assert on == pytest.approx(on_at, abs=2e-3)
    assert off == pytest.approx(off_at, abs=2e-3)


def test_negative_vh_is_warned_about_with_ngspices_thresholds():
    with pytest.warns(NetlistWarning, match=r"on at VT\+VH=0.3 V .* off at VT-VH=0.7 V") as info:
        circuit = parse_netlist(RAMP.format(vh=-0.2), source="ramp.cir")
    assert "ramp.cir:6" in str(info[0].message)
    findings = [f for f in check_circuit(circuit) if f.kind == "negative-hysteresis"]
    assert len(findings) == 1 and "swm" in findings[0].message


def test_negative_vh_given_by_a_parameter_is_found_by_check():
    text = RAMP.format(vh="{h}").replace(".tran", ".param h=-0.1\n.tran")
    with warnings.catch_warnings():
        warnings.simplefilter("error", NetlistWarning)  # not known at read time: no warning
        circuit = parse_netlist(text)
    findings = [f for f in check_circuit(circuit) if f.kind == "negative-hysteresis"]
    assert len(findings) == 1 and "VH=-0.1" in findings[0].message


def test_zero_and_positive_vh_are_quiet():
    for vh in (0, 0.2):
        with warnings.catch_warnings():
            warnings.simplefilter("error", NetlistWarning)
            circuit = parse_netlist(RAMP.format(vh=vh))
        assert not [f for f in check_circuit(circuit) if f.kind == "negative-hysteresis"]


def test_the_builtin_engine_refuses_negative_vh_rather_than_differ_from_ngspice():
    from circuitsim.solver import simulate
    from circuitsim.solver.errors import CircuitInputError

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NetlistWarning)
        circuit = parse_netlist(RAMP.format(vh=-0.2))
    with pytest.raises(CircuitInputError, match=r"switch S1: model VH < 0"):
        simulate(circuit)
