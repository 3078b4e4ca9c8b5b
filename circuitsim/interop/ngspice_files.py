"""What in an ngspice deck names a file ngspice would open, and ngspice's messages without the
text of included files.

Two duties of the ngspice runner (docs/netlists.md, "The ngspice runner"):

* :func:`refuse_file_names` refuses a deck in which a card makes ngspice 39 open a file of its
  own choosing (the runner's private folder is the only place ngspice may write, and ngspice
  reads no file but the deck and its system ``spinit``). What ngspice 39's sources (tag
  ``ngspice-39`` of ``imr/ngspice``) show, card by card:

  - an option card's words become front-end variables of the circuit, any variable at all
    (``src/frontend/options.c`` ``inp_getopts``, ``src/frontend/inp.c`` ``inp_dodeck`` with
    ``cp_setparse``), so the variables ngspice opens a file or runs a program by
    (:data:`FILE_OPTIONS`) are refused on every card starting ``.opt`` (``inp_getopts``
    takes them by ``ciprefix(".opt")``; plain ngspice 39 acted on ``.option`` and
    ``.options`` in any case in the tests, not on ``.opt``, ``.opts`` or ``.optfoo``);
  - ``.model`` (and XSPICE's ``.cmodel``) of the code models that read a file
    (:data:`FILE_MODELS`) and CIDER's file parameters (:data:`CIDER_FILE_PARAMETERS`) on any
    card.

  The words are found the way ngspice's ``inp_casefix`` and lexer would still find them: any
  case, quotes read as blanks, backslashes dropped or read as blanks, characters that are not
  printable ASCII read as ``_``.
* :func:`hide_included` replaces each line of ngspice's output that quotes a line of an
  included file (a word of 3 or more characters of it, not only digits and not also in the
  top netlist, or the whole line) by a note naming that file and line: the included file may
  be anything the netlist names (``.include /etc/passwd``), the reader's rule
  (:meth:`~circuitsim.netlist.errors.NetlistError.without_source_text`).
"""

from __future__ import annotations

import functools
import re
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from circuitsim.netlist.errors import NetlistError

if TYPE_CHECKING:  # pragma: no cover
    from circuitsim.interop.ngspice_deck import DeckLine

__all__ = [
    "FILE_OPTIONS",
    "FILE_MODELS",
    "CIDER_FILE_PARAMETERS",
    "STITCH_BLANKS",
    "refuse_file_names",
    "hide_included",
]

FILE_OPTIONS: dict[str, str] = {
    "measoutfile": "the file .meas results are written to (src/frontend/measure.c)",
    "rawfile": "the rawfile of a batch run without .control (src/frontend/inpcom.c)",
    "sourcepath": "folders included and sourced files are looked for in (src/frontend/inpcom.c)",
    "inputdir": "the folder XSPICE file readers look in (src/frontend/inp.c)",
    "helppath": "the folder of help files (src/frontend/com_ghelp.c)",
    "editor": "the program 'edit' starts (src/frontend/inp.c)",
    "spicepath": "the program 'aspice' starts (src/frontend/aspice.c)",
    "rprogram": "the program 'rspice' starts (src/frontend/aspice.c)",
    "remote_shell": "the shell 'rspice' starts (src/frontend/aspice.c)",
    "rhost": "the host 'rspice' connects to (src/frontend/aspice.c)",
    "lprps": "the print command of 'hardcopy' (src/frontend/com_hardcopy.c)",
    "lprplot5": "the print command of 'hardcopy' (src/frontend/com_hardcopy.c)",
    "hcopydev": "the printer 'hardcopy' prints on (src/frontend/com_hardcopy.c)",
}
"""Front-end variables (set by any ``.opt...`` card) naming a file, folder, program or host."""

FILE_MODELS: dict[str, str] = {
    "filesource": "file (src/xspice/icm/analog/file_source/cfunc.mod)",
    "d_source": "input_file (src/xspice/icm/digital/d_source/cfunc.mod)",
    "d_state": "state_file (src/xspice/icm/digital/d_state/cfunc.mod)",
    "table2d": "file (src/xspice/icm/table/table2D/cfunc.mod)",
    "table3d": "file (src/xspice/icm/table/table3D/cfunc.mod)",
}
"""XSPICE code models that read the file their parameter names (``fopen_with_path``)."""

CIDER_FILE_PARAMETERS: dict[str, str] = {
    "rootfile": "writes device state files (src/ciderlib/input/output.c, numd/numddump.c)",
    "infile": "reads a doping profile (src/ciderlib/input/doping.c, support/suprmitf.c)",
    "ic.file": "reads initial conditions (src/ciderlib/input/optionsc.c, numd/numd.c)",
}
"""Parameters of CIDER's numerical devices (NUMD, NBJT, NUMOS) that name a file."""

_BLANKS = " \t\n\v\f\r"
STITCH_BLANKS = "".join(chr(c) for c in range(33))
"""What ngspice's stitching skips before a card's first character (every character <= ' ')."""
_RUN = re.compile(r"[a-z0-9_]+")
_DOTTED_RUN = re.compile(r"[a-z0-9_.]+")
_MODEL_HINTS = re.compile("file|source|state|table")  # in every word of FILE_MODELS
_MIN_WORD = 3
_MAX_WHOLE_LINES = 5000  # included lines compared whole with ngspice's output lines


def _printable(text: str) -> str:
    """``text`` lower case, non-printable ASCII as ``_`` and quotes as blanks (inp_casefix)."""
    chars = (c if c in _BLANKS or " " <= c <= "~" else "_" for c in text.lower())
    return "".join(chars).replace('"', " ").replace("'", " ")


def _words(text: str) -> set[str]:
    """Every word ngspice could read in ``text`` (see the module docstring), lower case."""
    seen = _printable(text)
    words: set[str] = set()
    for variant in (seen.replace("\\", ""), seen.replace("\\", " ")):
        words.update(_RUN.findall(variant))
        words.update(_DOTTED_RUN.findall(variant))
    return words


def _plain_words(text: str) -> set[str]:
    """The runs of ASCII letters, digits and ``_`` in ``text``, lower case."""
    return set(_RUN.findall(text.lower()))


def _cards(lines: list[DeckLine]) -> list[list[DeckLine]]:
    """The deck's cards as ngspice stitches them (``inp_stitch_continuation_lines``).

    A line whose first character above blank is ``+`` continues the card before it; lines
    starting ``*``, ``#``, ``$`` or blank are passed over.
    """
    cards: list[list[DeckLine]] = []
    for line in lines:
        lead = line.text.lstrip(STITCH_BLANKS)
        if not lead or lead[0] in "*#$":
            continue
        if lead[0] == "+" and cards:
            cards[-1].append(line)
        else:
            cards.append([line])
    return cards


def refuse_file_names(lines: list[DeckLine]) -> None:
    """Refuse a deck with a card that makes ngspice open a file (see the module docstring).

    Parameters
    ----------
    lines : list of DeckLine
        The flattened deck (:func:`~circuitsim.interop.ngspice_deck.flatten_deck`).

    Raises
    ------
    NetlistError
        Naming the file and line of the word, what ngspice would do with it and the remedy.
        The message quotes no text of the line beyond the word, which is ngspice's vocabulary.
    """
    for card in _cards(lines):
        keyword = card[0].text.lstrip(STITCH_BLANKS).lower()
        is_option = keyword.startswith(".opt")
        is_model = keyword.startswith((".model", ".cmodel"))
        for line in card:
            seen = line.text.lower().replace("\\", "")
            if not (is_option or (is_model and _MODEL_HINTS.search(seen)) or "file" in seen):
                continue  # none of the words can be in it (a large library reads fast)
            words = _words(line.text)
            if is_option:
                for name in sorted(words & FILE_OPTIONS.keys()):
                    raise _refusal(
                        line,
                        f"the .options variable {name} names {FILE_OPTIONS[name]}; the ngspice "
                        "runner lets ngspice write only in its private folder and run nothing, "
                        f"so it does not take {name}: remove it (the runner returns ngspice's "
                        "results itself)",
                    )
            if is_model:
                for kind in sorted(words & FILE_MODELS.keys()):
                    raise _refusal(
                        line,
                        f"the XSPICE model {kind} reads the file its parameter "
                        f"{FILE_MODELS[kind]} names; the ngspice runner lets ngspice read no "
                        "file but its deck: give the waveform as a PWL source instead",
                    )
            for name in sorted(words & CIDER_FILE_PARAMETERS.keys()):
                raise _refusal(
                    line,
                    f"the CIDER parameter {name} {CIDER_FILE_PARAMETERS[name]}; the ngspice "
                    "runner lets ngspice read and write no file of the netlist's choosing: "
                    f"remove {name}",
                )


def _refusal(line: DeckLine, message: str) -> NetlistError:
    return NetlistError(message, file=line.file, line=line.number, text=line.text)


def hide_included(log: str, lines: list[DeckLine]) -> str:
    """``log`` with every line that quotes a line of an included file replaced by a note.

    Parameters
    ----------
    log : str
        ngspice's output (or a part of it).
    lines : list of DeckLine
        The deck it was given; lines with ``included`` set came from an included file (those
        of the package part library excepted: they are ours, not the user's).

    Returns
    -------
    str
        ``log``, each line holding a word of an included line (3 characters or more, not only
        digits, not a dot card's keyword and not found in the top netlist's lines) or a whole
        included line (blanks collapsed, any case) replaced by ``(ngspice's output quotes
        FILE:LINE here; an included file: not shown)``.
    """
    included = [line for line in lines if line.included and not _ours(line.file)]
    if not included:
        return log
    shown = set().union(*(_plain_words(line.text) for line in lines if not line.included))
    secret: dict[str, list[DeckLine]] = {}
    whole: list[tuple[str, DeckLine]] = []
    for line in included:
        words = {w for w in _plain_words(line.text) if len(w) >= _MIN_WORD and not w.isdigit()}
        first = line.text.split(maxsplit=1)
        if first and first[0].startswith("."):
            words -= _plain_words(first[0])  # .subckt, .model ...: SPICE's words, not the file's
        words -= shown
        for word in words:
            secret.setdefault(word, []).append(line)
        text = " ".join(_printable(line.text).split())
        if not words and len(text) >= 2 and len(whole) < _MAX_WHOLE_LINES:
            whole.append((text, line))
    out = []
    for entry in log.split("\n"):
        source = _quoted(entry, secret, whole)
        out.append(
            entry
            if source is None
            else f"(ngspice's output quotes {source.file}:{source.number} here; "
            "an included file: not shown)"
        )
    return "\n".join(out)


def _quoted(
    entry: str, secret: dict[str, list[DeckLine]], whole: Iterable[tuple[str, DeckLine]]
) -> DeckLine | None:
    """The included line ``entry`` quotes, if any (the one with most of its words)."""
    votes: dict[DeckLine, int] = {}
    for word in _plain_words(entry):
        for line in secret.get(word, ()):
            votes[line] = votes.get(line, 0) + 1
    if votes:
        return max(votes, key=lambda line: (votes[line], -line.number))
    seen = " ".join(_printable(entry).split())
    for text, line in whole:
        if text in seen:
            return line
    return None


@functools.lru_cache(maxsize=256)
def _ours(file: str) -> bool:
    """``file`` is in the package part library (not the user's: nothing to hide)."""
    from circuitsim.netlist.reader import LIBRARY_DIR

    try:
        return Path(file).resolve().is_relative_to(LIBRARY_DIR.resolve())
    except (OSError, ValueError):
        return False
