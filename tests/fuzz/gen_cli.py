"""Fuzzed command lines: random and hostile options through every verb, run in-process.

Each case is one ``circuitsim`` command line run by :func:`~tests.fuzz.harness.cli_call` (the
domain is ``cli-<verb>``): a valid base command of the verb with one to three mutations
(``MUTATIONS``): an option's value replaced by a hostile one (NaN, infinities, 400-digit
numbers, empty, foreign digits, a NUL byte), an option added with a random value, an option
or positional argument dropped, an option repeated, a path replaced by a hostile path (missing,
a folder, ``/dev/null``, in a missing folder, 5,000 characters, a NUL byte, a file of the
other kind). The outcome must be an exit code with at most one ``error:`` line and no
traceback (the harness's ``classify_cli``).

Budgets keep every case short: the base commands run small models over fractions of a second,
``ode`` and ``simulate`` carry ``--max-steps``/``--max-wall-time`` (which a mutation may
change), and verbs whose valid runs are long (``reproduce``) are given only values that must
be refused.
"""

from __future__ import annotations

import atexit
import random
import shutil
import tempfile
from collections.abc import Callable, Iterator
from functools import cache
from pathlib import Path

from tests.fuzz.harness import Case, cli_call

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT / "tests" / "synthesis" / "models"
GOLDEN = ROOT / "tests" / "solver" / "golden"

HOSTILE_VALUES = [
    "nan", "NaN", "inf", "-inf", "-1", "0", "-0", "1e308", "1e309", "1e-320", "1" * 400,
    "1" * 5000, "", " ", "abc", "1,2", "1:2:3", "\uff11\uff10", "\u0661", "1e", "0x10",
    "--", "-h", "-", "=", "x=", "=1", "x=nan", "x=1e999", "\x00", "a\x00b", "\U0001f600",
    "99999999999999999999", "-99999999999999999999", "1e-300", "3", "0.5",
]  # fmt: skip

EXTRA_OPTIONS = [
    "--speed", "--freq", "--amplitude", "--param", "--tstop", "--y0", "--rtol", "--dt",
    "--swing", "--time-scale", "--range", "--switch-at", "--series", "--dialect", "--opamp",
    "--nonlinear", "--scaling", "--engine", "--kernel", "--probe", "--bracket", "--parameter",
    "--coeffs", "--model", "--max-steps", "--max-wall-time", "--values", "--window", "--jobs",
    "--max-nrmsd", "--tolerance", "--workers", "--flange", "--no-flange", "--json",
    "--eigenvalues", "--nosuch", "-o", "--csv", "--plot", "--netlist", "--out",
    "--write-netlist", "--raw", "--scale", "--states", "--forcing", "--ngspice-timeout",
    "--log", "--pair-tolerance", "--speed-range", "--knob", "--pot-series",
    "--schematic", "--opamp-lib", "--opamp-subckt", "--max-step", "--max-memory",
    "--analysis", "--state", "--region", "--fmin", "--fmax", "--points-per-decade", "--freqs",
    "--max-db", "--max-degrees",
]  # fmt: skip

PATH_OPTIONS = (
    "-o",
    "--csv",
    "--plot",
    "--netlist",
    "--out",
    "--model",
    "--write-netlist",
    "--raw",
    "--scale",
    "--states",
    "--schematic",
    "--opamp-lib",
)  # options whose value is a path: mutated with hostile paths


@cache
def work_folder() -> Path:
    """A private folder for outputs and hostile files, removed when the interpreter exits."""
    folder = Path(tempfile.mkdtemp(prefix="circuitsim-fuzz-cli-"))
    atexit.register(shutil.rmtree, folder, True)
    (folder / "a_folder").mkdir()
    (folder / "binary.toml").write_bytes(bytes(range(256)) * 8)
    (folder / "empty.cir").write_text("")
    (folder / "model_as_netlist.cir").write_text((MODELS / "gap_oscillator.toml").read_text())
    (folder / "netlist_as_model.toml").write_text((GOLDEN / "rc.cir").read_text())
    return folder


def hostile_paths() -> list[str]:
    folder = work_folder()
    return [
        str(folder / "missing.cir"), str(folder / "a_folder"), "/dev/null",
        str(folder / "no" / "such" / "folder" / "out.cir"), str(folder / ("x" * 5000)),
        str(folder / "nul\x00.cir"), str(folder / "binary.toml"), str(folder / "empty.cir"),
        str(folder / "model_as_netlist.cir"), str(folder / "netlist_as_model.toml"),
        str(folder / "out.unknownsuffix"), str(folder / "out.pgf"), "", "-", ".",
        str(folder / "out.png"), str(folder / "out.csv"),
    ]  # fmt: skip


MODEL_CHOICES = (
    "gap_oscillator.toml", "chua_diode.toml", "two_mass_stop.toml", None, "wheelset", "bogie",
)  # fmt: skip


def _model(rng: random.Random) -> list[str]:
    choice = rng.choice(MODEL_CHOICES)
    if choice is None:
        return []  # the built-in wheelset
    if choice.endswith(".toml"):
        return ["--model", str(MODELS / choice)]
    return ["--model", choice]  # a shipped model by name


def base_command(rng: random.Random, verb: str) -> list[str]:
    """A valid, short command line of ``verb`` (before mutation)."""
    out = work_folder()
    netlist = str(GOLDEN / rng.choice(["rc.cir", "rc.cir", "halfwave.cir"]))
    if verb == "ode":
        return ["ode", *_model(rng), "--tstop", "0.2", "--max-steps", "3000",
                "--max-wall-time", "2", "--csv", str(out / "o.csv")]  # fmt: skip
    if verb == "stability":
        extra = rng.choice([["--eigenvalues"], ["--eigenvalues", "--json"], ["--json"], []])
        return ["stability", *_model(rng), *extra]
    if verb == "generate":
        return ["generate", *_model(rng), "--tstop", "0.3", "-o", str(out / "g.cir")]
    if verb == "compare":
        return ["compare", "--model", str(MODELS / "chua_diode.toml"), "--tstop", "0.1",
                "--json"]  # fmt: skip
    if verb == "sweep":
        return ["sweep", "--param", "speed", "--values", "50,52", "--tstop", "0.05",
                "--jobs", "1", "--out", str(out / "sweep")]  # fmt: skip
    if verb == "reproduce":
        return ["reproduce", "--jobs", rng.choice(["0", "-1"]), "--out", str(out / "r")]
    if verb == "check":
        return ["check", netlist]
    if verb == "convert":
        return ["convert", netlist, "--dialect", rng.choice(["ltspice", "multisim"]),
                "-o", str(out / "c.cir")]  # fmt: skip
    if verb == "simulate":
        return ["simulate", netlist, "--max-steps", "2000", "--max-wall-time", "8",
                "--csv", str(out / "s.csv")]  # fmt: skip
    if verb == "tolerance":
        return ["tolerance", *_model(rng), "-n", "3", "--tstop", "0.05", "--jobs", "1",
                "--seed", "7", "--out", str(out / "tol")]  # fmt: skip
    if verb == "hunting":
        return ["hunting", "--speeds", "54:55:1", "--settle", "0.05", "--record", "0.05",
                rng.choice(["--no-circuit", "--flange"]), "--out", str(out / "hunt")]  # fmt: skip
    if verb == "frf":
        return ["frf", "--freq", "3", "--engine", "builtin", "--fmin", "1", "--fmax", "20",
                "--points-per-decade", "4", "--tstop", "0.5"]  # fmt: skip
    if verb == "stepped-sine":
        return ["stepped-sine", "--freqs", "2,3", "--settle", "0.05", "--record", "0.05",
                "--no-circuit", "--out", str(out / "steps")]  # fmt: skip
    raise ValueError(verb)


VERBS = ("ode", "stability", "generate", "compare", "sweep", "reproduce", "check", "convert",
         "simulate", "tolerance", "hunting", "frf", "stepped-sine")  # fmt: skip
"""Every verb of the command line (``circuitsim --help``)."""

# options whose valid values make a run long: a mutation gives them only refused values
LONG_RUNS = {"--tstop", "--values", "--window", "--max-steps", "--max-wall-time", "--workers",
             "--jobs", "--dt", "--freq", "--speed", "--time-scale", "-n", "--speeds",
             "--settle", "--record", "--max-step", "--max-memory", "--fmin", "--fmax",
             "--points-per-decade", "--freqs"}  # fmt: skip
REFUSED = ["nan", "inf", "-1", "0", "", "abc", "1" * 400, "\x00", "-inf", "1e-320:1:1"]


def _value_for(rng: random.Random, option: str, verb: str) -> str:
    if option in LONG_RUNS and verb in ("ode", "generate", "compare", "sweep", "reproduce",
                                        "simulate", "tolerance", "hunting", "frf",
                                        "stepped-sine"):  # fmt: skip
        return rng.choice(REFUSED)
    if option in PATH_OPTIONS:
        return rng.choice(hostile_paths())
    return rng.choice(HOSTILE_VALUES)


def replace_value(rng: random.Random, argv: list[str], verb: str) -> list[str]:
    """Give one option (or positional path) a hostile value."""
    spots = [i for i in range(1, len(argv)) if not argv[i].startswith("--") or argv[i] == "--"]
    if not spots:
        return argv
    i = rng.choice(spots)
    option = argv[i - 1] if argv[i - 1].startswith("-") else ""
    if option == "":  # a positional argument: a netlist path
        argv[i] = rng.choice(hostile_paths())
    else:
        argv[i] = _value_for(rng, option, verb)
    return argv


def add_option(rng: random.Random, argv: list[str], verb: str) -> list[str]:
    """Add an option (maybe unknown to the verb) with a hostile value."""
    option = rng.choice(EXTRA_OPTIONS)
    if option in ("--json", "--flange", "--no-flange", "--eigenvalues"):
        return [*argv, option]
    return [*argv, option, _value_for(rng, option, verb)]


def drop_argument(rng: random.Random, argv: list[str], verb: str) -> list[str]:
    """Drop one argument (a required option or its value, a positional path)."""
    if len(argv) > 1:
        del argv[rng.randrange(1, len(argv))]
    return argv


def repeat_option(rng: random.Random, argv: list[str], verb: str) -> list[str]:
    """Repeat one option with a hostile value (the last one wins, or appends)."""
    options = [i for i in range(1, len(argv) - 1) if argv[i].startswith("--")]
    if not options:
        return argv
    option = argv[rng.choice(options)]
    return [*argv, option, _value_for(rng, option, verb)]


def hostile_path(rng: random.Random, argv: list[str], verb: str) -> list[str]:
    """Point one path (model, netlist, output) somewhere hostile."""
    paths = [i for i, a in enumerate(argv) if "/" in a]
    if not paths:
        return [*argv, "--model", rng.choice(hostile_paths())] if verb in VERBS[:5] else argv
    argv[rng.choice(paths)] = rng.choice(hostile_paths())
    return argv


MUTATIONS: tuple[Callable[[random.Random, list[str], str], list[str]], ...] = (
    replace_value, replace_value, replace_value, add_option, add_option, drop_argument,
    repeat_option, hostile_path, hostile_path,
)  # fmt: skip


def cases(seed: int, count: int, verbs: tuple[str, ...] = VERBS) -> Iterator[Case]:
    """``count`` command lines, cycling through ``verbs``; the same seed gives the same ones."""
    rng = random.Random(seed)
    for index in range(count):
        verb = verbs[index % len(verbs)]
        argv = base_command(rng, verb)
        applied = []
        for _ in range(rng.choice((1, 1, 2, 3))):
            mutation = rng.choice(MUTATIONS)
            argv = mutation(rng, list(argv), verb)
            applied.append(mutation.__name__)
        if verb == "reproduce" and "--jobs" not in argv and "--workers" not in argv:
            # dropping the refused --jobs value left a valid reproduce: a full run of a minute
            # or more, which the time bound reads as a hang (seed 20261204, case 77)
            argv = [*argv, "--jobs", "0"]
        yield Case(
            f"cli-{verb}",
            f"{seed}-{index}-{verb}-{'+'.join(applied)}",
            "",
            cli_call(argv, work_folder()),
            argv=tuple(argv),
        )
