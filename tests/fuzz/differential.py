"""Differential fuzz: mutated netlists that both engines accept, run by both, compared.

Usage (from the repository root; needs ngspice)::

    python -m tests.fuzz.differential --seed 7 --count 400

Each mutated netlist (``gen_netlists.mutate`` with gentler value and node mutations added,
so that more of them stay valid) is read by our reader; the ones it accepts are run by the
builtin engine (default kernel, a step limit and a time bound) and by ngspice
(:func:`circuitsim.interop.ngspice.run_ngspice`, in its sandbox). When both return, every
top-level node voltage (no ``.`` in the name: subcircuit internals are left out) is compared
on ngspice's time points: the largest difference over the run, divided by the range of
ngspice's trace (or its magnitude for an operating point), above 5 % is a difference. Prints
counts and each difference with its mutation, for docs/reliability.md.
"""

from __future__ import annotations

import argparse
import faulthandler
import random
import signal
import sys
import warnings
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from tests.fuzz import gen_netlists  # noqa: E402
from tests.fuzz.harness import CaseTimeout, time_bound  # noqa: E402

THRESHOLD = 0.05
"""A node differs when max |ours - ngspice| > THRESHOLD * range of ngspice's trace."""


def scale_value(rng: random.Random, text: str) -> str:
    """Multiply one number (outside the title) by a power of ten from 1e-3 to 1e3, or negate it."""
    matches = list(gen_netlists.NUMBER.finditer(text, text.find("\n") + 1))
    if not matches:
        return text
    m = rng.choice(matches)
    factor = rng.choice(["*1e-3", "*1e-1", "*10", "*1e3", "*-1"])
    replacement = "{" + m.group(0) + factor + "}" if m.group(0)[-1:].isdigit() else m.group(0)
    return text[: m.start()] + replacement + text[m.end() :]


def swap_nodes(rng: random.Random, text: str) -> str:
    """Swap the two nodes of one two-terminal element line (R, C, L, V, I, D)."""
    lines = text.splitlines()
    candidates = [i for i, ln in enumerate(lines[1:], 1) if ln[:1].upper() in "RCLVID"]
    if not candidates:
        return text
    i = rng.choice(candidates)
    words = lines[i].split()
    if len(words) >= 3:
        words[1], words[2] = words[2], words[1]
        lines[i] = " ".join(words)
    return "\n".join(lines) + "\n"


GENTLE = (scale_value, swap_nodes, gen_netlists.tabs, gen_netlists.case_change)


def differential_texts(seed: int, count: int):
    """``count`` mutated netlists ``(name, text)``: half gentle, half from the full campaign."""
    rng = random.Random(seed)
    seeds = gen_netlists.seed_texts()
    for k in range(count):
        origin, text = seeds[rng.randrange(len(seeds))]
        if rng.random() < 0.5:
            names = []
            for _ in range(rng.choice([1, 2, 3])):
                mutation = rng.choice(GENTLE)
                text = mutation(rng, text)
                names.append(mutation.__name__)
            how = "+".join(names)
        else:
            text, how = gen_netlists.mutate(rng, text)
        yield f"diff seed={seed} #{k} {origin} {how}", text


def top_level_nodes(waves) -> list[str]:
    return [n for n in waves.names if n.startswith("v(") and "." not in n]


def compare(ours, theirs) -> list[tuple[str, float]]:
    """``(node, difference / range)`` for every top-level node above :data:`THRESHOLD`."""
    out = []
    t_ref = np.asarray(theirs.time, dtype=float)
    t_ours = np.asarray(ours.time, dtype=float)
    for name in top_level_nodes(theirs):
        if name not in ours.names:
            out.append((name, float("inf")))
            continue
        ref = np.asarray(theirs[name], dtype=float)
        mine = np.asarray(ours[name], dtype=float)
        if len(t_ref) > 1 and len(t_ours) > 1:
            mine = np.interp(t_ref, t_ours, mine)
        elif len(mine) != len(ref):
            mine = np.full_like(ref, mine[-1])
        scale = float(np.ptp(ref)) if len(ref) > 1 else 0.0
        scale = max(scale, float(np.max(np.abs(ref))) if scale == 0.0 else scale, 1e-9)
        error = float(np.max(np.abs(mine - ref))) / scale
        if not np.isfinite(error) or error > THRESHOLD:
            out.append((name, error))
    return out


def run_one(name: str, text: str, bound: float) -> tuple[str, object]:
    """``(status, detail)``: status is refused, builtin-error, ngspice-error, both, same, differ."""
    from circuitsim.interop.ngspice import run_ngspice
    from circuitsim.netlist.errors import NetlistError
    from circuitsim.solver import SimulationOptions, simulate

    folder = Path(gen_netlists.include_folder())
    try:
        circuit = gen_netlists.read(text)
    except NetlistError:
        return "refused", None
    path = folder / "diff.cir"
    path.write_text(text, encoding="utf-8")
    ours = theirs = None
    why_ours = why_theirs = ""
    try:
        with time_bound(bound):
            ours = simulate(circuit, SimulationOptions.from_circuit(circuit, max_steps=200_000))
    except CaseTimeout:
        why_ours = "time bound"
    except Exception as exc:  # noqa: BLE001 - recorded: the campaign judges tracebacks
        why_ours = f"{type(exc).__name__}: {str(exc)[:120]}"
    try:
        theirs = run_ngspice(path, timeout=bound)
    except Exception as exc:  # noqa: BLE001
        why_theirs = f"{type(exc).__name__}: {str(exc)[:120]}"
    if ours is None and theirs is None:
        return "both-failed", (why_ours, why_theirs)
    if ours is None:
        return "builtin-failed", why_ours
    if theirs is None:
        return "ngspice-failed", why_theirs
    differences = compare(ours, theirs)
    return ("differ", differences) if differences else ("same", None)


def warm_up() -> None:
    """Run every seed netlist once without a time bound, so that the compiled kernels are
    compiled (or loaded from numba's cache) before the bounded runs start."""
    from circuitsim.solver import simulate

    for name, text in gen_netlists.seed_texts():
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                simulate(gen_netlists.read(text))
        except Exception as exc:  # noqa: BLE001 - a seed the engine refuses is fine here
            print(f"  warm-up {name}: {type(exc).__name__}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.fuzz.differential")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--count", type=int, default=400)
    parser.add_argument("--time-bound", type=float, default=60.0)
    args = parser.parse_args(argv)
    faulthandler.register(signal.SIGUSR1)  # kill -USR1 <pid> shows where a slow run is
    warm_up()
    counts: dict[str, int] = {}
    rows = []
    for k, (name, text) in enumerate(differential_texts(args.seed, args.count)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            status, detail = run_one(name, text, args.time_bound)
        counts[status] = counts.get(status, 0) + 1
        if status != "refused":
            rows.append((name, status, detail, text))
        if k % 10 == 0:
            print(f"  {k} netlists: {counts}", file=sys.stderr)
    print(f"differential fuzz: seed {args.seed}, {args.count} netlists, threshold "
          f"{THRESHOLD:.0%} of range")
    for status, n in sorted(counts.items()):
        print(f"  {status:15} {n}")
    for name, status, detail, text in rows:
        if status == "same":
            continue
        print(f"\n[{status}] {name}: {detail}")
        for line in text.splitlines()[:25]:
            print("    " + (line if len(line) < 160 else line[:160] + "..."))
    return 0


if __name__ == "__main__":
    sys.exit(main())


