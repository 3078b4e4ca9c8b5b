"""Running ngspice in batch mode on a netlist and reading its waveforms back.

ngspice is given only what the simulation needs (its input can otherwise run shell commands;
docs/netlists.md, "Running ngspice", says what was checked and why):

* a deck made by :mod:`circuitsim.interop.ngspice_deck`: the netlist with its includes spliced
  in by us (relative files beside the including file, then in the package part library, as
  the netlist reader finds them), without any ``.control`` block, comment line, ``.title`` or
  anything after ``.end``, under a fixed title;
* of the deck's analysis cards (``.op``, ``.ac``, ``.dc``, ..., any case, in any file) only the
  chosen one, since ngspice 39 aborts a ``run`` over an ``.op`` together with another analysis
  ("no data saved for Transient analysis; analysis not run");
* then our own block, which runs the analysis and writes its vectors to a binary rawfile that
  :mod:`circuitsim.interop.rawfile` parses (exact doubles, and fast)::

    .control
    set filetype=binary
    set measoutfile=meas.txt
    run
    setplot tran1
    write out.raw
    .endc
    .end

ngspice runs as ``ngspice -b -n deck.cir`` (``-n``: no ``.spiceinit`` from ``$SPICE_USERINIT_DIR``,
the working folder or ``$HOME``) in a private temporary folder as its working folder, with a
bare environment (``HOME`` is that folder; no ``SPICE_*``/``NGSPICE_*`` variable, which could
move the system ``spinit`` or the input path) and a time limit; the folder goes away when the
run ends, however it ends (:mod:`circuitsim.interop.sandbox`).

ngspice's exit status is not trusted (a failed run may still exit 0): a run counts as failed
when the rawfile is missing or empty, or when the log holds error lines ("Error", "singular
matrix", "Timestep too small", "doAnalyses: ...", "simulation(s) aborted"); the error then
carries those lines (at most 40, each cut to about 200 characters).

Results: ``.tran`` (time plus signals), ``.op`` (one point at t = 0), or ``.ac`` as magnitude
and phase: the "time" axis holds the frequencies (Hz) and each complex vector becomes two real
ones, ``vm(node)``/``vp(node)`` (volts, degrees) and ``im(vname)``/``ip(vname)`` (amperes,
degrees), the names ngspice's own ``.print ac`` uses.
"""

from __future__ import annotations

import dataclasses
import os
import re
import shutil
import time
from pathlib import Path

from circuitsim.inputfile import (
    NETLIST_BYTES,
    RAW_FILE_BYTES,
    InputTooLargeError,
    read_bytes,
)
from circuitsim.interop.errors import NgspiceError, NgspiceTimeout
from circuitsim.interop.ngspice_deck import TITLE, DeckLine, check_inert, decode, flatten_deck
from circuitsim.interop.ngspice_files import STITCH_BLANKS, hide_included
from circuitsim.interop.ngspice_limits import RunLimits, refuse_endless_sweep
from circuitsim.interop.rawfile import parse_ascii_raw, parse_rawfile
from circuitsim.interop.sandbox import (
    TimeLimitExceeded,
    bare_environment,
    private_folder,
    run_with_limit,
)

__all__ = [
    "DEFAULT_TIMEOUT",
    "RunLimits",
    "ngspice_available",
    "run_ngspice",
    "parse_rawfile",
    "parse_ascii_raw",
]
from circuitsim.netlist.circuit import Circuit
from circuitsim.netlist.errors import shorten
from circuitsim.solver.recording import check_finite
from circuitsim.solver.waveforms import Waveforms

DEFAULT_TIMEOUT = 300.0  # seconds; the paper's slowest case takes a few seconds
FOLDER_PREFIX = "circuitsim-ngspice-"
_ERROR_LINE = re.compile(
    r"\berror\b|singular matrix|timestep too small|doanalyses|simulations? aborted"
    r"|unknown subckt|could not find|unable to find definition|no such vector|not found",
    re.IGNORECASE,
)
# ngspice prints tables of node values ("out   1.5"); a node called "error" is not an error.
_TABLE_ROW = re.compile(r"^\s*\S+\s+[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*$")
_MAX_LOG_LINES = 40


def ngspice_available() -> bool:
    """True when an ``ngspice`` executable is on PATH."""
    return shutil.which("ngspice") is not None


def run_ngspice(
    netlist: Circuit | str | os.PathLike,
    probes: list[str] | None = None,
    timeout: float = DEFAULT_TIMEOUT,
    analysis: str | None = None,
    limits: RunLimits | None = None,
) -> Waveforms:
    """Run ``ngspice -b -n`` on ``netlist`` in a private folder and return its waveforms.

    Parameters
    ----------
    netlist : Circuit, str or path-like
        A circuit (written with the ngspice dialect), SPICE text (a ``str``; a one-line
        ``str`` naming an existing file is that file; its relative includes are looked for in
        the working folder), or a netlist file (a path-like; relative ``.include``/``.lib``
        files are found beside it, then in the package part library).
    probes : list of str, optional
        Signals to return (``"out"`` or ``"v(out)"``, ``"i(v1)"``); all of them when None.
    timeout : float
        Seconds before ngspice is stopped and :class:`NgspiceTimeout` raised (default 300).
    analysis : {"tran", "op", "ac"}, optional
        Which of the deck's analyses to run and return; by default the ``.tran`` if there is
        one, else the ``.op``, else the ``.ac``. The deck's other analysis cards (with their
        ``+`` continuation lines) are left out of the deck ngspice runs.

    Returns
    -------
    Waveforms
        ``engine="ngspice"``; ``time`` in seconds, shape (m,), ``v(node)`` volts and
        ``i(name)`` amperes with lower-case SPICE names (subcircuit nodes as ``v(x1.node)``);
        an operating point is one point at t = 0; an ``.ac`` sweep has frequencies (Hz) as
        ``time`` and ``vm``/``vp``/``im``/``ip`` signals. ``stats["wall_time_s"]`` is
        ngspice's wall-clock time including start-up, ``stats["analysis"]`` ``"tran"``,
        ``"op"`` or ``"ac"``.

    Raises
    ------
    NetlistError
        An include or library file is missing, unreadable or included by itself (with the
        file and line that names it).
    NgspiceTimeout
        ngspice did not finish within ``timeout`` seconds.
    NgspiceError
        ngspice is not installed, reported errors, wrote no output, the deck has no
        ``.tran``/``.op``/``.ac`` (or not the one asked for), or a probe is not among the
        results.
    CircuitInputError, RunSizeError
        The ``.tran`` refused before ngspice starts, as the builtin engine refuses it.
    MemoryBudgetError
        ngspice's resident memory passed ``limits.max_memory``; it was stopped.
    NonFiniteError
        A result is inf or NaN (ngspice diverged without saying so).
    """
    found = _deck_found(netlist)
    lines = [line.text for line in found]
    analysis = _chosen_analysis(lines, analysis)
    if analysis == "ac":
        refuse_endless_sweep(lines)
    deck = _with_control(lines, analysis)
    binary = shutil.which("ngspice")
    if binary is None:
        raise NgspiceError("ngspice is not installed or not on PATH (apt-get install -y ngspice)")
    limits = limits if limits is not None else RunLimits()
    watch = limits.before_run(lines if analysis == "tran" else [])
    with private_folder(FOLDER_PREFIX) as folder:
        raw = folder / "out.raw"
        (folder / "deck.cir").write_bytes(deck.encode("utf-8", errors="surrogateescape"))
        started = time.perf_counter()
        try:
            done = run_with_limit(
                [binary, "-b", "-n", "deck.cir"], folder, bare_environment(folder), timeout, watch
            )
        except TimeLimitExceeded as exc:
            raise NgspiceTimeout(timeout, _tail(hide_included(exc.output, found))) from None
        except OSError as exc:
            raise NgspiceError(f"cannot start ngspice ({binary}): {exc}") from None
        wall = time.perf_counter() - started
        log = done.stdout + "\n" + done.stderr
        if (memory := watch.allocation_failure(log)) is not None:
            raise memory
        if _error_lines(log):
            shown = hide_included(log, found)  # no line of an included file quoted
            raise NgspiceError("ngspice reported errors", _error_lines(shown) or _tail(shown))
        if not raw.exists() or raw.stat().st_size == 0:
            raise NgspiceError(
                f"ngspice wrote no results (exit status {done.returncode})",
                _tail(hide_included(log, found)),
            )
        try:
            data = read_bytes(raw, RAW_FILE_BYTES, "a raw file")
        except InputTooLargeError as exc:
            raise NgspiceError(
                f"ngspice's results are {exc.reason}; probe fewer signals (--probe) or ask "
                "for a coarser output step"
            ) from None
        waves = parse_rawfile(data)
    check_finite(waves.signals, waves.time)
    waves.stats["peak_memory_bytes"] = watch.peak
    waves.stats["wall_time_s"] = wall
    waves.stats["analysis"] = analysis
    if probes is not None:
        missing = [p for p in probes if p not in waves]
        if missing:
            raise NgspiceError(
                f"no signal {', '.join(missing)} in the ngspice results; "
                f"have {', '.join(waves.names)}"
            )
        waves = waves.select(probes)
        waves.stats = {"wall_time_s": wall, "analysis": analysis}
    return waves


def _deck_lines(netlist: Circuit | str | os.PathLike) -> list[str]:
    """The netlist's circuit lines, flattened (:func:`~.ngspice_deck.flatten_deck`)."""
    return [line.text for line in _deck_found(netlist)]


def _deck_found(netlist: Circuit | str | os.PathLike) -> list[DeckLine]:
    """The netlist's circuit lines with their origins (:func:`~.ngspice_deck.flatten_deck`)."""
    if isinstance(netlist, Circuit):
        from circuitsim.netlist.writer import write_netlist

        text = write_netlist(dataclasses.replace(netlist, control=[]), "ngspice")
        found = flatten_deck(text, "<circuit>", Path.cwd())
    elif isinstance(netlist, str) and ("\n" in netlist or not os.path.isfile(netlist)):
        found = flatten_deck(netlist, "<string>", Path.cwd())
    else:
        path = Path(netlist)
        try:
            text = decode(read_bytes(path, NETLIST_BYTES, "a netlist file"))
        except InputTooLargeError as exc:
            raise NgspiceError(f"cannot read the netlist {exc}") from None
        except OSError as exc:
            raise NgspiceError(f"cannot read the netlist {path}: {exc.strerror or exc}") from None
        found = flatten_deck(text, str(path), path.resolve().parent)
    return found


def _cards(lines: list[str]) -> list[tuple[str, list[int]]]:
    """Each card's first word (lower case) and the indices of its lines (``+`` lines too).

    ``#`` and ``$`` lines are passed over when joining, and the first character above blank
    decides (a vertical tab before ``+`` continues too), as ngspice's stitching does.
    """
    cards: list[tuple[str, list[int]]] = []
    for index, text in enumerate(lines):
        lead = text.lstrip(STITCH_BLANKS)
        if lead.startswith("+") and cards:
            cards[-1][1].append(index)
        elif lead.startswith(("#", "$", "*")) or not lead:
            continue
        else:
            word = re.split(r"[\s;]", text, maxsplit=1)[0].lower()
            cards.append((word, [index]))
    return cards


def _chosen_analysis(lines: list[str], wanted: str | None = None) -> str:
    """``wanted`` if the deck has it; by default ``"tran"``, else ``"op"``, else ``"ac"``."""
    found = {word[1:] for word, _ in _cards(lines) if word in (".tran", ".op", ".ac")}
    if wanted is not None:
        if wanted not in ("tran", "op", "ac"):
            raise NgspiceError(f"unknown analysis {wanted!r}; choose tran, op or ac")
        if wanted not in found:
            have = ", ".join(f".{a}" for a in sorted(found)) or "none"
            raise NgspiceError(f"the netlist has no .{wanted} analysis (it has: {have})")
        return wanted
    for kind in ("tran", "op", "ac"):
        if kind in found:
            return kind
    raise NgspiceError("the netlist has no .tran, .op or .ac analysis for ngspice to run")


# The analysis cards ngspice runs on ``run``; all but the chosen one are left out, since
# ngspice 39 aborts a ``run`` over an ``.op`` together with another analysis ("no data saved
# for ... analysis; analysis not run").
_ANALYSIS_CARDS = frozenset(
    (".ac", ".dc", ".disto", ".noise", ".op", ".pss", ".pz", ".sens", ".sp", ".tf", ".tran")
)


def _with_control(lines: list[str], analysis: str) -> str:
    """The deck ngspice is given: our title, the circuit, only the chosen analysis, our block.

    Parameters
    ----------
    lines : list of str
        The flattened circuit lines (:func:`_deck_lines`), without a title.
    analysis : {"tran", "op", "ac"}
        The analysis to run.

    Returns
    -------
    str
        :data:`~.ngspice_deck.TITLE`, then ``lines`` without the analysis cards other than
        ``.<analysis>`` (and their ``+`` lines), then a ``.control`` block that runs and
        writes the chosen analysis to ``out.raw`` in ngspice's working folder, then ``.end``.

    Raises
    ------
    RuntimeError
        A line ngspice would act on is left (:func:`~.ngspice_deck.check_inert`).
    """
    dropped = {
        index
        for word, indices in _cards(lines)
        if word in _ANALYSIS_CARDS and word != f".{analysis}"
        for index in indices
    }
    kept = [text for index, text in enumerate(lines) if index not in dropped]
    check_inert(kept)
    # measoutfile is refused in the deck (ngspice_files); set here too, a global variable
    # outranks the circuit's .options ones (cp_getvar), so .meas output stays in the folder.
    # "save all": a .save card in the netlist (the generator writes one of the state nodes)
    # would otherwise keep every other vector out of the rawfile.
    block = [
        ".control",
        "set filetype=binary",
        "set measoutfile=meas.txt",
        "save all",
        "run",
        f"setplot {analysis}1",
        "write out.raw",
    ]
    return "\n".join([TITLE, *kept, *block, ".endc", ".end"]) + "\n"


def _error_lines(log: str) -> str:
    """The lines of ngspice's log that report an error, each with the line after it."""
    lines = log.splitlines()
    picked: dict[str, None] = {}
    for index, line in enumerate(lines):
        if line.startswith("Circuit:") or _TABLE_ROW.match(line):
            continue
        if not _ERROR_LINE.search(line):
            continue
        for extra in lines[index : index + 2]:
            if extra.strip():
                picked.setdefault(shorten(extra.rstrip()), None)
    return "\n".join(list(picked)[:_MAX_LOG_LINES])


def _tail(log: str) -> str:
    lines = [shorten(line) for line in log.splitlines() if line.strip()]
    return "\n".join(lines[-_MAX_LOG_LINES:])


def _text(data: bytes | str | None) -> str:
    if data is None:
        return ""
    return data if isinstance(data, str) else data.decode(errors="replace")
