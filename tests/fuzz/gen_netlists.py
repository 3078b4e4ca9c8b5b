"""Fuzzed netlists: the corpus mutated, then read, checked, converted and simulated.

Each mutated netlist gives three cases, one per domain:

``netlist-check``
    read (:func:`~circuitsim.netlist.reader.parse_netlist`) and
    :func:`~circuitsim.netlist.topology.check_circuit`, what ``circuitsim check`` does;
``netlist-convert``
    read, write in every dialect, and read the ngspice text back (what ``convert`` does, plus
    the round trip that must hold for anything the reader accepted);
``netlist-simulate``
    read and run the builtin engine with a small step budget (:data:`MAX_STEPS`).

The seeds are the netlists of ``tests/netlist/corpus`` and ``tests/solver/golden``. The
mutations are the ones that broke readers before (``MUTATIONS``): token swaps, foreign digits,
huge numbers, deep nesting, long lines, ``.param`` chains, unknown cards, missing or looping
include files, text after ``.end``, control blocks, self-instantiating subcircuits ...
Included files resolve against a private copy of the corpus folder (:func:`include_folder`),
which also holds a file standing for a secret (its first line must never appear in a message).
"""

from __future__ import annotations

import atexit
import random
import re
import shutil
import tempfile
from collections.abc import Callable, Iterator
from functools import cache
from pathlib import Path

from tests.fuzz.harness import MAX_MESSAGE_CHARS, Case

ROOT = Path(__file__).resolve().parents[1]
SEED_FOLDERS = (ROOT / "netlist" / "corpus", ROOT / "solver" / "golden")
MAX_STEPS = 400
"""Step budget of the builtin engine per fuzzed netlist (a named error past it)."""
KERNEL = "python"
"""The builtin engine's loop for fuzzing: the reference loop. The compiled loops compile once
per cache and argument types (over a minute when the cache is cold), which the time bound
would count as hangs; they are checked against this loop by the solver's own tests."""

SECRET = "root:x:0:0:fuzz-secret-line:/root:/bin/bash"
"""First line of ``secret.txt`` in the include folder: no error message may show it."""


@cache
def seed_texts() -> tuple[tuple[str, str], ...]:
    """``(name, text)`` of every seed netlist, sorted by name."""
    texts = []
    for folder in SEED_FOLDERS:
        for path in sorted(folder.glob("*.cir")):
            texts.append((f"{folder.name}/{path.name}", path.read_text()))
    return tuple(texts)


@cache
def include_folder() -> str:
    """A private folder with the corpus's include files, a self-including file and a secret.

    Removed when the interpreter exits.
    """
    folder = Path(tempfile.mkdtemp(prefix="circuitsim-fuzz-"))
    atexit.register(shutil.rmtree, folder, True)
    for seed in SEED_FOLDERS:
        for path in seed.iterdir():
            if path.suffix in (".inc", ".lib", ".cir") and not (folder / path.name).exists():
                shutil.copy(path, folder / path.name)
    (folder / "secret.txt").write_text(SECRET + "\nsecond line\n")
    (folder / "loop.inc").write_text("* includes itself\n.include loop.inc\nRloop a 0 1k\n")
    (folder / "binary.inc").write_bytes(bytes(range(256)) * 4)
    return str(folder)


# --- mutations: each takes (rng, text) and returns a new text ------------------------------

NUMBER = re.compile(r"(?<![\w.])[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?[a-zA-Z]*")

NASTY_NUMBERS = [
    "1e999", "-1e999", "1e-999", "nan", "inf", "-inf", "9" * 400, "1" + "0" * 5000,
    "0." + "0" * 400 + "1", "1e308", "-1e308", "1e-320", "1e-30", "0", "-0", "1..2", "1.2.3",
    "4k7", "1meg1", "1e", "1e+", ".", "-", "e5", "{1/0}", "{}", "{(}", "{1e308*10}",
    "{sqrt(-1)}", "{log(0)}", "{undefined_name}", "{min(1)}", "{max(2)}", "{min()}",
    "{max(1,2,3)}", "{pow(2)}", "{if(1)}", "'a*'", "{1?2:3}", "{-1e308-1e308}",
    "\uff11\uff10",  # fullwidth "10"
    "\u0661\u0660",  # Arabic-Indic "10"
    "\u00b9", "\u2155", "\U0001d7e3", "1\u00b5", "1\u03bc", "1\u2212", "\u22121",
]

NASTY_TOKENS = [
    "\u212a", "k", "K", "\u0130", "\u00df", "\u0000", "\ufeff", "\u200b", "\t", "\\", "+", "=",
    "(", ")", "{", "}", ",", ";", "$", "*", "0", "gnd", "GND", "n\u00e9", "\U0001f600",
    ".end", ".ends", ".endc", ".control", "shell", "'", '"',
]

UNKNOWN_CARDS = [
    ".foo bar", ".probe v(a)", ".nodeset v(a)=1", ".ic v(b)=0.5", ".save all", ".meas tran x",
    ".global a", ".temp 27", ".four 1k v(a)", ".func f(x) {x*2}", ".csparam a=1", ".option",
    ".options reltol=-1", ".options method=euler", ".options maxord=9", ".options gmin=nan",
    ".ac dec 10 1 1k", ".dc v1 0 1 0.1", ".noise v(a) v1 dec 10 1 1k", ".op", ".tran 0 0",
    ".tran -1 1", ".tran 1u 1e9", ".tran 1e-30 1", ".tran 1u 1m 2m", ".subckt", ".ends",
    ".model", ".model m sw vt=1 vh=-0.5", ".model d1 d(is=-1)", ".model x nosuchkind",
    "Q1 a b c qmod", "M1 a b c d nmos", "Z1 a b zz", "J1 a b c jf", "Y1 a b", "T1 a 0 b 0 z0=50",
    "Xnosuch a b nosub", "W1 a 0 vx wmod", "B1 a 0 v={v(a)*2}", "A1 a b amod",
    "R1", "R1 a", "R1 a b", "C1 a b", "L1 a b 0", "V1 a", "I1 a 0 pulse(", "V1 a 0 sin(0 1)",
    "E1 a 0 b", "G1 a 0 b 0", "F1 a 0 vnone 2", "H1 a 0 vnone 2", "S1 a 0 b 0",
    "V9 a 0 pulse(0 1 -1m -1u -1u 1m 2m)", "V9 a 0 pwl(0 0 -1 1 1 2)", "V9 a 0 pwl(1 0 0 1)",
    "R9 a 0 1e-30", "R9 a 0 -1k", "C9 a 0 -1u", "L9 a 0 0", "D9 a 0 nomodel",
]

INCLUDES = [
    ".include nosuch.inc", ".include /nonexistent/dir/x.inc", ".include loop.inc",
    ".include secret.txt", ".include binary.inc", ".include .", ".include",
    ".lib sections.lib nosuchsection", ".lib nosuch.lib typ", ".include /etc/passwd",
    '.include "parts.inc', ".include\tparts.inc", ".lib\tsections.lib\ttyp",
]


def _lines(text: str) -> list[str]:
    return text.splitlines()


def _body_index(rng: random.Random, lines: list[str]) -> int:
    """A random line index after the title line (the first line is always a title)."""
    return rng.randrange(1, len(lines)) if len(lines) > 1 else len(lines)


def token_swap(rng: random.Random, text: str) -> str:
    """Swap two tokens, on one line or across two lines."""
    lines = _lines(text)
    if len(lines) < 2:
        return text
    i, j = _body_index(rng, lines), _body_index(rng, lines)
    ti, tj = lines[i].split(), lines[j].split()
    if not ti or not tj:
        return text
    a, b = rng.randrange(len(ti)), rng.randrange(len(tj))
    if i == j:
        ti[a], ti[b] = ti[b], ti[a]
        lines[i] = " ".join(ti)
    else:
        ti[a], tj[b] = tj[b], ti[a]
        lines[i], lines[j] = " ".join(ti), " ".join(tj)
    return "\n".join(lines) + "\n"


def nasty_number(rng: random.Random, text: str) -> str:
    """Replace one number of the text by a hostile one."""
    matches = list(NUMBER.finditer(text, text.find("\n") + 1))
    if not matches:
        return text
    m = rng.choice(matches)
    return text[: m.start()] + rng.choice(NASTY_NUMBERS) + text[m.end() :]


def foreign_digits(rng: random.Random, text: str) -> str:
    """Replace every ASCII digit of one line by a digit of another script."""
    lines = _lines(text)
    i = _body_index(rng, lines)
    if i >= len(lines):
        return text
    zero = rng.choice([0xFF10, 0x0660, 0x06F0, 0x0966, 0x1D7CE, 0x2070])
    lines[i] = "".join(chr(zero + int(c)) if c.isascii() and c.isdigit() else c for c in lines[i])
    return "\n".join(lines) + "\n"


def nasty_token(rng: random.Random, text: str) -> str:
    """Insert, or replace a token by, a hostile one (Kelvin sign, NUL, BOM, control words)."""
    lines = _lines(text)
    i = _body_index(rng, lines)
    if i >= len(lines):
        return text
    tokens = lines[i].split() or [""]
    k = rng.randrange(len(tokens))
    token = rng.choice(NASTY_TOKENS)
    if rng.random() < 0.5:
        tokens[k] = token
    else:
        tokens[k] = tokens[k] + token if rng.random() < 0.5 else token + tokens[k]
    lines[i] = " ".join(tokens)
    return "\n".join(lines) + "\n"


def deep_nesting(rng: random.Random, text: str) -> str:
    """Replace a number by a deeply nested expression (parentheses, signs or sums)."""
    depth = rng.choice([50, 300, 1200, 3000])
    shape = rng.choice(["paren", "minus", "sum", "brace", "call"])
    nested = {
        "paren": "{" + "(" * depth + "1" + ")" * depth + "}",
        "minus": "{" + "-" * depth + "1}",
        "sum": "{" + "+".join(["1"] * depth) + "}",
        "brace": "{" * depth + "1" + "}" * depth,
        "call": "{" + "abs(" * depth + "1" + ")" * depth + "}",
    }[shape]
    matches = list(NUMBER.finditer(text, text.find("\n") + 1))
    if not matches:
        return text
    m = rng.choice(matches)
    return text[: m.start()] + nested + text[m.end() :]


def long_line(rng: random.Random, text: str) -> str:
    """Make one line very long: a long token, many tokens, or a long comment."""
    lines = _lines(text)
    i = _body_index(rng, lines)
    size = rng.choice([5_000, 100_000, 1_000_000])
    kind = rng.choice(["token", "tokens", "comment", "continuation"])
    if kind == "token":
        addition = " " + "x" * size
    elif kind == "tokens":
        addition = " a" * (size // 2)
    elif kind == "comment":
        addition = " ; " + "c" * size
    else:
        lines.insert(i, "+ 1" * min(size // 3, 20_000))
        return "\n".join(lines) + "\n"
    if i < len(lines):
        lines[i] += addition
    else:
        lines.append("R" + addition)
    return "\n".join(lines) + "\n"


def param_chain(rng: random.Random, text: str) -> str:
    """Prepend a chain of ``.param`` lines each using the one before (or all before)."""
    n = rng.choice([10, 500, 3000])
    kind = rng.choice(["chain", "fan", "cycle", "function-name"])
    if kind == "chain":
        params = [".param p0=1"] + [f".param p{k}={{p{k - 1}+1}}" for k in range(1, n)]
    elif kind == "fan":
        params = [f".param q{k}={{{rng.randrange(1, 9)}*2}}" for k in range(n)]
        params.append(".param qs={" + "+".join(f"q{k}" for k in range(min(n, 400))) + "}")
    elif kind == "cycle":
        params = [".param a1={a2}", ".param a2={a3}", ".param a3={a1}", "R99 a 0 {a1}"]
    else:
        params = [f".param {rng.choice(['sqrt', 'min', 'max', 'exp', 'abs', 'pi', 'if'])}=2"]
    lines = _lines(text)
    return "\n".join(lines[:1] + params + lines[1:]) + "\n"


def unknown_card(rng: random.Random, text: str) -> str:
    """Insert an unusual, unknown or malformed card."""
    lines = _lines(text)
    lines.insert(_body_index(rng, lines), rng.choice(UNKNOWN_CARDS))
    return "\n".join(lines) + "\n"


def include_card(rng: random.Random, text: str) -> str:
    """Insert an include of a missing, looping, binary or secret file."""
    lines = _lines(text)
    lines.insert(_body_index(rng, lines), rng.choice(INCLUDES))
    return "\n".join(lines) + "\n"


def after_end(rng: random.Random, text: str) -> str:
    """Put cards after ``.end`` (ngspice ignores them) or drop ``.end``."""
    tail = rng.choice([
        "R77 a 0 1", "V77 a 0 5", ".control\nshell echo pwned\n.endc", ".end", "garbage (",
        ".tran 1n 1n",
    ])
    lines = [ln for ln in _lines(text) if ln.strip().lower() != ".end"]
    if rng.random() < 0.2:
        return "\n".join(lines) + "\n"
    return "\n".join([*lines, ".end", tail]) + "\n"


def control_block(rng: random.Random, text: str) -> str:
    """Insert a control block in one of the spellings ngspice matches by prefix."""
    opener, closer = rng.choice([
        (".control", ".endc"), (".control;x", ".endc;x"), (".controls", ".endcs"),
        (".CONTROL", ".ENDC"), (".control", ""), ("", ".endc"),
    ])
    lines = _lines(text)
    lines.insert(_body_index(rng, lines), f"{opener}\nshell echo pwned\n{closer}")
    return "\n".join(lines) + "\n"


def tabs(rng: random.Random, text: str) -> str:
    """Replace the spaces of some lines by tabs (ngspice separates fields by any blank)."""
    lines = _lines(text)
    for _ in range(rng.randrange(1, 4)):
        i = _body_index(rng, lines)
        if i < len(lines):
            lines[i] = lines[i].replace(" ", rng.choice(["\t", " \t", "\t\t"]))
    return "\n".join(lines) + "\n"


def recursive_subcircuit(rng: random.Random, text: str) -> str:
    """Add a subcircuit that instantiates itself (directly or through another one)."""
    if rng.random() < 0.5:
        block = ".subckt selfie a b\nXin a b selfie\nR1 a b 1k\n.ends\nXtop 1 0 selfie"
    else:
        block = (".subckt ping a b\nXp a b pong\n.ends\n.subckt pong a b\nXq a b ping\n.ends\n"
                 "Xtop 1 0 ping")
    lines = _lines(text)
    lines.insert(_body_index(rng, lines), block)
    return "\n".join(lines) + "\n"


def delete_or_duplicate(rng: random.Random, text: str) -> str:
    """Delete, duplicate or truncate a line, or cut the text at a random character."""
    lines = _lines(text)
    i = _body_index(rng, lines)
    if i >= len(lines):
        return text
    action = rng.choice(["delete", "duplicate", "truncate", "cut"])
    if action == "delete":
        del lines[i]
    elif action == "duplicate":
        lines.insert(i, lines[i])
    elif action == "truncate":
        lines[i] = lines[i][: rng.randrange(len(lines[i]) + 1)]
    else:
        return text[: rng.randrange(len(text) + 1)]
    return "\n".join(lines) + "\n"


def random_bytes(rng: random.Random, text: str) -> str:
    """Insert a few random characters (printable, control or non-ASCII) at random places."""
    chars = list(text)
    pool = "(){}=,+*;$'\".\t\\:!?@#%&|<>^~-_0123456789eEkKmMuUgGxX \x00\u00b5\u2013\n\r\x0c"
    for _ in range(rng.randrange(1, 6)):
        chars.insert(rng.randrange(len(chars) + 1), rng.choice(pool))
    return "".join(chars)


def case_change(rng: random.Random, text: str) -> str:
    """Change the case of the whole text or of one line (SPICE is case-insensitive)."""
    if rng.random() < 0.5:
        return text.upper() if rng.random() < 0.5 else text.lower()
    lines = _lines(text)
    i = _body_index(rng, lines)
    if i < len(lines):
        lines[i] = lines[i].swapcase()
    return "\n".join(lines) + "\n"


MUTATIONS: tuple[Callable[[random.Random, str], str], ...] = (
    token_swap, nasty_number, foreign_digits, nasty_token, deep_nesting, long_line,
    param_chain, unknown_card, include_card, after_end, control_block, tabs,
    recursive_subcircuit, delete_or_duplicate, random_bytes, case_change,
)


def mutate(rng: random.Random, text: str) -> tuple[str, str]:
    """Apply one to three random mutations; returns the new text and the mutation names."""
    names = []
    for _ in range(rng.choice([1, 1, 1, 2, 3])):
        mutation = rng.choice(MUTATIONS)
        text = mutation(rng, text)
        names.append(mutation.__name__)
    return text, "+".join(names)


# --- what each domain runs ----------------------------------------------------------------

def read(text: str):
    """Read ``text`` as the file ``fuzz.cir`` in the include folder."""
    from circuitsim.netlist.reader import parse_netlist

    return parse_netlist(text, source="fuzz.cir", base_dir=include_folder())


def check(text: str) -> object:
    """What ``circuitsim check`` does: read and list the findings."""
    from circuitsim.netlist.topology import check_circuit

    return check_circuit(read(text))


def convert(text: str) -> object:
    """What ``circuitsim convert`` does in every dialect; the ngspice output must read back."""
    from circuitsim.netlist.reader import parse_netlist
    from circuitsim.netlist.writer import write_netlist

    circuit = read(text)
    outputs = {d: write_netlist(circuit, d) for d in ("ngspice", "ltspice", "multisim")}
    parse_netlist(outputs["ngspice"], source="converted.cir", base_dir=include_folder())
    return outputs


def simulate(text: str) -> object:
    """The builtin engine on the netlist, with a step budget of :data:`MAX_STEPS`."""
    from circuitsim.solver import SimulationOptions
    from circuitsim.solver import simulate as run

    circuit = shortened(read(text))
    options = SimulationOptions.from_circuit(circuit, max_steps=MAX_STEPS, kernel=KERNEL)
    return run(circuit, options)


def shortened(circuit):
    """``circuit`` with its ``.tran`` cut to 100 of its steps: the budget then exercises the
    circuit rather than ending most runs at the step limit."""
    import dataclasses

    from circuitsim.netlist.circuit import Transient

    analyses = []
    for analysis in circuit.analyses:
        if isinstance(analysis, Transient):
            tstop = min(analysis.tstop, analysis.tstart + 100 * analysis.tstep)
            if tstop > analysis.tstart:
                analysis = dataclasses.replace(analysis, tstop=tstop)
        analyses.append(analysis)
    return dataclasses.replace(circuit, analyses=analyses)


DOMAINS: dict[str, Callable[[str], object]] = {
    "netlist-check": check,
    "netlist-convert": convert,
    "netlist-simulate": simulate,
}


class LeakyMessage(AssertionError):
    """A named error whose message shows the secret file's content or is too long."""


def guarded(call: Callable[[str], object]) -> Callable[[str], object]:
    """``call`` with the check that a NetlistError's message is short and keeps the secret."""
    from circuitsim.netlist.errors import NetlistError

    def run(text: str) -> object:
        try:
            return call(text)
        except NetlistError as error:
            message = str(error)
            if "fuzz-secret-line" in message or len(message) > MAX_MESSAGE_CHARS:
                raise LeakyMessage(f"{len(message)} characters: {message[:300]}") from error
            raise

    return run


def mutated_texts(seed: int, count: int) -> Iterator[tuple[str, str]]:
    """``count`` mutated netlists ``(name, text)`` for ``seed`` (the same on every run)."""
    rng = random.Random(seed)
    seeds = seed_texts()
    for k in range(count):
        origin, text = seeds[rng.randrange(len(seeds))]
        text, how = mutate(rng, text)
        yield f"netlist seed={seed} #{k} {origin} {how}", text


def cases(seed: int, count: int) -> Iterator[Case]:
    """``count`` cases (a third of them per domain) from ``count // 3`` mutated netlists."""
    calls = {domain: guarded(call) for domain, call in DOMAINS.items()}
    for name, text in mutated_texts(seed, max(1, count // len(DOMAINS))):
        for domain, call in calls.items():
            yield Case(domain, name, text, lambda call=call, text=text: call(text))
