"""Resistances of 1e-30 ohm (issue 21 listed "R = 1e-30 ohm: gain 1 vs 2" against ngspice).

The report's netlist was not kept; these are the circuits it could have been (a ladder of tiny
resistors, and an amplifier whose feedback and ground resistors are both 1e-30 ohm, gain
1 + Rf/Rg = 2), each solved by both engines and by hand.
"""

import pytest

from circuitsim.netlist.reader import parse_netlist
from circuitsim.solver import simulate
from tests.conftest import requires_ngspice

LADDER = """* tiny resistors in series
V1 in 0 1
R1 in a 1e-30
R2 a b 1e-30
R3 b 0 1e-30
.op
.end
"""

AMPLIFIER = """* non-inverting amplifier, Rf = Rg = 1e-30 ohm
V1 in 0 1
E1 out 0 in n 1e6
Rf out n 1e-30
Rg n 0 1e-30
.op
.end
"""

# by hand: thirds of 1 V; gain A / (1 + A/2) with A = 1e6, i.e. 2 / (1 + 2e-6)
EXPECTED = {
    LADDER: {"v(a)": 2 / 3, "v(b)": 1 / 3},
    AMPLIFIER: {"v(out)": 2 / (1 + 2e-6), "v(n)": 1 / (1 + 2e-6)},
}


@pytest.mark.parametrize("text", [LADDER, AMPLIFIER], ids=["ladder", "amplifier"])
def test_tiny_resistors_give_the_hand_values(text):
    waves = simulate(parse_netlist(text))
    for name, value in EXPECTED[text].items():
        assert float(waves[name][0]) == pytest.approx(value, rel=1e-12)


@requires_ngspice
@pytest.mark.parametrize("text", [LADDER, AMPLIFIER], ids=["ladder", "amplifier"])
def test_tiny_resistors_agree_with_ngspice(text):
    from circuitsim.interop.ngspice import run_ngspice

    ours, theirs = simulate(parse_netlist(text)), run_ngspice(text)
    for name in EXPECTED[text]:
        assert float(ours[name][0]) == pytest.approx(float(theirs[name][0]), rel=1e-12)
