"""Running ngspice in batch mode on a netlist and reading its waveforms back.

The netlist (a :class:`~circuitsim.netlist.circuit.Circuit`, written in the ngspice dialect, or
SPICE text, or a file) gets its own ``.control`` blocks replaced by one that runs the chosen
analysis and writes its vectors to a rawfile, which :mod:`circuitsim.interop.rawfile` parses
(binary: exact doubles, and fast)::

    .control
    set filetype=binary
    run
    setplot tran1
    write <tmp>/out.raw
    .endc

An ``.include file`` (or ``.lib file section``) line of the deck that names no file beside the
netlist but a file of the package part library (``.include parts.lib``) is pointed at that
library file by its absolute path, as the netlist reader finds it (ngspice knows only the first
place). Includes inside included files are left to ngspice.

Only the chosen analysis runs: the deck's other analysis cards (``.op``, ``.ac``, ``.dc``, ...,
any case) and their ``+`` continuation lines are commented out with a leading ``*`` in the copy
ngspice reads, since ngspice 39 aborts a ``run`` over an ``.op`` together with another analysis
("no data saved for Transient analysis; analysis not run"). Cards in included files are left
to ngspice.

ngspice's exit status is not trusted (a failed run may still exit 0): a run counts as failed
when the rawfile is missing or empty, or when the log holds error lines ("Error", "singular
matrix", "Timestep too small", "doAnalyses: ...", "simulation(s) aborted"); the error then
carries those lines.

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
import subprocess
import tempfile
import time
from pathlib import Path

from circuitsim.interop.errors import NgspiceError
from circuitsim.interop.rawfile import parse_ascii_raw, parse_rawfile

__all__ = ["ngspice_available", "run_ngspice", "parse_rawfile", "parse_ascii_raw"]
from circuitsim.netlist.circuit import Circuit
from circuitsim.solver.waveforms import Waveforms

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
    timeout: float = 300.0,
    analysis: str | None = None,
) -> Waveforms:
    """Run ``ngspice -b`` on ``netlist`` and return its waveforms.

    Parameters
    ----------
    netlist : Circuit, str or path-like
        A circuit (written with the ngspice dialect), SPICE text (a ``str``; a one-line
        ``str`` naming an existing file is that file), or a netlist file (a path-like;
        relative ``.include``/``.lib`` files are found beside it).
    probes : list of str, optional
        Signals to return (``"out"`` or ``"v(out)"``, ``"i(v1)"``); all of them when None.
    timeout : float
        Seconds before ngspice is stopped and NgspiceError raised.
    analysis : {"tran", "op", "ac"}, optional
        Which of the deck's analyses to run and return; by default the ``.tran`` if there is
        one, else the ``.op``, else the ``.ac``. The deck's other analysis cards (with their
        ``+`` continuation lines) are commented out in the copy ngspice runs, so ngspice runs
        exactly this one.

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
    NgspiceError
        ngspice is not installed, timed out, reported errors, wrote no output, the deck has
        no ``.tran``/``.op``/``.ac`` (or not the one asked for), or a probe is not among the
        results.
    """
    deck, cwd = _deck_text(netlist)
    deck = _library_includes(deck, Path(cwd) if cwd else Path(os.getcwd()))
    analysis = _chosen_analysis(deck, analysis)
    binary = shutil.which("ngspice")
    if binary is None:
        raise NgspiceError("ngspice is not installed or not on PATH (apt-get install -y ngspice)")
    with tempfile.TemporaryDirectory(prefix="circuitsim-ngspice-") as tmp:
        raw = Path(tmp) / "out.raw"
        deck_path = Path(tmp) / "deck.cir"
        deck_path.write_text(_with_control(deck, analysis, raw))
        started = time.perf_counter()
        try:
            done = subprocess.run(
                [binary, "-b", str(deck_path)],
                cwd=cwd or tmp,
                capture_output=True,
                text=True,
                errors="replace",
                timeout=timeout,
                stdin=subprocess.DEVNULL,
            )
        except subprocess.TimeoutExpired as exc:
            log = _text(exc.stdout) + _text(exc.stderr)
            raise NgspiceError(f"ngspice did not finish within {timeout:g} s", _tail(log)) from None
        wall = time.perf_counter() - started
        log = done.stdout + "\n" + done.stderr
        errors = _error_lines(log)
        if errors:
            raise NgspiceError("ngspice reported errors", errors)
        if not raw.exists() or raw.stat().st_size == 0:
            raise NgspiceError(
                f"ngspice wrote no results (exit status {done.returncode})", _tail(log)
            )
        waves = parse_rawfile(raw.read_bytes())
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


def _deck_text(netlist: Circuit | str | os.PathLike) -> tuple[str, str | None]:
    """The SPICE text to run and the folder to run it in (None: a temporary one)."""
    if isinstance(netlist, Circuit):
        from circuitsim.netlist.writer import write_netlist

        return write_netlist(dataclasses.replace(netlist, control=[]), "ngspice"), None
    if isinstance(netlist, str) and ("\n" in netlist or not os.path.isfile(netlist)):
        return netlist, None
    path = Path(netlist)
    try:
        text = path.read_text(errors="replace")
    except OSError as exc:
        raise NgspiceError(f"cannot read the netlist {path}: {exc}") from None
    return text, str(path.resolve().parent)


_INCLUDE_LINE = re.compile(
    r"""^(?P<lead>\s*)(?P<word>\.include|\.inc|\.lib)(?P<gap>\s+)
    (?P<path>"[^"]*"|'[^']*'|[^\s"']+)(?P<rest>.*)$""",
    re.IGNORECASE | re.VERBOSE,
)


def _library_includes(deck: str, folder: Path) -> str:
    """``deck`` with includes of the package part library given as absolute paths.

    Parameters
    ----------
    deck : str
        SPICE text; its first line is the title.
    folder : Path
        Where the netlist's relative includes are looked for first (the netlist's folder).

    Returns
    -------
    str
        The same text, except each top-level ``.include``/``.inc file`` or ``.lib file
        section`` line whose relative file is not in ``folder`` but is in the package part
        library, which now names the library file by its absolute path, quoted. A ``.lib``
        with one word is left alone (ngspice reads it as a section name, not a file).
    """
    from circuitsim.netlist.reader import LIBRARY_DIR

    lines = deck.splitlines(keepends=True)
    in_control = False
    for index, line in enumerate(lines[1:], start=1):
        word = line.strip().split(maxsplit=1)[0].lower() if line.strip() else ""
        if word == ".control":
            in_control = True
        elif word == ".endc":
            in_control = False
        match = None if in_control else _INCLUDE_LINE.match(line.rstrip("\r\n"))
        if match is None:
            continue
        name = match["path"].strip("\"'")
        if match["word"].lower() == ".lib" and not match["rest"].split():
            continue
        try:
            if not name or Path(name).is_absolute() or (folder / name).is_file():
                continue
            library_file = LIBRARY_DIR / name
            if not library_file.is_file():
                continue
        except (OSError, ValueError):  # a name no file system takes: ngspice will say so
            continue
        ending = line[len(line.rstrip("\r\n")) :]
        lines[index] = (
            f'{match["lead"]}{match["word"]}{match["gap"]}"{library_file.resolve()}"'
            f"{match['rest']}{ending}"
        )
    return "".join(lines)


def _logical_lines(deck: str) -> list[str]:
    """Physical lines with ``+`` continuations joined (first line, the title, kept as is)."""
    joined: list[str] = []
    for line in deck.splitlines():
        if joined and line.lstrip().startswith("+") and len(joined) > 1:
            joined[-1] += " " + line.lstrip()[1:]
        else:
            joined.append(line)
    return joined


def _chosen_analysis(deck: str, wanted: str | None = None) -> str:
    """``wanted`` if the deck has it; by default ``"tran"``, else ``"op"``, else ``"ac"``."""
    found = set()
    in_control = False
    for line in _logical_lines(deck)[1:]:
        word = line.strip().split(maxsplit=1)[0].lower() if line.strip() else ""
        if word == ".control":
            in_control = True
        elif word == ".endc":
            in_control = False
        elif not in_control and word in (".tran", ".op", ".ac"):
            found.add(word[1:])
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


# The analysis cards ngspice runs on ``run``; all but the chosen one are commented out, since
# ngspice 39 aborts a ``run`` over an ``.op`` together with another analysis ("no data saved
# for ... analysis; analysis not run").
_ANALYSIS_CARDS = frozenset(
    (".ac", ".dc", ".disto", ".noise", ".op", ".pss", ".pz", ".sens", ".sp", ".tf", ".tran")
)


def _with_control(deck: str, analysis: str, raw: Path) -> str:
    """The deck ngspice is given: only the chosen analysis, and our ``.control`` block.

    Parameters
    ----------
    deck : str
        SPICE text; its first line is the title.
    analysis : {"tran", "op", "ac"}
        The analysis to run.
    raw : Path
        Where ngspice writes the binary rawfile.

    Returns
    -------
    str
        ``deck`` without its ``.control`` blocks and ``.end``, with every analysis card other
        than ``.<analysis>`` (outside control blocks, any case) and its ``+`` continuation lines
        commented out with a leading ``*``, then a ``.control`` block that runs and writes the
        chosen analysis, then ``.end``.
    """
    kept: list[str] = []
    in_control = False
    dropping = False  # inside a commented-out card: its continuation lines go as well
    for index, line in enumerate(deck.splitlines()):
        stripped = line.strip()
        word = stripped.split(maxsplit=1)[0].lower() if stripped and index else ""
        if in_control or word in (".control", ".endc", ".end"):
            if word == ".control":
                in_control = True
            elif word == ".endc":
                in_control = False
            dropping = False
        elif dropping and stripped.startswith("+"):
            kept.append("*" + line)
        elif dropping and (not stripped or stripped.startswith("*")):
            # ngspice drops blank and comment lines before joining continuations, so a "+"
            # line after them still belongs to the commented-out card
            kept.append(line)
        else:
            dropping = word in _ANALYSIS_CARDS and word != f".{analysis}"
            kept.append("*" + line if dropping else line)
    kept += [
        ".control",
        "set filetype=binary",
        "run",
        f"setplot {analysis}1",
        f"write {raw}",
        ".endc",
        ".end",
    ]
    return "\n".join(kept) + "\n"


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
                picked.setdefault(extra.rstrip(), None)
    return "\n".join(list(picked)[:_MAX_LOG_LINES])


def _tail(log: str) -> str:
    lines = [line for line in log.splitlines() if line.strip()]
    return "\n".join(lines[-_MAX_LOG_LINES:])


def _text(data: bytes | str | None) -> str:
    if data is None:
        return ""
    return data if isinstance(data, str) else data.decode(errors="replace")
