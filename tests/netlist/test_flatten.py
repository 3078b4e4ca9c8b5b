"""flatten: names, nodes, parameter scoping and model scoping, checked against hand analysis.

The nested corpus circuits are also solved here with a small dense nodal analysis of the
flattened elements and compared with the voltage divider worked by hand and with ngspice's
operating point of the unflattened file.
"""

import copy
import dataclasses
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from circuitsim.netlist import flatten as flatten_module
from circuitsim.netlist.circuit import (
    Capacitor,
    Cccs,
    Ccvs,
    Circuit,
    Diode,
    Expression,
    Pulse,
    Pwl,
    Resistor,
    Sin,
    SubcircuitCall,
    Vccs,
    Vcvs,
    VoltageSource,
)
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.flatten import flatten
from circuitsim.netlist.reader import parse_netlist, read_netlist

CORPUS = Path(__file__).parent / "corpus"
requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)


def dc_solve(circuit: Circuit) -> dict[str, float]:
    """Node voltages of a flat linear circuit (R, V dc, E, G, F, H) by modified nodal analysis."""
    nodes = circuit.node_names()
    index = {n: i for i, n in enumerate(nodes)}
    branches = [e for e in circuit.elements if isinstance(e, VoltageSource | Vcvs | Ccvs)]
    bindex = {e.name.lower(): len(nodes) + k for k, e in enumerate(branches)}
    size = len(nodes) + len(branches)
    a = np.zeros((size, size))
    z = np.zeros(size)

    def add(row, col, value):
        if row is not None and col is not None:
            a[row, col] += value

    def at(node):
        return index.get(node)

    for e in circuit.elements:
        p, n = at(e.positive), at(e.negative)
        if isinstance(e, Resistor):
            g = 1.0 / e.resistance
            add(p, p, g), add(n, n, g), add(p, n, -g), add(n, p, -g)
        elif isinstance(e, Vccs):
            cp, cn = at(e.control_positive), at(e.control_negative)
            gm = e.transconductance
            add(p, cp, gm), add(p, cn, -gm), add(n, cp, -gm), add(n, cn, gm)
        elif isinstance(e, Cccs):
            k = bindex[e.control.lower()]
            add(p, k, e.gain), add(n, k, -e.gain)
        else:  # a branch: v(p) - v(n) = ...
            k = bindex[e.name.lower()]
            add(p, k, 1.0), add(n, k, -1.0), add(k, p, 1.0), add(k, n, -1.0)
            if isinstance(e, VoltageSource):
                z[k] = e.dc
            elif isinstance(e, Vcvs):
                add(k, at(e.control_positive), -e.gain), add(k, at(e.control_negative), e.gain)
            else:
                add(k, bindex[e.control.lower()], -e.transresistance)
    x = np.linalg.solve(a, z)
    return {n: float(x[i]) for n, i in index.items()}


def test_nested_subcircuits_names_nodes_and_values():
    flat = flatten(read_netlist(CORPUS / "nested_subckt.cir"))
    # r = rbase*scale = 2k; XA: rtop=r, rbot defaults to rtop; XB: rtop=2r, rbot=r
    assert flat.elements == [
        VoltageSource("V1", "vin", "0", dc=9.0),
        Resistor("R.X1.XA.Rt", "vin", "x1.m1", 2e3),
        Resistor("R.X1.XA.Rb", "x1.m1", "0", 2e3),
        Resistor("R.X1.XB.Rt", "x1.m1", "vout", 4e3),
        Resistor("R.X1.XB.Rb", "vout", "0", 2e3),
        Resistor("Rprobe", "vout", "0", 1e9),
    ]
    assert flat.params == {"rbase": 1e3, "scale": 2.0}
    assert flat.subcircuits == {}


def test_nested_subcircuits_solve_like_the_hand_analysis():
    v = dc_solve(flatten(read_netlist(CORPUS / "nested_subckt.cir")))
    bottom = 1 / (1 / 2e3 + 1 / 1e9)  # XB's 2k in parallel with the 1G probe
    load = 1 / (1 / 2e3 + 1 / (4e3 + bottom))  # XA's bottom 2k in parallel with XB
    m1 = 9.0 * load / (2e3 + load)
    assert v["x1.m1"] == pytest.approx(m1, rel=1e-12)
    assert v["vout"] == pytest.approx(m1 * bottom / (4e3 + bottom), rel=1e-12)


@requires_ngspice
@pytest.mark.parametrize("name", ["nested_subckt.cir", "controlled_sources.cir"])
def test_flattened_solution_matches_ngspice(name):
    ours = dc_solve(flatten(read_netlist(CORPUS / name)))
    out = subprocess.run(
        ["ngspice", "-b", str(CORPUS / name)], capture_output=True, text=True, timeout=60
    ).stdout
    theirs = {
        m[1]: float(m[2])
        for m in re.finditer(r"^\s+([a-z0-9_.]+)\s+([-+]?\d\.\d+e[-+]\d+)\s*$", out, re.MULTILINE)
        if "#" not in m[1]
    }
    assert theirs, out
    for node, value in theirs.items():
        assert ours[node] == pytest.approx(value, rel=1e-5, abs=1e-9), node


def test_controlled_sources_hand_values():
    v = dc_solve(flatten(read_netlist(CORPUS / "controlled_sources.cir")))
    i_sense = 1.0 / 1e3  # V1 = 1 V across R1 into the 0 V ammeter
    assert v["e1"] == pytest.approx(2.5)
    assert v["g1"] == pytest.approx(2e-3 * 1.0 * 500)
    assert v["f1"] == pytest.approx(3 * i_sense * 1e3)
    assert v["h1"] == pytest.approx(2e3 * i_sense)


NESTED = """params and models
.param k=2
.model dm D(is=1e-14)
.subckt inner a b params: r=1k n=1
.model dm D(is={r*1e-17} n={n})
R1 a mid {r}
D1 mid b dm
Vs mid m2 0
H1 b 0 Vs {r}
F1 b 0 Vtop 1
.ends
.subckt outer x y params: a=1 b={2*a*k}
Xi x y inner r={b} n={a}
D2 x y dm
.ends outer
Vtop in 0 1
XU1 in 0 outer a=3
XU2 in out outer
D3 in out dm 2
C1 out 0 {k*1u} IC={k/4}
Vs2 s 0 SIN(0 {k} {k*1k}) AC {k}
Vp p 0 PULSE(0 {k} 0 1n 1n {k*1m})
Vw w 0 PWL(0 0 {k*1m} {k})
.ic v(out)={k/2}
.options gmin={k*1e-12}
.tran 1u 1m
"""


def test_parameters_override_in_order_and_models_are_scoped():
    circuit = parse_netlist(NESTED)
    before = copy.deepcopy(circuit)
    flat = flatten(circuit)
    assert circuit == before  # the input is not modified
    by_name = {e.name: e for e in flat.elements}
    # XU1: a=3 so b=2*3*k=12; XU2: a=1 so b=4
    assert by_name["R.XU1.Xi.R1"].resistance == 12.0
    assert by_name["R.XU2.Xi.R1"].resistance == 4.0
    assert by_name["R.XU1.Xi.R1"].negative == "xu1.xi.mid"
    assert by_name["D.XU1.Xi.D1"] == Diode("D.XU1.Xi.D1", "xu1.xi.mid", "0", "xu1.xi.dm")
    assert flat.models["xu1.xi.dm"].params == {"is": 12 * 1e-17, "n": 3.0}
    assert flat.models["xu2.xi.dm"].params == {"is": 4 * 1e-17, "n": 1.0}
    # outer has no local dm: its diode uses the global one, as does the top-level D3
    assert by_name["D.XU1.D2"].model == "dm" and by_name["D3"].model == "dm"
    assert by_name["D3"].area == 2.0
    assert flat.models["dm"].params == {"is": 1e-14}
    # H1's control is the local Vs (renamed with it); F1's is the top-level Vtop
    assert by_name["H.XU2.Xi.H1"].control == "V.XU2.Xi.Vs"
    assert by_name["H.XU2.Xi.H1"].transresistance == 4.0
    assert by_name["F.XU2.Xi.F1"].control == "Vtop"
    assert by_name["H.XU2.Xi.H1"].positive == "out"
    assert by_name["C1"] == Capacitor("C1", "out", "0", 2e-6, ic=0.5)
    assert by_name["Vs2"].waveform == Sin(0.0, 2.0, 2e3) and by_name["Vs2"].ac_magnitude == 2.0
    assert by_name["Vp"].waveform == Pulse(0.0, 2.0, 0.0, 1e-9, 1e-9, 2e-3)
    assert by_name["Vw"].waveform == Pwl(((0.0, 0.0), (2e-3, 2.0)))
    assert flat.initial_conditions == {"out": 1.0}
    assert flat.options == {"gmin": 2e-12}


def no_expressions(value) -> bool:
    if isinstance(value, Expression | SubcircuitCall):
        return False
    if dataclasses.is_dataclass(value):
        return all(no_expressions(getattr(value, f.name)) for f in dataclasses.fields(value))
    if isinstance(value, tuple | list):
        return all(no_expressions(v) for v in value)
    if isinstance(value, dict):
        return all(no_expressions(v) for v in value.values())
    return True


@pytest.mark.parametrize("path", sorted(CORPUS.glob("*.cir")), ids=lambda p: p.name)
def test_flat_corpus_has_no_expression_left(path):
    flat = flatten(read_netlist(path))
    assert no_expressions(flat)
    names = [e.name.lower() for e in flat.elements]
    assert len(names) == len(set(names))


def test_harmonic_oscillator_flattens_to_two_integrators_and_an_inverter():
    flat = flatten(read_netlist(CORPUS / "harmonic_oscillator.cir"))
    by_name = {e.name: e for e in flat.elements}
    assert by_name["R.Xi1.Rin"] == Resistor("R.Xi1.Rin", "x", "xi1.sum", 10e3)
    assert by_name["C.Xi2.Cf"] == Capacitor("C.Xi2.Cf", "xi2.sum", "xm", 100e-9)
    assert by_name["E.Xinv.Eop"] == Vcvs("E.Xinv.Eop", "x", "0", "0", "xinv.s", 1e6)
    assert len(flat.elements) == 9


FLATTEN_ERRORS = {
    "unknown subcircuit": ("t\nX1 a b nothere\n", "X1: unknown subcircuit 'nothere'"),
    "port count": (
        "t\n.subckt s p q\nR1 p q 1\n.ends\nX1 a s\n",
        "X1: subcircuit s has 2 port(s) (p q), got 1 connection(s)",
    ),
    "direct recursion": (
        "t\n.subckt s p\nX2 p s\n.ends\nX1 a s\n",
        "in X1: X2: recursive subcircuit s -> s",
    ),
    "indirect recursion": (
        "t\n.subckt s p\nX2 p u\n.ends\n.subckt u p\nX3 p s\n.ends\nX1 a s\n",
        "in X1.X2: X3: recursive subcircuit s -> u -> s",
    ),
    "undefined global parameter": (
        "t\n.param a={b*2}\nR1 x 0 {a}\n",
        "global parameter a: undefined parameter 'b' in 'b*2'",
    ),
    "undefined parameter in an element": (
        "t\nR1 x 0 {q}\n",
        "R1 resistance: undefined parameter 'q' in 'q'",
    ),
    "undefined parameter in a body": (
        "t\n.subckt s p\nR1 p 0 {rr}\n.ends\nX1 a s\n",
        "in X1: R1 resistance: undefined parameter 'rr' in 'rr'",
    ),
    "instance parameter not declared": (
        "t\n.subckt s p params: r=1\nR1 p 0 {r}\n.ends\nX1 a s q=2\n",
        "X1: subcircuit s has no parameter 'q' (its parameters: r)",
    ),
    "arithmetic failure": (
        "t\n.param z=0\nR1 a 0 {1/z}\n",
        "R1 resistance: division by zero in '1/z'",
    ),
    "bad .ic": ("t\nR1 a 0 1\n.ic v(a)={nope}\n", ".ic v(a): undefined parameter 'nope' in 'nope'"),
}


@pytest.mark.parametrize("name", list(FLATTEN_ERRORS))
def test_flatten_errors(name):
    text, message = FLATTEN_ERRORS[name]
    with pytest.raises(NetlistError) as info:
        flatten(parse_netlist(text, source="case.cir"))
    assert (info.value.file, info.value.message) == ("case.cir", message)


def test_subcircuit_defined_inside_another_is_local():
    text = "t\n.subckt a p\n.subckt b q\nR1 q 0 1\n.ends\nXb p b\n.ends\nXa n a\nXb2 n b\n"
    with pytest.raises(NetlistError, match="Xb2: unknown subcircuit 'b'"):
        flatten(parse_netlist(text))
    flat = flatten(parse_netlist(text.replace("Xb2 n b\n", "")))
    assert [e.name for e in flat.elements] == ["R.Xa.Xb.R1"]


def test_builder_circuit_with_int_values_flattens():
    c = Circuit(elements=[Resistor("R1", "a", "0", 1000), Vccs("G1", "a", "0", "a", "0", 0)])
    flat = flatten(c)
    assert flat.elements[0].resistance == 1000.0 and isinstance(
        flat.elements[1].transconductance, float
    )


def test_ccvs_and_cccs_keep_their_types():
    flat = flatten(read_netlist(CORPUS / "controlled_sources.cir"))
    kinds = {type(e) for e in flat.elements}
    assert {Vcvs, Vccs, Cccs, Ccvs} <= kinds


def test_fan_out_tree_is_capped_not_hung(monkeypatch):
    monkeypatch.setattr(flatten_module, "MAX_ELEMENTS", 5000)  # the mechanism, quickly
    # s0 calls s1 twice, s1 calls s2 twice ...: 2**60 instances, no element at all
    lines = ["t"]
    for level in range(60):
        lines += [f".subckt s{level} p", f"Xa p s{level + 1}", f"Xb p s{level + 1}", ".ends"]
    lines += [".subckt s60 p", ".ends", "X1 n s0"]
    with pytest.raises(NetlistError, match="would exceed 5000 elements and instances"):
        flatten(parse_netlist("\n".join(lines) + "\n"))
