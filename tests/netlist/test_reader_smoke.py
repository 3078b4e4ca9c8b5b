"""A first end-to-end read: one of every element kind, values checked against the text."""

from circuitsim.netlist.circuit import Expression, Pulse, Pwl, Sin
from circuitsim.netlist.reader import parse_netlist

TEXT = """Smoke
V1 in 0 DC 5 AC 1 SIN(0 1 1k)
Vp p 0 PULSE(0 5 0 1n 1n 0.5m 1m)
Vw w gnd pwl 0,0 1m,5
+ 2m,0
R1 IN out {2*rbase}
C1 out 0 1u IC=0.5
.param rbase=10k
.tran 1u 10m uic
.end
"""


def test_smoke():
    c = parse_netlist(TEXT)
    assert c.title == "Smoke"
    v1 = c.element("v1")
    assert (v1.dc, v1.ac_magnitude, v1.waveform) == (5.0, 1.0, Sin(0.0, 1.0, 1e3))
    assert c.element("Vp").waveform == Pulse(0.0, 5.0, 0.0, 1e-9, 1e-9, 0.5e-3, 1e-3)
    assert c.element("Vw").waveform == Pwl(((0.0, 0.0), (1e-3, 5.0), (2e-3, 0.0)))
    assert c.element("Vw").negative == "0"
    r1 = c.element("R1")
    assert (r1.positive, r1.negative, r1.resistance) == ("in", "out", Expression("2*rbase"))
    assert c.element("C1").ic == 0.5
    assert c.params == {"rbase": 10e3}
    assert c.transient.tstop == 10e-3 and c.transient.uic
