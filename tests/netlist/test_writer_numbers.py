"""Numbers in generated netlists: no float noise in derived values, part values exact.

``round_derived`` rounds what the generator computes (source values, initial conditions) to
12 significant digits; the reference answers are the decimal numbers written by hand.
"""

import re

from circuitsim.netlist.circuit import Capacitor, Circuit, Pwl, Resistor, Sin, VoltageSource
from circuitsim.netlist.tidy import round_derived, round_significant
from circuitsim.netlist.writer import write_netlist


def test_float_noise_is_rounded_away():
    assert round_significant(3.3 * 4) == 13.2  # 13.200000000000001
    assert round_significant(-0.1 - 0.12) == -0.22  # -0.22000000000000003
    assert round_significant(2.97 - 1e-16) == 2.97
    assert round_significant(1 / 3) == 0.333333333333
    assert str(round_significant(-0.0)) == "-0.0"
    assert round_significant(float("inf")) == float("inf")


def test_generated_values_are_written_short_and_parts_exact():
    c = Circuit(title="noise")
    c.add(
        VoltageSource("V1", "a", "0", waveform=Sin(0.0, 3.3 * 4, 3.0)),
        VoltageSource("V2", "b", "0", dc=-0.1 - 0.12),
        VoltageSource("V3", "c", "0", waveform=Pwl(((0.0, 0.0), (0.1 * 3, 0.7 + 0.1)))),
        Capacitor("C1", "a", "b", 1e-6, ic=-0.1 - 0.12),
        Resistor("R1", "a", "b", 0.1 + 0.2),  # a part: kept bit for bit
    )
    c.initial_conditions = {"a": -0.1 - 0.12}
    text = write_netlist(round_derived(c))
    assert "SIN(0 13.2 3)" in text
    assert "V2 b 0 DC -0.22" in text
    assert "PWL(0 0 0.3 0.8)" in text
    assert "C1 a b 1u IC=-0.22" in text
    assert ".ic v(a)=-0.22" in text
    assert "R1 a b 0.30000000000000004" in text


def test_committed_netlists_carry_no_float_noise():
    from pathlib import Path

    folder = Path(__file__).resolve().parents[2] / "netlists"
    files = sorted(folder.glob("*.cir"))
    assert files
    for path in files:
        text = path.read_text()
        # 15 or more significant digits in a row is float noise, never a designed value
        assert not re.search(r"\d\.?\d{14,}", text), path.name
        assert text.startswith("* ")
