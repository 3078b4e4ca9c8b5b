"""Fuzz: mutated and random netlists never make the reader or flatten fail other than cleanly.

Whatever the input, ``parse_netlist`` either returns a Circuit or raises NetlistError with a
line number inside the text, and ``flatten`` of a read circuit either returns or raises
NetlistError. The hypothesis deadline catches hangs (an example takes about a millisecond;
the deadline allows a thousand times that for noisy CI machines).
"""

import warnings
from datetime import timedelta
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.flatten import flatten
from circuitsim.netlist.reader import parse_netlist

CORPUS = Path(__file__).parent / "corpus"
TEXTS = [p.read_text() for p in sorted(CORPUS.glob("*.cir"))]

FUZZ = settings(
    deadline=timedelta(seconds=1),
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    derandomize=True,  # the same examples on every run: a CI failure reproduces locally
    database=None,
)

NASTY_CHARS = list("(){}=,+*;$'\".\t\\:!?@#%&|<>^~-_0123456789eEkKmMuUgGxX \x00\u00b5\u2013\n")
BAD_NUMBERS = [
    "1e999",
    "-1e999",
    "1e-999",
    "4k7",
    "1..2",
    "1.2.3",
    "nan",
    "inf",
    "-",
    "+",
    ".",
    "e5",
    "1e",
    "1e+",
    "9" * 400,
    "0." + "0" * 400 + "1",
    "1" + "e9" * 3,
    "{1/0}",
    "{}",
    "{(}",
    "{1e308*10}",
    "{" * 50 + "1" + "}" * 50,
    "{" + "(" * 500 + "1" + ")" * 500 + "}",
    "{sqrt(-1)}",
    "{undefined_name}",
    "'a*'",
    "1meg1",
    "0",
    "-0",
]


def run(text: str) -> None:
    """The property: only NetlistError escapes, and reader errors carry a valid line number."""
    lines = text.splitlines()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            circuit = parse_netlist(text, source="fuzz.cir", base_dir=str(CORPUS))
        except NetlistError as error:
            assert error.line is not None, str(error)
            if error.file == "fuzz.cir":
                assert 1 <= error.line <= max(len(lines), 1), str(error)
            assert error.message
            return
        try:
            flatten(circuit)
        except NetlistError as error:
            assert error.message


@st.composite
def mutated_corpus(draw):
    lines = draw(st.sampled_from(TEXTS)).splitlines()
    for _ in range(draw(st.integers(1, 6))):
        op = draw(st.integers(0, 9))
        i = draw(st.integers(0, len(lines) - 1)) if lines else 0
        if not lines:
            lines.append("")
            continue
        line = lines[i]
        if op == 0:  # truncate a line
            lines[i] = line[: draw(st.integers(0, max(len(line) - 1, 0)))]
        elif op == 1:  # a stray character
            j = draw(st.integers(0, len(line)))
            lines[i] = line[:j] + draw(st.sampled_from(NASTY_CHARS)) + line[j:]
        elif op == 2:  # drop a field: wrong arity
            words = line.split()
            if words:
                del words[draw(st.integers(0, len(words) - 1))]
            lines[i] = " ".join(words)
        elif op == 3:  # an extra field
            words = line.split()
            words.insert(draw(st.integers(0, len(words))), draw(st.sampled_from(BAD_NUMBERS)))
            lines[i] = " ".join(words)
        elif op == 4:  # a malformed or huge number in place of a field
            words = line.split()
            if words:
                words[draw(st.integers(0, len(words) - 1))] = draw(st.sampled_from(BAD_NUMBERS))
            lines[i] = " ".join(words)
        elif op == 5:  # delete a line (a .ends, an .endc, a .subckt ...)
            del lines[i]
        elif op == 6:  # duplicate a line
            lines.insert(i, line)
        elif op == 7:  # make it a continuation, or remove one
            lines[i] = line[1:] if line.startswith("+") else "+ " + line
        elif op == 8:  # delete a character
            j = draw(st.integers(0, max(len(line) - 1, 0)))
            lines[i] = line[:j] + line[j + 1 :]
        else:  # swap two lines
            k = draw(st.integers(0, len(lines) - 1))
            lines[i], lines[k] = lines[k], lines[i]
    return "\n".join(lines) + draw(st.sampled_from(["\n", "", "\r\n"]))


@given(mutated_corpus())
@settings(FUZZ, max_examples=1000)
def test_mutated_corpus(text):
    run(text)


TOKENS = st.sampled_from(
    [
        "a", "b", "0", "gnd", "n1", "1k", "2", "-1", "dc", "DC", "ac", "sin", "SIN(", "pulse",
        "PWL", "(", ")", ")(", "=", "ic=", "IC", "=1", "on", "off", "params:", "r=1", "r={x}",
        "{a*2}", "x=", "poly(1)", "dmod", "sw", "D(", "SW(is=1", "v(a)=1", "v(", "uic", "dec",
        "10", "1meg", "sub", "Vx", ",", ";", "$", "+", "*", "'1+'", "{", "}", "1e999", "4k7",
    ]
)  # fmt: skip
HEADS = st.sampled_from(
    "R1 C1 L1 V1 I1 E1 G1 F1 H1 D1 S1 X1 Q1 K1 B1 .tran .ac .op .ic .param .model .options "
    ".subckt .ends .include .lib .endl .control .endc .global .print .save .title .end .func "
    "+ * ; .".split()
)


@st.composite
def random_lines(draw):
    lines = ["fuzz title"]
    for _ in range(draw(st.integers(0, 12))):
        head = draw(HEADS)
        lines.append(" ".join([head, *draw(st.lists(TOKENS, max_size=9))]))
    return "\n".join(lines) + "\n"


@given(random_lines())
@settings(FUZZ, max_examples=600)
def test_random_lines(text):
    run(text)


@st.composite
def subcircuit_graphs(draw):
    """Subcircuits calling each other at random (self calls and cycles included)."""
    count = draw(st.integers(1, 5))
    names = [f"s{i}" for i in range(count)]
    ports = {name: draw(st.integers(0, 3)) for name in names}
    # mostly right: the port count and parameters that resolve, so flatten gets to work
    usually = st.sampled_from([True, True, True, True, False])

    def connections(callee, pool):
        if callee in ports and draw(usually):
            return " ".join(draw(st.sampled_from(pool)) for _ in range(ports[callee]))
        return " ".join(draw(st.lists(st.sampled_from(pool), max_size=3)))

    out = ["hierarchy", ".param g=2"]
    for name in names:
        out.append(
            f".subckt {name} " + " ".join(f"p{k}" for k in range(ports[name])) + " params: r={g*1k}"
        )
        for j in range(draw(st.integers(0, 3))):
            callee = draw(st.sampled_from([*names, "missing"]))
            conns = connections(callee, ["p0", "p1", "p2", "i", "0"][: ports[name]] + ["i", "0"])
            param = draw(st.sampled_from(["r={r/2}", "", "r={q}", "q=1", "r=0"]))
            out.append(f"X{j} {conns} {callee} {param}")
        value = draw(st.sampled_from(["r", "1/r", "r*g", "zz"]))
        out.append(f"R{name} i 0 {{{value}}}")
        if draw(usually):  # sometimes the .ends is missing
            out.append(".ends")
    for j in range(draw(st.integers(1, 3))):
        callee = draw(st.sampled_from(names))
        out.append(f"Xtop{j} {connections(callee, ['a', 'b', '0'])} {callee}")
    out.append(".tran 1u 1m")
    return "\n".join(out) + "\n"


@given(subcircuit_graphs())
@settings(FUZZ, max_examples=400)
def test_subcircuit_graphs(text):
    run(text)


def test_recursion_is_reported_not_overflowed():
    text = "t\n.subckt a p\nXb p b\n.ends\n.subckt b p\nXa p a\n.ends\nX1 n a\n"
    try:
        flatten(parse_netlist(text))
    except NetlistError as error:
        assert "recursive subcircuit a -> b -> a" in error.message
    else:
        raise AssertionError("recursion not detected")
