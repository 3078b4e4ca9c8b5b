"""read(write(c)) == c: every element kind and source shape, in every dialect, bit for bit.

The reference is the Circuit itself (dataclass equality compares every field, floats exactly).
Expressions that a dialect respells (``log`` -> ``ln``, ``^`` -> ``**``) are compared after
flattening, where they have become numbers.
"""

import dataclasses
import math
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from circuitsim.netlist.circuit import (
    AcSweep,
    Capacitor,
    Cccs,
    Ccvs,
    Circuit,
    CurrentSource,
    Diode,
    Expression,
    Inductor,
    Model,
    OperatingPoint,
    Pulse,
    Pwl,
    Resistor,
    Sin,
    Subcircuit,
    SubcircuitCall,
    Switch,
    Transient,
    Vccs,
    Vcvs,
    VoltageSource,
)
from circuitsim.netlist.dialects import get_dialect
from circuitsim.netlist.reader import parse_netlist, read_netlist
from circuitsim.netlist.writer import save_netlist, title_line, write_netlist

DIALECTS = ["ngspice", "ltspice", "multisim"]

# Awkward floats: shortest repr needs 17 digits, subnormal-free extremes, negative zero.
AWKWARD = [0.1 + 0.2, 1 / 3, 2.0 / 7e-9, 6.02214076e23, 1.602176634e-19, -0.0, 4.7e3, 1e-15]


def _every_kind() -> Circuit:
    c = Circuit(title="every kind: R C L V I E F G H D S X")
    c.params = {"rbase": 1e3, "gain": Expression("2*rbase/1k + 1")}
    c.models = {
        "dmod": Model("DMOD", "D", {"is": 1e-14, "n": 1.9, "rs": 0.1 + 0.2}),
        "smod": Model("Smod", "SW", {"vt": 0.5, "vh": 0.1, "ron": 1.0, "roff": 1e7}),
    }
    inner = Subcircuit(
        "inner",
        ("p", "q"),
        [Resistor("R1", "p", "q", Expression("rr/3"))],
        params={"rr": 1 / 3},
    )
    c.subcircuits = {
        "blk": Subcircuit(
            "Blk",
            ("a", "b", "c"),
            [
                Resistor("R1", "a", "m", Expression("rtop")),
                SubcircuitCall("X1", ("m", "b"), "inner", {"rr": Expression("rtop*2")}),
                Capacitor("C1", "m", "c", 1e-9),
                Diode("D1", "m", "c", "dloc", area=2.5),
            ],
            models={"dloc": Model("Dloc", "D", {"is": 2e-15})},
            subcircuits={"inner": inner},
            params={"rtop": 4.7e3, "k": Expression("rtop/2")},
        )
    }
    c.add(
        Resistor("R1", "in", "out", Expression("rbase")),
        Resistor("r2", "out", "0", AWKWARD[0]),
        Capacitor("C1", "out", "0", 1e-6, ic=0.25),
        Capacitor("C2", "out", "mid", AWKWARD[1]),
        Inductor("L1", "mid", "0", 2.2e-3, ic=-1e-3),
        Inductor("L2", "mid", "x", 1e-6),
        VoltageSource("V1", "in", "0", dc=5.0, ac_magnitude=1.0, ac_phase=45.0),
        VoltageSource("Vsin", "s", "0", waveform=Sin(0.5, 2.0, 50.0, 1e-3, 10.0, 30.0)),
        VoltageSource("Vsin2", "s2", "0", waveform=Sin(0.0, 1.0, AWKWARD[2])),
        VoltageSource(
            "Vpulse", "pl", "0", dc=1.0, waveform=Pulse(0.0, 5.0, 1e-6, 1e-9, 2e-9, 1e-3, 2e-3)
        ),
        VoltageSource("Vone", "p1", "0", waveform=Pulse(-1.0, 1.0, 1e-3)),
        VoltageSource("Vwid", "p2", "0", waveform=Pulse(0.0, 1.0, 0.0, 0.0, 0.0, 5e-4)),
        VoltageSource(
            "Vpwl", "w", "0", waveform=Pwl(tuple((k * 1e-4, AWKWARD[k % 8]) for k in range(40)))
        ),
        CurrentSource("I1", "out", "0", dc=-1e-3, ac_magnitude=AWKWARD[4]),
        CurrentSource("I2", "x", "0", waveform=Sin(0.0, 1e-3, 1e3)),
        CurrentSource("I3", "x", "0", waveform=Pulse(0.0, 1e-3, 0.0, 1e-6, 1e-6, 1e-3, 2e-3)),
        CurrentSource("I4", "x", "0", waveform=Pwl(((0.0, 0.0), (1e-3, 1e-3)))),
        Vcvs("E1", "e", "0", "out", "0", Expression("gain")),
        Vccs("G1", "e", "0", "in", "out", AWKWARD[3]),
        Cccs("F1", "f", "0", "V1", -2.0),
        Ccvs("H1", "h", "0", "Vsin", 50.0),
        Diode("D1", "out", "e", "dmod"),
        Diode("D2", "e", "out", "dmod", area=AWKWARD[6]),
        Switch("S1", "out", "0", "s", "0", model="smod"),
        Switch("S2", "out", "e", "s", "0", model="smod", initial="on"),
        Switch("S3", "out", "f", "s", "0", model="smod", initial="off"),
        SubcircuitCall("XA", ("in", "out", "0"), "blk"),
        SubcircuitCall("XB", ("in", "h", "0"), "blk", {"rtop": AWKWARD[7], "k": -0.0}),
    )
    c.initial_conditions = {"out": 0.5, "mid": AWKWARD[5]}
    c.options = {"reltol": 1e-4, "abstol": 1e-12, "method": "gear", "noacct": True}
    c.analyses = [
        Transient(1e-6, 1e-3),
        Transient(1e-6, 2e-3, 1e-4, 1e-7, uic=True),
        OperatingPoint(),
        AcSweep("dec", 20, 1.0, 1e6),
    ]
    return c


def _as_written(c: Circuit, dialect: str) -> Circuit:
    """``c`` with what the writer adds by design: the title as a ``*`` comment line, and the
    dialect's own ``.options`` (LTspice's plotwinsize=0) where the circuit has none."""
    options = dict(c.options)
    for key, value in get_dialect(dialect).options:
        options.setdefault(key, float(value))
    return dataclasses.replace(c, title=title_line(c.title), options=options)


def _read_back(c: Circuit, dialect: str) -> Circuit:
    back = parse_netlist(write_netlist(c, dialect))
    back.source = c.source
    return back


@pytest.mark.parametrize("dialect", DIALECTS)
def test_every_kind_round_trips_exactly(dialect):
    c = _every_kind()
    if dialect == "ngspice":
        c.control = ["set filetype=ascii\nrun\nwrite out.raw"]
    back = _read_back(c, dialect)
    if dialect != "ngspice":
        c.control = []  # not part of the other dialects: dropped with a note
    for got, want in zip(back.elements, c.elements, strict=True):
        assert got == want
    assert back == _as_written(c, dialect)
    # Negative zero survives too (== would not see its sign).
    assert math.copysign(1.0, back.element("XB").params["k"]) == -1.0


@pytest.mark.parametrize("dialect", DIALECTS)
def test_respelled_expressions_keep_their_value(dialect):
    from circuitsim.netlist.flatten import flatten

    c = Circuit(title="expressions")
    c.params = {
        "a": Expression("2^3 + 10**-1"),
        "b": Expression("log(a) + log10(a)*pow(2, 0.5) - LOG(2)^2"),
    }
    c.add(
        VoltageSource("V1", "x", "0", dc=1.0),
        Resistor("R1", "x", "0", Expression("a*b")),
        Resistor("R2", "x", "0", Expression("-2^2 + 2^3^2")),
    )
    text = write_netlist(c, dialect)
    assert "log(" not in text.lower()
    if dialect == "ltspice":
        assert "^" not in text  # LTspice reads ^ as XOR
    want = flatten(c)
    got = flatten(parse_netlist(text))
    assert [e.resistance for e in got.elements[1:]] == [e.resistance for e in want.elements[1:]]
    assert want.elements[2].resistance == -4.0 + 512.0  # ngspice precedence, by hand


@pytest.mark.parametrize("dialect", DIALECTS)
def test_written_text_is_a_fixed_point(dialect):
    once = write_netlist(_every_kind(), dialect)
    twice = write_netlist(parse_netlist(once), dialect)
    assert twice == once


# --- the corpus: netlists written the way people write them -------------------------------

CORPUS = Path(__file__).parent / "corpus"
CORPUS_FILES = sorted(CORPUS.glob("*.cir"))

requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)


def _same_meaning(got: Circuit, want: Circuit, dialect: str) -> None:
    from circuitsim.netlist.flatten import flatten

    want = dataclasses.replace(_as_written(want, dialect), source=None)
    got = dataclasses.replace(got, source=None)
    if dialect != "ngspice":
        want.control = []
    assert flatten(got) == flatten(want)


def test_corpus_is_there():
    assert len(CORPUS_FILES) >= 8


@pytest.mark.parametrize("dialect", DIALECTS)
@pytest.mark.parametrize("path", CORPUS_FILES, ids=lambda p: p.stem)
def test_corpus_round_trips(path, dialect):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # .print/.plot lines are dropped with a warning
        original = read_netlist(path)
    text = write_netlist(original, dialect)
    # The title is one line whatever its length; everything else is continued in time.
    assert max(len(line) for line in text.splitlines()[1:]) <= 80
    back = parse_netlist(text)
    _same_meaning(back, original, dialect)
    # Writing what was read back gives the same text again (less the note about a dropped
    # .control block, which the first writing consumed).
    dropped = f"* circuitsim: .control block dropped ({dialect} has none)\n"
    assert write_netlist(back, dialect) == text.replace(dropped, "")


def _ngspice_pair(path, tmp_path):
    from circuitsim.interop.ngspice import run_ngspice

    original = run_ngspice(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        circuit = read_netlist(path)
    written = tmp_path / f"{path.stem}.ngspice.cir"
    save_netlist(circuit, written, "ngspice")
    return original, run_ngspice(written)


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("path", CORPUS_FILES, ids=lambda p: p.stem)
def test_corpus_written_for_ngspice_runs_the_same(path, tmp_path):
    original, rewritten = _ngspice_pair(path, tmp_path)
    assert rewritten.names == original.names
    # Same deck up to number spelling: ngspice's own number parser may land one ulp away
    # from ours on a value like 4.7k, which can move a time step; compare on the original's
    # time points with a tolerance far below any circuit effect.
    assert rewritten.time[-1] == pytest.approx(original.time[-1], rel=1e-12)
    for name in original.names:
        want = original[name]
        got = np.interp(original.time, rewritten.time, rewritten[name])
        scale = max(np.max(np.abs(want)), 1e-12)
        assert np.max(np.abs(got - want)) <= 1e-6 * scale, name


# --- random circuits: any finite float, any element kind, any dialect ---------------------

_FLOATS = st.floats(allow_nan=False, allow_infinity=False)
_NODES = st.sampled_from(["0", "a", "b", "n_1", "out"])


# PWL times: not decreasing (the reader refuses others, as ngspice does).
_pwl_points = st.lists(st.tuples(_FLOATS.map(abs), _FLOATS), min_size=1, max_size=30).map(
    lambda pts: tuple(sorted(pts, key=lambda p: p[0]))
)


@st.composite
def _elements(draw, index: int):
    kind = draw(st.sampled_from("RCLVIEGFHDSX"))
    n1, n2, n3, n4 = (draw(_NODES) for _ in range(4))
    x = draw(_FLOATS)
    name = f"{kind}{index}"
    if kind == "R":
        return Resistor(name, n1, n2, x)
    if kind in "CL":
        cls = Capacitor if kind == "C" else Inductor
        return cls(name, n1, n2, x, ic=draw(st.none() | _FLOATS))
    if kind in "VI":
        cls = VoltageSource if kind == "V" else CurrentSource
        shape = draw(
            st.none()
            | st.builds(Sin, _FLOATS, _FLOATS, _FLOATS, _FLOATS, _FLOATS, _FLOATS)
            | st.builds(Pulse, _FLOATS, _FLOATS, _FLOATS, _FLOATS, _FLOATS, _FLOATS, _FLOATS)
            | st.builds(Pulse, _FLOATS, _FLOATS, _FLOATS, _FLOATS, _FLOATS, _FLOATS)
            | st.builds(Pwl, _pwl_points)
        )
        return cls(
            name, n1, n2, dc=x, waveform=shape, ac_magnitude=draw(_FLOATS), ac_phase=draw(_FLOATS)
        )
    if kind in "EG":
        return (Vcvs if kind == "E" else Vccs)(name, n1, n2, n3, n4, x)
    if kind in "FH":
        return (Cccs if kind == "F" else Ccvs)(name, n1, n2, "Vc", x)
    if kind == "D":
        return Diode(name, n1, n2, "dm", area=x)
    if kind == "S":
        return Switch(
            name, n1, n2, n3, n4, model="sm", initial=draw(st.sampled_from([None, "on", "off"]))
        )
    return SubcircuitCall(name, (n1, n2), "blk", {"p": x})


@st.composite
def _circuits(draw):
    c = Circuit(title=draw(st.sampled_from(["t", "random circuit", "R1 looks like an element"])))
    c.elements = [draw(_elements(k)) for k in range(draw(st.integers(1, 8)))]
    c.models = {
        "dm": Model("dm", "D", {"is": draw(_FLOATS)}),
        "sm": Model("sm", "SW", {"vt": draw(_FLOATS), "vh": draw(_FLOATS)}),
    }
    c.subcircuits = {
        "blk": Subcircuit(
            "blk",
            ("p1", "p2"),
            [Resistor("R1", "p1", "p2", Expression("p"))],
            params={"p": draw(_FLOATS)},
        )
    }
    c.initial_conditions = {"a": draw(_FLOATS)}
    return c


@pytest.mark.parametrize("dialect", DIALECTS)
@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(c=_circuits())
def test_random_circuits_round_trip_bit_for_bit(dialect, c):
    back = parse_netlist(write_netlist(c, dialect))
    back.source = None
    assert back == _as_written(c, dialect)
