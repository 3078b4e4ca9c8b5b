"""Runs whose recorded size is large: fine output steps, long stops, many nodes, each with a
memory budget (``--max-memory``), through ``circuitsim simulate`` on both engines.

Each case is a netlist (an RC ladder of 2 to 200 nodes, or the committed TL074 wheelset) with
a ``.tran`` whose step and stop are drawn so that the recorded table ranges from kilobytes to
far past any machine's memory, run with a budget of 8 MiB to 1 GiB. The outcome must be a run
that fits (``clean``), or a named refusal before the run or a named stop while recording
(``named``, exit 3): never an out-of-memory kill, and never a process that grows far past
its budget (the campaign's log records the peak resident memory after every case).
"""

from __future__ import annotations

import atexit
import random
import shutil
import tempfile
from collections.abc import Iterator
from functools import cache
from pathlib import Path

from tests.fuzz.harness import Case, cli_call

ROOT = Path(__file__).resolve().parents[2]
WHEELSET = ROOT / "netlists" / "wheelset_flange_tl074_ngspice.cir"
BUDGETS = ("8M", "32M", "64M", "256M", "1G")


@cache
def work_folder() -> Path:
    """A private folder for the netlists and outputs, removed when the interpreter exits."""
    folder = Path(tempfile.mkdtemp(prefix="circuitsim-fuzz-memory-"))
    atexit.register(shutil.rmtree, folder, True)
    return folder


def ladder(nodes: int, tstep: float, tstop: float) -> str:
    """An RC ladder driven by a sine: ``nodes`` nodes of 1 kOhm and 1 uF each."""
    lines = [f"rc ladder of {nodes}", "V1 n0 0 SIN(0 1 50)"]
    for k in range(1, nodes + 1):
        lines += [f"R{k} n{k - 1} n{k} 1k", f"C{k} n{k} 0 1u"]
    lines += [f".tran {tstep:g} {tstop:g} 0 {tstep:g}", ".end"]
    return "\n".join(lines) + "\n"


def wheelset(tstep: float, tstop: float) -> str:
    """The TL074 wheelset with its ``.tran`` replaced."""
    text = WHEELSET.read_text().splitlines()
    out = [f".tran {tstep:g} {tstop:g} 0 {tstep:g} uic" if t.startswith(".tran") else t
           for t in text]  # fmt: skip
    return "\n".join(out) + "\n"


def cases(seed: int, count: int) -> Iterator[Case]:
    """``count`` sized runs of ``seed``."""
    rng = random.Random(seed)
    folder = work_folder()
    for k in range(count):
        tstop = 10 ** rng.uniform(-3, 3)
        tstep = tstop / 10 ** rng.uniform(2, 9)
        if rng.random() < 0.2:
            text, what = wheelset(tstep, tstop), "wheelset"
        else:
            nodes = rng.choice([2, 10, 50, 200])
            text, what = ladder(nodes, tstep, tstop), f"ladder{nodes}"
        path = folder / f"m{k}.cir"
        path.write_text(text)
        engine = "ngspice" if rng.random() < 0.2 else "builtin"
        budget = rng.choice(BUDGETS)
        argv = ["simulate", str(path), "--engine", engine, "--max-memory", budget,
                "--max-wall-time", "20", "--ngspice-timeout", "20",
                "--csv", str(folder / "out.csv")]  # fmt: skip
        name = f"seed{seed}-{k}-{what}-{engine}-{budget}-tstep{tstep:.2g}-tstop{tstop:.2g}"
        yield Case("memory", name, text[:2000], cli_call(argv, folder), argv)
