"""The fuzz harness: run hostile inputs in-process, each within a time bound, and classify them.

A fuzz campaign is a stream of :class:`Case` objects (made by the ``gen_*.py`` modules of this
folder, see ``campaign.py``). :func:`run_case` calls one case's callable under a wall-clock
bound (``signal.setitimer`` in the main thread) and classifies what happened:

``clean``
    The callable returned (a result, or for the command line an exit code 0, or 1 without an
    ``error:`` line: ``check`` reporting findings).
``named``
    It raised one of the project's typed errors (:data:`NAMED_ERRORS`, or the case's own
    ``named`` types); for the command line: exit code 1, 2 or 3 (README, "Exit codes") with
    exactly one ``error:`` line on stderr and no traceback.
``traceback``
    Anything else: an untyped exception (``TypeError``, ``RecursionError``, ``MemoryError``
    ...), or a command line that printed a traceback, several error lines or an error message
    longer than :data:`MAX_MESSAGE_CHARS`.
``hang``
    The time bound passed before the callable returned.

The target of the campaign is zero ``traceback`` and zero ``hang`` outcomes. A
:class:`Summary` counts outcomes per domain and keeps a few examples of each failure kind with
the input that produced it, so a failure can be replayed from the report alone.

Example
-------
>>> from tests.fuzz.harness import Case, run_cases
>>> summary = run_cases([Case("demo", "int", "12", lambda: int("12"))], time_bound=1.0)
>>> summary.counts[("demo", "clean")]
1
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import signal
import threading
import time
import traceback
import warnings
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

OUTCOMES = ("clean", "named", "traceback", "hang")
"""The four outcome kinds, in the order the summary prints them."""

FAILURES = ("traceback", "hang")
"""The outcome kinds a campaign must not produce."""

MAX_MESSAGE_CHARS = 4000
"""A command-line error message longer than this counts as a failure: an error must not echo
a whole input line (a 1 MB line once produced a 2 MB message)."""


def _project_errors() -> tuple[type[BaseException], ...]:
    """The typed errors of every room (the command line catches the same set)."""
    from circuitsim.atomic import WriteError
    from circuitsim.cli import _library_errors

    return (*_library_errors(), WriteError)


NAMED_ERRORS: tuple[type[BaseException], ...] = _project_errors()
"""Exceptions that count as a ``named`` outcome for an in-process library call."""


class CaseTimeout(BaseException):
    """Raised inside a case when its time bound passes.

    A BaseException, so that a case's own ``except Exception`` cannot swallow it.
    """


@dataclass(frozen=True)
class Case:
    """One fuzz input and the call that consumes it.

    Parameters
    ----------
    domain : str
        What is fuzzed (``"netlist-check"``, ``"model"``, ``"cli"`` ...): the summary's rows.
    name : str
        A short, unique, replayable label (generator, seed, mutation).
    text : str
        The input text (netlist or model file), kept for the report; may be empty.
    run : callable
        Called with no argument. Returns anything (clean) or raises. For a command line, use
        :func:`cli_call`, whose result the harness classifies by exit code and stderr.
    argv : sequence of str, optional
        The command line, when the case is one (kept for the report).
    named : tuple of exception types, optional
        Further exceptions that count as ``named`` for this case only.
    """

    domain: str
    name: str
    text: str
    run: Callable[[], object]
    argv: Sequence[str] = ()
    named: tuple[type[BaseException], ...] = ()


@dataclass(frozen=True)
class CliResult:
    """What a command line run in-process left: exit code and captured streams."""

    code: int
    stdout: str
    stderr: str


def cli_call(argv: Sequence[str], folder: Path | None = None) -> Callable[[], CliResult]:
    """A callable that runs ``circuitsim <argv>`` in-process and captures its output.

    ``SystemExit`` (argparse's own exit) becomes the exit code; any other exception
    propagates, and the harness classifies it as a traceback. ``folder``: the working folder
    of the call (relative outputs such as ``-o -`` land there, not in the repository).
    """

    def call() -> CliResult:
        from circuitsim.cli import main

        out, err = io.StringIO(), io.StringIO()
        where = contextlib.chdir(folder) if folder is not None else contextlib.nullcontext()
        with where, contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(list(argv))
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
        return CliResult(int(code), out.getvalue(), err.getvalue())

    return call


def classify_cli(result: CliResult) -> tuple[str, str]:
    """The outcome kind of a command-line result and a one-line detail."""
    errors = [line for line in result.stderr.splitlines() if "error:" in line]
    if "Traceback (most recent call last)" in result.stderr:
        return "traceback", f"exit {result.code} with a traceback on stderr"
    if len(result.stderr) > MAX_MESSAGE_CHARS:
        return "traceback", f"exit {result.code}, {len(result.stderr)} characters on stderr"
    if result.code == 0 or (result.code == 1 and not errors):
        return "clean", f"exit {result.code}"
    if result.code in (1, 2, 3) and len(errors) == 1:  # README "Exit codes": 3 a failed run
        return "named", errors[0][:200]
    return "traceback", f"exit {result.code} with {len(errors)} error lines"


@dataclass(frozen=True)
class Outcome:
    """How one case ended.

    Attributes
    ----------
    case : Case
    kind : str
        One of :data:`OUTCOMES`.
    detail : str
        The exception's type and message (cut to 200 characters), or the exit code.
    seconds : float
        Wall time of the call, s.
    trace : str
        The formatted traceback for ``traceback`` outcomes raised in-process, else ``""``.
    peak_rss_mb : float
        The campaign process's peak resident memory after the case (its high-water mark so
        far, MiB): a case that needed more memory than every case before it raised it.
    peak_child_rss_mb : float
        The same for the largest child process waited for so far (ngspice), MiB.
    """

    case: Case
    kind: str
    detail: str
    seconds: float
    trace: str = ""
    peak_rss_mb: float = 0.0
    peak_child_rss_mb: float = 0.0


def peak_rss_mb(children: bool = False) -> float:
    """This process's (or its largest waited-for child's) peak resident memory so far, MiB
    (``ru_maxrss``, KiB on Linux)."""
    import resource

    who = resource.RUSAGE_CHILDREN if children else resource.RUSAGE_SELF
    return resource.getrusage(who).ru_maxrss / 1024.0


@contextlib.contextmanager
def time_bound(seconds: float):
    """Raise :class:`CaseTimeout` in the body once ``seconds`` of wall time have passed.

    Uses ``signal.setitimer(ITIMER_REAL)``, so it works only in the main thread; the previous
    handler and timer are restored afterwards.
    """
    if threading.current_thread() is not threading.main_thread():
        raise RuntimeError("the fuzz time bound needs the main thread (signal.setitimer)")

    def expire(signum, frame):
        raise CaseTimeout(f"time bound of {seconds:g} s passed")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _cut(text: str, limit: int) -> str:
    """``text`` cut to ``limit`` characters, saying how long it was."""
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def _message(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text[:200]}"


def run_case(case: Case, bound: float = 10.0) -> Outcome:
    """Run ``case`` within ``bound`` seconds of wall time and classify the outcome, with the
    process's peak resident memory after it.

    Warnings raised by the case are ignored (a warning is a clean way to report).
    """
    outcome = _run_case(case, bound)
    return dataclasses.replace(
        outcome, peak_rss_mb=peak_rss_mb(), peak_child_rss_mb=peak_rss_mb(children=True)
    )


def _run_case(case: Case, bound: float) -> Outcome:
    named = NAMED_ERRORS + tuple(case.named)
    start = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with time_bound(bound):
                result = case.run()
    except CaseTimeout as exc:
        return Outcome(case, "hang", str(exc), time.perf_counter() - start)
    except named as exc:
        return Outcome(case, "named", _message(exc), time.perf_counter() - start)
    except (Exception, RecursionError, MemoryError) as exc:
        return Outcome(
            case, "traceback", _message(exc), time.perf_counter() - start, traceback.format_exc()
        )
    seconds = time.perf_counter() - start
    if isinstance(result, CliResult):
        kind, detail = classify_cli(result)
        return Outcome(case, kind, detail, seconds, result.stderr if kind != "clean" else "")
    return Outcome(case, "clean", "", seconds)


@dataclass
class Summary:
    """Outcome counts per ``(domain, kind)`` and a few examples of each failure.

    Attributes
    ----------
    counts : Counter
        ``counts[(domain, kind)]`` is the number of cases of ``domain`` that ended as ``kind``.
    failures : list of Outcome
        Up to ``keep`` outcomes per ``(domain, kind)`` of the kinds in :data:`FAILURES`.
    seconds : float
        Total wall time of the cases, s.
    slowest : Outcome or None
        The slowest case that was not a hang.
    """

    keep: int = 5
    counts: Counter = field(default_factory=Counter)
    failures: list[Outcome] = field(default_factory=list)
    seconds: float = 0.0
    slowest: Outcome | None = None

    def add(self, outcome: Outcome) -> None:
        """Count ``outcome`` (and keep it if it is one of the first failures of its kind)."""
        key = (outcome.case.domain, outcome.kind)
        self.counts[key] += 1
        self.seconds += outcome.seconds
        if outcome.kind in FAILURES and self.counts[key] <= self.keep:
            self.failures.append(outcome)
        if outcome.kind != "hang" and (
            self.slowest is None or outcome.seconds > self.slowest.seconds
        ):
            self.slowest = outcome

    @property
    def total(self) -> int:
        """Number of cases run."""
        return sum(self.counts.values())

    def count(self, kind: str, domain: str | None = None) -> int:
        """Number of ``kind`` outcomes, in ``domain`` or in all domains."""
        return sum(n for (d, k), n in self.counts.items() if k == kind and domain in (None, d))

    def table(self) -> str:
        """The counts as a plain-text table, one row per domain plus a total row."""
        domains = sorted({d for d, _ in self.counts})
        header = f"{'domain':<22}" + "".join(f"{k:>11}" for k in OUTCOMES) + f"{'total':>9}"
        rows = [header]
        for domain in [*domains, None]:
            cells = [self.count(k, domain) for k in OUTCOMES]
            label = domain if domain is not None else "all"
            rows.append(f"{label:<22}" + "".join(f"{n:>11}" for n in cells) + f"{sum(cells):>9}")
        return "\n".join(rows)

    def report(self) -> str:
        """The table followed by the kept failures, each with its input (cut), to replay it."""
        lines = [self.table(), f"wall time of the cases: {self.seconds:.1f} s"]
        if self.slowest is not None:
            lines.append(f"slowest case: {self.slowest.case.name} ({self.slowest.seconds:.2f} s)")
        for outcome in self.failures:
            case = outcome.case
            lines.append(f"\n[{outcome.kind}] {case.domain} {case.name}: {outcome.detail}")
            if case.argv:
                lines.append("  argv: " + " ".join(case.argv))
            if case.text:
                lines.append("  input:")
                lines.extend("    " + _cut(t, 160) for t in case.text.splitlines()[:30])
                if case.text.count("\n") > 30:
                    lines.append(f"    ... ({case.text.count(chr(10)) + 1} lines)")
            if outcome.trace:
                lines.append("  " + "\n  ".join(outcome.trace.strip().splitlines()[-6:]))
        return "\n".join(lines)


def run_cases(
    cases: Iterable[Case],
    time_bound: float = 10.0,
    progress: Callable[[Outcome], None] | None = None,
) -> Summary:
    """Run every case with :func:`run_case` and count the outcomes.

    Parameters
    ----------
    cases : iterable of Case
    time_bound : float
        Wall-time bound per case, s.
    progress : callable, optional
        Called with each outcome (the campaign prints a progress line from it).
    """
    summary = Summary()
    for case in cases:
        outcome = run_case(case, time_bound)
        summary.add(outcome)
        if progress is not None:
            progress(outcome)
    return summary
