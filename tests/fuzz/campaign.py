"""The long fuzz campaign: every ``gen_*.py`` generator of this folder, seeded, counted.

Usage (from the repository root)::

    python -m tests.fuzz.campaign --seed 1 --count 2000 --log campaign.csv
    python tests/fuzz/campaign.py --seed 1 --count 2000 --only gen_netlists --time-bound 20

``--count`` is the number of cases asked of EACH generator module (a generator may yield
fewer, e.g. when its corpus is exhausted). Prints progress on stderr, then a table of outcome
counts per domain (``clean``, ``named``, ``traceback``, ``hang``; see ``harness.py``) and the
first failures of each kind with their inputs. Exit code 0 when there is no traceback and no
hang, 1 otherwise.

A generator module is any ``tests/fuzz/gen_<name>.py`` exposing
``cases(seed: int, count: int) -> Iterable[Case]``; the same seed gives the same cases.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from collections.abc import Iterable
from pathlib import Path

if __package__ in (None, ""):  # run as a script path: make ``tests.fuzz`` importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.fuzz.harness import FAILURES, Case, Outcome, Summary, run_case  # noqa: E402

FOLDER = Path(__file__).parent


def generator_names() -> list[str]:
    """The ``gen_*`` module names of this folder, sorted."""
    return sorted(path.stem for path in FOLDER.glob("gen_*.py"))


def generator_cases(name: str, seed: int, count: int) -> Iterable[Case]:
    """The cases of generator module ``name`` (``gen_netlists`` ...) for ``seed``, ``count``."""
    module = importlib.import_module(f"tests.fuzz.{name}")
    return module.cases(seed, count)


def run_campaign(
    names: Iterable[str],
    seed: int,
    count: int,
    time_bound: float,
    quiet: bool = False,
    log: list | None = None,
) -> Summary:
    """Run the cases of ``names`` and return the summary (progress on stderr unless quiet);
    each case's outcome is appended to ``log`` when given."""
    from circuitsim.solver.compiled import warm_up

    # the kernels' first compile (minutes after a source change, on a loaded machine) is
    # not a case's work: a case's time bound interrupting it would count as a hang
    warm_up(("ports", "compiled"))
    summary = Summary()
    start = time.perf_counter()
    last = start

    def progress(outcome: Outcome) -> None:
        nonlocal last
        now = time.perf_counter()
        if outcome.kind in FAILURES:
            print(f"  {outcome.kind}: {outcome.case.name}: {outcome.detail}", file=sys.stderr)
        if now - last > 10:
            last = now
            print(
                f"  {summary.total} cases, {now - start:.0f} s "
                f"({summary.count('traceback')} tracebacks, {summary.count('hang')} hangs)",
                file=sys.stderr,
            )

    for name in names:
        if not quiet:
            print(f"{name}: seed {seed}, count {count}", file=sys.stderr)
        for case in generator_cases(name, seed, count):
            outcome = run_case(case, time_bound)
            summary.add(outcome)
            if log is not None:
                log.append(outcome)
            if not quiet:
                progress(outcome)
    return summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m tests.fuzz.campaign",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument(
        "--count", type=int, default=1000, help="cases per generator module (default 1000)"
    )
    parser.add_argument(
        "--time-bound", type=float, default=30.0, help="wall-time bound per case, s (default 30)"
    )
    parser.add_argument("--log", metavar="FILE.csv", help="one row per case (see above)")
    parser.add_argument(
        "--only",
        action="append",
        metavar="GEN",
        help="run only this generator module (gen_netlists ...); repeatable",
    )
    args = parser.parse_args(argv)
    names = generator_names()
    if args.only:
        unknown = sorted(set(args.only) - set(names))
        if unknown:
            parser.error(f"no generator {', '.join(unknown)}; present: {', '.join(names)}")
        names = [n for n in names if n in args.only]
    start = time.perf_counter()
    log: list = []
    summary = run_campaign(names, args.seed, args.count, args.time_bound, log=log)
    if args.log:
        _write_log(args.log, log)
    print(
        f"fuzz campaign: generators {', '.join(names)}; seed {args.seed}; "
        f"count {args.count} per generator; time bound {args.time_bound:g} s per case"
    )
    print(summary.report())
    if log:
        raised = max(log, key=lambda o: o.peak_rss_mb)
        first = next(o for o in log if o.peak_rss_mb == raised.peak_rss_mb)
        child = max(o.peak_child_rss_mb for o in log)
        print(
            f"peak resident memory of the campaign process: {raised.peak_rss_mb:.0f} MiB "
            f"(reached in {first.case.domain} {first.case.name}); of a child: {child:.0f} MiB"
        )
    print(f"campaign wall time: {time.perf_counter() - start:.0f} s")
    return 1 if any(summary.count(kind) for kind in FAILURES) else 0


def _write_log(path: str, log: list) -> None:
    """The per-case CSV: domain, name, outcome, seconds, peak resident memory so far (MiB)."""
    import csv

    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(
            ["domain", "name", "outcome", "seconds", "peak_rss_mib", "peak_child_rss_mib"]
        )
        for o in log:
            writer.writerow([o.case.domain, o.case.name, o.kind, f"{o.seconds:.3f}",
                             f"{o.peak_rss_mb:.1f}", f"{o.peak_child_rss_mb:.1f}"])  # fmt: skip


if __name__ == "__main__":
    sys.exit(main())
