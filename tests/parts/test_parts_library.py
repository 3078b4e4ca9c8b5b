"""parts.lib: what it holds, what it may use, and the diode model against datasheet figures."""

import re

import partbench
import pytest

from circuitsim.interop.ngspice import run_ngspice
from circuitsim.netlist import library
from circuitsim.netlist.circuit import Diode, SubcircuitCall
from circuitsim.netlist.errors import NetlistError

# Element letters every target simulator (ngspice, LTspice, Multisim) accepts alike.
PORTABLE_LETTERS = set("RCLEGFHDVI")


def test_library_holds_the_parts_with_their_pins_and_parameters():
    subcircuits, models = library.load_library()
    assert set(subcircuits) == {"opamp_ideal", "tl074"}
    assert subcircuits["tl074"].ports == ("inp", "inm", "vcc", "vee", "out")
    assert subcircuits["tl074"].params == {"vos": 0.0, "ib": 0.0, "ios": 0.0}
    assert subcircuits["opamp_ideal"].ports == ("inp", "inm", "out")
    assert subcircuits["opamp_ideal"].params == {"gain": 1e6}
    assert models["d1n4148"].kind == "D"


def test_library_uses_only_portable_primitives():
    subcircuits, _ = library.load_library()
    for sub in subcircuits.values():
        letters = {element.letter for element in sub.elements}
        assert letters <= PORTABLE_LETTERS, (sub.name, letters - PORTABLE_LETTERS)
        assert not sub.subcircuits
    # and the text itself has no behavioural source or other simulator-specific line
    text = library.library_text()
    assert not re.search(r"^\s*[BAXQMJ]", text, re.IGNORECASE | re.MULTILINE)


def test_copies_do_not_share_state_with_the_cache():
    first = library.subcircuit("TL074")
    first.elements.clear()
    first.params["vos"] = 1.0
    again = library.subcircuit("tl074")
    assert again.elements and again.params["vos"] == 0.0
    diode = library.model("d1n4148")
    diode.params.clear()
    assert library.model("D1N4148").params


def test_unknown_part_names_the_library_contents():
    with pytest.raises(NetlistError, match="tl074"):
        library.subcircuit("LM741")
    with pytest.raises(NetlistError, match="d1n4148"):
        library.model("1N914")


def test_library_file_is_found_by_plain_include():
    # The reader falls back to the package library for `.include parts.lib`.
    from circuitsim.netlist.reader import parse_netlist

    circuit = parse_netlist("t\n.include parts.lib\nX1 a b c OPAMP_IDEAL\nD1 c 0 D1N4148\n")
    assert isinstance(circuit.elements[0], SubcircuitCall)
    assert isinstance(circuit.elements[1], Diode)
    assert "tl074" in circuit.subcircuits and "d1n4148" in circuit.models


# Forward voltage of a 1N4148 at 25 C, read from published typical characteristic curves
# (forward current against forward voltage); the 10 mA point is below the 1.0 V maximum.
DATASHEET_VF = {1e-3: 0.62, 10e-3: 0.74, 100e-3: 0.95}


ENGINES = [
    pytest.param("ngspice", marks=partbench.requires_ngspice),
    pytest.param("builtin"),
]
RUN = {"ngspice": run_ngspice, "builtin": partbench.run_builtin}


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("amps", sorted(DATASHEET_VF))
def test_diode_forward_voltage_matches_datasheet_curve(amps, engine):
    body = f"I1 0 a {amps!r}\nD1 a 0 D1N4148\n"
    vf = float(RUN[engine](partbench.deck(body, ".op"))["v(a)"][0])
    assert vf == pytest.approx(DATASHEET_VF[amps], abs=0.02)


@pytest.mark.parametrize("engine", ENGINES)
def test_diode_reverse_leakage_below_datasheet_maximum(engine):
    # Datasheet: IR <= 25 nA at VR = 20 V, 25 C.
    waves = RUN[engine](partbench.deck("V1 k 0 20\nD1 0 k D1N4148\n", ".op"))
    assert 0 < abs(float(waves["i(v1)"][0])) <= 25e-9


@pytest.mark.parametrize("engine", ENGINES)
def test_ideal_opamp_inverting_gain(engine):
    # Inverting amplifier, gain -10: closed-loop gain -10 / (1 + 11 / A) with A = 1e6.
    body = "VIN in 0 0.5\nR1 in m 1k\nR2 m out 10k\nX1 0 m out OPAMP_IDEAL\n"
    out = float(RUN[engine](partbench.deck(body, ".op"))["v(out)"][0])
    assert out == pytest.approx(-5.0 / (1 + 11 / 1e6), rel=1e-9)


@pytest.mark.parametrize("engine", ENGINES)
def test_ideal_opamp_gain_parameter(engine):
    # gain=100: a follower gives 100/101 of its input.
    body = "VIN in 0 1\nX1 in out out OPAMP_IDEAL gain=100\nRL out 0 1k\n"
    out = float(RUN[engine](partbench.deck(body, ".op"))["v(out)"][0])
    assert out == pytest.approx(100 / 101, rel=1e-9)
