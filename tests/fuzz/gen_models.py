"""Fuzzed model files: the shipped and test models mutated, then loaded, solved, analysed and
translated.

Each mutated file gives up to four cases, one per domain:

``model-load``
    :func:`~circuitsim.mechanics.load_model` (reads, checks and evaluates every coefficient
    set: what every verb does first);
``model-ode``
    load, then :func:`~circuitsim.mechanics.solve` over at most 1 model second with a small
    step and wall-time budget (:data:`MAX_STEPS`, :data:`MAX_WALL_TIME`): a limit is a named
    error, never a hang;
``model-stability``
    load, then the modes of the linear part (:func:`~circuitsim.mechanics.stability.modes`);
``model-generate``
    load, then :func:`~circuitsim.synthesis.synthesize` over a short run (:data:`T_STOP`).

The seeds are ``circuitsim/mechanics/models/*.toml`` and ``tests/synthesis/models/*.toml``. The
mutations (``MUTATIONS``) are the ones the reliability probe of issue 21 used and their
relatives: hostile numbers (huge, denormal, 401 and 5,000 digits, inf, nan), hostile expressions
(1,500-term sums, 1,200 parentheses, 1,500 signs, unknown names and functions, domain errors),
extreme frequencies and amplitudes, deleted, duplicated and swapped lines, renamed keys and
tables, truncation, foreign characters, grown or shrunk name lists.
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

from tests.fuzz.harness import Case

ROOT = Path(__file__).resolve().parents[2]
SEED_FOLDERS = (
    ROOT / "circuitsim" / "mechanics" / "models",
    ROOT / "tests" / "synthesis" / "models",
)

MAX_STEPS = 3_000
"""Step budget of the direct solution per fuzzed model (an IntegrationLimitError past it)."""

MAX_WALL_TIME = 3.0
"""Wall-time budget of the direct solution per fuzzed model, s."""

T_STOP = 0.5
"""Model seconds of the translator's scaling run per fuzzed model."""

DOMAINS = ("model-load", "model-ode", "model-stability", "model-generate")


@cache
def seed_texts() -> tuple[tuple[str, str], ...]:
    """``(name, text)`` of every seed model file, sorted by name."""
    texts = []
    for folder in SEED_FOLDERS:
        for path in sorted(folder.glob("*.toml")):
            texts.append((f"{folder.name}/{path.name}", path.read_text()))
    return tuple(texts)


@cache
def work_folder() -> Path:
    """A private folder for the mutated files, removed when the interpreter exits."""
    folder = Path(tempfile.mkdtemp(prefix="circuitsim-fuzz-models-"))
    atexit.register(shutil.rmtree, folder, True)
    return folder


# --- mutations: each takes (rng, text) and returns a new text ------------------------------

NUMBER = re.compile(r"(?<![\w.\"])[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?(?![\w\"])")
STRING = re.compile(r'"[^"\n]*"')

NASTY_NUMBERS = [
    "0", "-0.0", "1e308", "-1e308", "1.7976931348623157e308", "1e-320", "-1e-320", "5e-324",
    "1e-300", "1e300", "inf", "-inf", "nan", "1" * 401, "1" * 5000, "-" + "9" * 30,
    "0x10", "1_000", "1e", "1..2", "true", '"1/0"', "[]", "{}",
]  # fmt: skip

NASTY_EXPRESSIONS = [
    "+".join(["1"] * 1500),
    "(" * 1200 + "1" + ")" * 1200,
    "-" * 1500 + "1",
    "sqrt(" * 400 + "1" + ")" * 400,
    "2" + "**2" * 400,
    "1/0", "0/0", "sqrt(-1)", "log(0)", "log(-1)", "exp(1000)", "1e308*10", "10**400",
    "(-8)**(1/3)", "tan(pi/2)", "atan(1e308)", "min(1)", "max(1, 2, 3)", "abs()",
    "nosuchname", "nosuch(1)", "pi(1)", "sqrt", "1 +", "* 2", "2 ^ 3", "(1", "1)",
    "1e999", "1" * 5000, "\uff11\uff10", "\u0661", "x\u200b", "", " ", "\u0000",
    "1" + "+1" * 299, "a" * 10000,
]  # fmt: skip

TABLE_HEADERS = [
    "[model]", "[coordinates]", "[states]", "[parameters]", "[options]", "[coefficients]",
    "[matrices]", "[nonlinear.x]", "[forcing.x]", "[initial]", "[circuit]", "[circuit.speed]",
    "[[nonlinear]]", "[extra]", "[model.model]", "[]", "[", "[parameters.k]",
]  # fmt: skip

LINES = [
    'kind = "first_order"', 'kind = "second_order"', 'kind = "third_order"', "kind = 1",
    'names = []', 'names = ["x", "x"]', 'names = ["x", "1y"]', 'names = ["pi"]',
    'names = ["' + "s" * 5000 + '"]', 'units = ["m"]', "units = []", 'time_unit = ""',
    'time_unit = "1"', "time_unit = 5", "t_stop = 0", "t_stop = -1", "t_stop = 1e300",
    "t_stop = 1e-300", "t_stop = nan", 't_stop = "5"', "time_scale = 0", "time_scale = 1e300",
    "time_scale = 1e-300", 'frequency = "1e9"', "frequency = 1e300", "frequency = -5",
    "amplitude = 0", "amplitude = 1e300", 'A = [["-1e-320"]]', "A = [[0]]", "M = [[0]]",
    'M = [["1e-300"]]', 'K = [["1e300"]]', "enters = {}", "enters = []", "abs = []",
    'abs = [{ gain = 0, row = [1], offset = 0 }]', "abs = [{}]", "abs = 5", "t_on = -1",
    "t_on = 1e300", "t_on = nan", 'default = "nosuch"', "a = " + "[" * 3000 + "]" * 3000,
    "a = " + "{b=" * 2000 + "1" + "}" * 2000, "enabled = false", "enabled = 1",
    "speed = { parameter = \"nosuch\" }", 'integrators = { nosuch = "U9" }',
]  # fmt: skip


def _lines(text: str) -> list[str]:
    return text.splitlines()


def replace_number(rng: random.Random, text: str) -> str:
    """Replace one number (outside strings) by a hostile one."""
    found = list(NUMBER.finditer(text))
    if not found:
        return text
    match = rng.choice(found)
    return text[: match.start()] + rng.choice(NASTY_NUMBERS) + text[match.end() :]


def scale_number(rng: random.Random, text: str) -> str:
    """Multiply one number by a power of ten (or negate it): the file stays valid, the model
    becomes stiff, unstable, tiny or huge, which is what the solver and translator must face."""
    found = list(NUMBER.finditer(text))
    if not found:
        return text
    match = rng.choice(found)
    try:
        value = float(match.group(0))
    except ValueError:
        return text
    factor = rng.choice([-1.0, 0.0, 10.0 ** rng.randint(-15, 15), -(10.0 ** rng.randint(-8, 8))])
    return text[: match.start()] + repr(value * factor) + text[match.end() :]


def replace_string(rng: random.Random, text: str) -> str:
    """Replace one quoted string (an expression, a name or a unit) by a hostile expression."""
    found = list(STRING.finditer(text))
    if not found:
        return text
    match = rng.choice(found)
    value = rng.choice(NASTY_EXPRESSIONS).replace("\\", "\\\\").replace('"', '\\"')
    return text[: match.start()] + f'"{value}"' + text[match.end() :]


def delete_line(rng: random.Random, text: str) -> str:
    """Drop one line (a missing key, table or bracket)."""
    lines = _lines(text)
    if lines:
        del lines[rng.randrange(len(lines))]
    return "\n".join(lines) + "\n"


def duplicate_line(rng: random.Random, text: str) -> str:
    """Repeat one line (a duplicate key is a TOML error; a duplicate table too)."""
    lines = _lines(text)
    if lines:
        i = rng.randrange(len(lines))
        lines.insert(i, lines[i])
    return "\n".join(lines) + "\n"


def swap_lines(rng: random.Random, text: str) -> str:
    """Exchange two lines (keys move to other tables)."""
    lines = _lines(text)
    if len(lines) > 1:
        i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
    return "\n".join(lines) + "\n"


def insert_line(rng: random.Random, text: str) -> str:
    """Insert a hostile line or table header somewhere."""
    lines = _lines(text)
    extra = rng.choice(LINES + TABLE_HEADERS)
    lines.insert(rng.randrange(len(lines) + 1), extra)
    return "\n".join(lines) + "\n"


def rename_key(rng: random.Random, text: str) -> str:
    """Misspell the key of one ``key = value`` line."""
    lines = _lines(text)
    keyed = [i for i, line in enumerate(lines) if re.match(r"\s*[A-Za-z_]\w*\s*=", line)]
    if not keyed:
        return text
    i = rng.choice(keyed)
    key = lines[i].split("=", 1)[0].strip()
    new = rng.choice([key + "x", key.upper(), "_" + key, key[:-1] or "k", "pi", "sqrt"])
    lines[i] = lines[i].replace(key, new, 1)
    return "\n".join(lines) + "\n"


def truncate(rng: random.Random, text: str) -> str:
    """Cut the file at a random character."""
    return text[: rng.randrange(len(text) + 1)]


def foreign_characters(rng: random.Random, text: str) -> str:
    """Insert a character TOML or the expression reader may trip on."""
    at = rng.randrange(len(text) + 1)
    char = rng.choice(["\u0000", "\ufeff", "\u200b", "\u212a", "\U0001f600", "\\", '"', "\r",
                       "\x7f", "\udcff", "#", "=", "[", "]", "{", "}", "'''", '"""'])  # fmt: skip
    return text[:at] + char + text[at:]


def grow_names(rng: random.Random, text: str) -> str:
    """Add or remove a name in a ``names = [...]`` list (matrices no longer match)."""
    match = re.search(r"names\s*=\s*\[([^\]]*)\]", text)
    if not match:
        return text
    names = [n.strip() for n in match.group(1).split(",") if n.strip()]
    if names and rng.random() < 0.5:
        names.pop()
    else:
        names.append(f'"extra{rng.randrange(100)}"')
    return text[: match.start(1)] + ", ".join(names) + text[match.end(1) :]


def flip_kind(rng: random.Random, text: str) -> str:
    """Swap first and second order (the tables no longer fit the kind)."""
    if "second_order" in text:
        return text.replace('"second_order"', '"first_order"', 1)
    return text.replace('"first_order"', '"second_order"', 1)


MUTATIONS: tuple[Callable[[random.Random, str], str], ...] = (
    scale_number, scale_number, scale_number, scale_number, scale_number, scale_number,
    replace_number, replace_number, replace_string, replace_string, delete_line,
    duplicate_line, swap_lines, insert_line, insert_line, rename_key, truncate,
    foreign_characters, grow_names, flip_kind,
)  # fmt: skip


def mutate(rng: random.Random, text: str) -> tuple[str, str]:
    """``text`` with one to three mutations; returns ``(mutated, description)``."""
    applied = []
    for _ in range(rng.choice((1, 1, 1, 2, 3))):
        mutation = rng.choice(MUTATIONS)
        text = mutation(rng, text)
        applied.append(mutation.__name__)
    return text, "+".join(applied)


# --- what each domain does with a mutated file -----------------------------------------------


def _load(path: Path):
    from circuitsim.mechanics import load_model

    return load_model(path)


def _ode(path: Path):
    from circuitsim.mechanics import solve

    model = _load(path)
    system = model.system()
    t_stop = min(1.0, float(model.circuit.get("t_stop", 1.0)))
    return solve(
        system, (0.0, t_stop), rtol=1e-8, atol=1e-10, max_steps=MAX_STEPS,
        max_wall_time=MAX_WALL_TIME,
    )  # fmt: skip


def _stability(path: Path):
    from circuitsim.mechanics.stability import modes

    return modes(_load(path))


def _generate(path: Path):
    from circuitsim.synthesis import synthesize
    from circuitsim.synthesis.options import SynthesisOptions

    options = SynthesisOptions(t_stop=T_STOP, scaling_wall_time=MAX_WALL_TIME)
    return synthesize(_load(path).system(), options)


ACTIONS: dict[str, Callable[[Path], object]] = {
    "model-load": _load,
    "model-ode": _ode,
    "model-stability": _stability,
    "model-generate": _generate,
}


def _write(name: str, text: str) -> Path:
    path = work_folder() / f"{name}.toml"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    return path


def cases(seed: int, count: int, domains: tuple[str, ...] = DOMAINS) -> Iterator[Case]:
    """``count`` cases from mutated model files, cycling through ``domains``.

    The same ``seed`` gives the same files and cases. Each case writes its file when run.
    """
    rng = random.Random(seed)
    seeds = seed_texts()
    for index in range(count):
        seed_name, text = seeds[rng.randrange(len(seeds))]
        mutated, applied = mutate(rng, text)
        domain = domains[index % len(domains)]
        name = f"{seed}-{index}-{Path(seed_name).stem}-{applied}"
        action = ACTIONS[domain]

        def run(name=name, mutated=mutated, action=action):
            return action(_write(name, mutated))

        yield Case(domain, name, mutated, run)
