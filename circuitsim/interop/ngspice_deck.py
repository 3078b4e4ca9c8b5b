"""The deck ngspice is given: the netlist flattened, with nothing in it that ngspice runs.

ngspice executes front-end commands (``shell``, ``source``, ``codemodel``, ``osdi``, ...) from
an input deck in three ways (ngspice 39, ``src/frontend/inp.c``, ``inp_spsource``): every card
between a line starting ``.control`` and one starting ``.endc`` (compared by prefix and
ignoring case, so ``.controls`` or ``.control;x`` open a block as well), every line starting
``*#``, and the whole file when its first line starts ``*ng_script``. Included files are spliced
into the deck before that (``src/frontend/inpcom.c``, ``inp_read``), so a block inside an
``.include``d file or a ``.lib`` section runs as well, and so does one after ``.end``: ngspice
keeps reading after ``.end``.

So this module reads the netlist the way ngspice's ``readline`` does (lines end at ``\\n`` only;
every carriage return is removed, also inside a line, so ``.con\\rtrol`` is ``.control``;
leading blanks and tabs are removed; a NUL ends the line; a line starting ``@`` ends the file;
a line ending in ``\\\\`` continues on the next), splices the included files in itself, and
hands over only circuit lines:

* ``.include``/``.inc`` (ngspice takes every line starting ``.inc``) and ``.lib file section``
  are replaced by the file's lines (the section's), looked for as the netlist reader does:
  beside the including file, then in the package part library; the deck ngspice gets names no
  file at all;
* every ``.control`` ... ``.endc`` block (and the ``+`` lines continuing its first or last
  card) is dropped, in every file, and so is every comment line (``*``, hence ``*#`` and
  ``*ng_script``) and ``.title`` line;
* the first line (the title) is replaced by a fixed one; reading stops at the top file's
  ``.end`` (in an included file ``.end`` is dropped, as ngspice does).

A card that would make ngspice open a file (``.options measoutfile=...`` and the others
:mod:`circuitsim.interop.ngspice_files` lists) is refused, naming its file and line.
:func:`check_inert` checks the result once more, line by line, the way ngspice will see it.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from circuitsim.inputfile import DECK_BYTES, NETLIST_BYTES, InputTooLargeError, read_bytes
from circuitsim.interop.ngspice_files import refuse_file_names
from circuitsim.netlist.errors import NetlistError

__all__ = ["DeckLine", "TITLE", "flatten_deck", "check_inert", "decode"]

TITLE = "circuitsim deck for ngspice"
_MAX_DEPTH = 32  # nested includes: deeper than any real library, shallower than the C stack
_MAX_BYTES = DECK_BYTES  # all files of one deck together


@dataclass(frozen=True)
class DeckLine:
    """One physical line of the deck ngspice reads, and where it came from.

    ``text`` is the line as ngspice's reader delivers it (carriage returns and leading blanks
    removed); ``file`` and ``number`` (1-based) locate it in the user's files; ``included``
    is true for a line of an included file or library section (its text is never quoted in
    messages).
    """

    text: str
    file: str
    number: int
    included: bool = False


@dataclass
class _Reading:
    """What carries over from line to line and from file to file while flattening."""

    lines: list[DeckLine] = field(default_factory=list)
    in_control: bool = False  # inside a .control block: ngspice's ``commands`` flag
    absorbing: bool = False  # the last card was dropped: its "+" lines go with it
    continued: bool = False  # the previous line ended in "\\": this one continues it
    stack: list[tuple[str, str]] = field(default_factory=list)  # (file, section) being read
    size: int = 0  # bytes of all files read so far


def decode(data: bytes) -> str:
    """Bytes of a netlist as text; bytes that are not UTF-8 pass through unchanged."""
    return data.decode("utf-8", errors="surrogateescape")


def _physical_lines(text: str) -> list[str]:
    """``text`` split as ngspice's ``readline`` splits and trims it (inpcom.c)."""
    out = []
    for raw in text.split("\n"):
        line = raw.split("\0", 1)[0].replace("\r", "")
        out.append(line.lstrip(" \t"))
    if out and out[-1] == "":
        out.pop()
    return out


def _starts(line: str, word: str) -> bool:
    """ngspice's ``ciprefix``: ``line`` starts with ``word``, ignoring ASCII case."""
    return line[: len(word)].lower() == word


def flatten_deck(text: str, source: str, folder: Path) -> list[DeckLine]:
    """The circuit lines of a netlist, its includes spliced in, without anything ngspice runs.

    Parameters
    ----------
    text : str
        The netlist; its first line is the title (dropped: the deck gets :data:`TITLE`).
    source : str
        Its file name for messages (``"<string>"`` for text given directly).
    folder : Path
        Where its relative ``.include``/``.lib`` files are looked for first.

    Returns
    -------
    list of DeckLine
        The deck's lines after the title, up to the top file's ``.end``, as the module
        docstring describes.

    Raises
    ------
    NetlistError
        An include or library file is missing, unreadable, not a regular file, included by
        itself, nested deeper than 32 files, or all files together pass 256 MiB; a ``.lib``
        section is missing or has no ``.endl``; an ``.include`` names no file; a card makes
        ngspice open a file (:func:`~.ngspice_files.refuse_file_names`). When the line
        at fault is in an included file, its text is not shown (only file and line number).
    """
    reading = _Reading(size=len(text))
    try:
        _read_lines(reading, _physical_lines(text), source, folder, top=True)
        refuse_file_names(reading.lines)
    except NetlistError as error:
        if error.file not in (None, source) and error.text:
            # a line of an included file: that file may be anything (.include /etc/passwd),
            # its content is not shown (the reader's rule); file and line number stay
            raise error.without_source_text() from None
        raise
    return reading.lines


def _read_lines(reading: _Reading, lines: list[str], file: str, folder: Path, top: bool) -> None:
    """Append the circuit lines of one file (or library section) to ``reading.lines``."""
    for number, line in enumerate(lines, start=1):
        if top and number == 1:
            continue  # the title: never a card, and replaced by ours
        if line.startswith("@"):
            return  # ngspice stops reading the file here
        if _starts(line, ".control") or _starts(line, ".endc"):
            reading.in_control = _starts(line, ".control")
            reading.absorbing = True
            reading.continued = False
            continue
        if _is_end(line):
            if top:
                return  # nothing after .end reaches ngspice
            continue  # ngspice turns .end in an included file into a comment
        if reading.in_control or not line or line.startswith("*") or _starts(line, ".title"):
            reading.continued = reading.continued and not line  # blank lines keep it
            continue
        where = DeckLine(line, file, number, included=not top)
        if _starts(line, ".inc"):
            reading.continued = False
            _include(reading, where, folder)
            continue
        if _starts(line, ".lib") and len(_lib_words(line)) >= 2:
            reading.continued = False
            _library_section(reading, where, folder)
            continue
        _keep(reading, where)


def _keep(reading: _Reading, where: DeckLine) -> None:
    """Append an ordinary line, applying ngspice's ``\\\\`` and ``+`` continuation rules."""
    text = where.text
    if reading.continued:
        text = "+" + text
        reading.continued = False
    if text.startswith("+"):
        if reading.absorbing:
            return  # continues a dropped card
    elif not text.startswith(("#", "$")):  # ngspice's stitching skips these like comments
        reading.absorbing = False
    if not text.startswith("$"):
        stripped = text.rstrip(" \t")
        if stripped.endswith("\\\\"):  # ngspice: the next line becomes a "+" line
            text = stripped[:-2]
            reading.continued = True
    reading.lines.append(DeckLine(text, where.file, where.number, where.included))


def _is_end(line: str) -> bool:
    """The deck's ``.end`` card (not ``.ends``, ``.endc``, ``.endl``, ...)."""
    return re.match(r"\.end(?![a-z0-9_])", line, re.IGNORECASE) is not None


def _strip_comment(line: str) -> str:
    """``line`` without its end-of-line comment, as ngspice's ``inp_stripcomments_line``."""
    for index in range(1, len(line)):
        if line[index] == ";":
            return line[:index]
        if line[index] == "$" and line[index - 1] in " ,\t":
            return line[:index]
        if line.startswith("//", index - 1):
            return line[: index - 1]
    return line


def _include_name(where: DeckLine) -> str:
    """The file an ``.include`` line names (ngspice's ``get_quoted_token``)."""
    rest = _strip_comment(where.text).split(maxsplit=1)
    rest_text = rest[1].strip() if len(rest) > 1 else ""
    if rest_text[:1] in ("'", '"'):
        end = rest_text.find(rest_text[0], 1)
        name = rest_text[1:end] if end > 0 else ""
    else:
        name = rest_text.split(maxsplit=1)[0] if rest_text else ""
    if not name:
        raise _error(where, ".include needs a file name (in quotes if it has blanks)")
    return name


def _lib_words(line: str) -> list[str]:
    """The words after ``.lib``, split at blanks and quotes as ngspice's ``.lib`` code does."""
    return [w for w in re.split(r"[\s\"']+", line)[1:] if w]


def _resolve(where: DeckLine, name: str, folder: Path) -> Path:
    """The include file ``name``: beside the including file, then in the part library."""
    from circuitsim.netlist.reader import LIBRARY_DIR

    given = Path(os.path.expanduser(name)) if name.startswith("~") else Path(name)
    tried = [given] if given.is_absolute() else [folder / given, LIBRARY_DIR / given]
    for candidate in tried:
        try:
            found, regular = candidate.exists(), candidate.is_file()
        except (OSError, ValueError):  # a name no file system takes (too long, a NUL)
            continue
        if found and not regular:  # a folder, a FIFO, /dev/zero: nothing to splice in
            raise _error(where, f"include file {name!r} is not a regular file ('{candidate}')")
        if found:
            return candidate.resolve()
    looked = " or ".join(f"'{t}'" for t in tried)  # quoted: masked if from an include
    raise _error(where, f"include file {name!r} not found (looked for {looked})")


def _open(reading: _Reading, where: DeckLine, path: Path, section: str) -> list[str]:
    """The physical lines of an include file, checked against cycles, depth and size."""
    key = (str(path), section)
    if key in reading.stack or len(reading.stack) >= _MAX_DEPTH:
        chain = " -> ".join(f"'{f}'" for f, _ in [*reading.stack, key])
        raise _error(where, f"include cycle or nesting deeper than {_MAX_DEPTH}: {chain}")
    try:
        size = path.stat().st_size
        if reading.size + size > _MAX_BYTES:
            raise _error(where, f"the included files pass {_MAX_BYTES // 2**20} MiB ('{path}')")
        data = read_bytes(path, NETLIST_BYTES, "a netlist file")
    except InputTooLargeError as exc:
        raise _error(where, f"cannot read '{path}': {exc.reason}") from None
    except OSError as exc:
        raise _error(where, f"cannot read '{path}': {exc.strerror or exc}") from None
    if reading.size + len(data) > _MAX_BYTES:  # a file that grew since its size was asked
        raise _error(where, f"the included files pass {_MAX_BYTES // 2**20} MiB ('{path}')")
    reading.size += len(data)
    return _physical_lines(decode(data))


def _include(reading: _Reading, where: DeckLine, folder: Path) -> None:
    path = _resolve(where, _include_name(where), folder)
    lines = _open(reading, where, path, "")
    reading.stack.append((str(path), ""))
    try:
        _read_lines(reading, lines, str(path), path.parent, top=False)
    finally:
        reading.stack.pop()


def _library_section(reading: _Reading, where: DeckLine, folder: Path) -> None:
    """Splice in the lines of ``.lib file section``'s section (without its .lib/.endl)."""
    name, section = _lib_words(where.text)[:2]
    path = _resolve(where, name, folder)
    lines = _open(reading, where, path, section.lower())
    cut = next((i for i, line in enumerate(lines) if line.startswith("@")), len(lines))
    lines = lines[:cut]  # ngspice read the library file only up to an "@" line
    start = next(
        (
            i
            for i, line in enumerate(lines)
            if _starts(line, ".lib") and [w.lower() for w in _lib_words(line)] == [section.lower()]
        ),
        None,
    )
    if start is None:
        raise _error(where, f"library section {section!r} not found in '{path}'")
    stop = next((i for i in range(start + 1, len(lines)) if _starts(lines[i], ".endl")), None)
    if stop is None:
        raise _error(where, f"library section {section!r} in '{path}' has no .endl")
    body = [""] * (start + 1) + lines[start + 1 : stop]  # blank lines keep the line numbers
    reading.stack.append((str(path), section.lower()))
    try:
        _read_lines(reading, body, str(path), path.parent, top=False)
    finally:
        reading.stack.pop()


def _error(where: DeckLine, message: str) -> NetlistError:
    return NetlistError(message, file=where.file, line=where.number, text=where.text)


def check_inert(lines: list[str]) -> None:
    """Refuse a deck in which ngspice would run a command or read a file.

    Parameters
    ----------
    lines : list of str
        The deck's lines after the title and before our own control block.

    Raises
    ------
    RuntimeError
        A line ngspice would read as a control block marker, a ``*#`` command, an include,
        a library reference or the end of its input (a defect of :func:`flatten_deck`, never
        of the user's netlist).
    """
    for text in lines:
        seen = text.split("\0", 1)[0].replace("\r", "").lstrip(" \t")
        bad = (
            "\n" in text
            or seen.startswith(("*", "@"))
            or any(_starts(seen, w) for w in (".control", ".endc", ".inc", ".title"))
            or (_starts(seen, ".lib") and len(_lib_words(seen)) >= 2)
        )
        if bad:
            raise RuntimeError(f"the ngspice deck still holds a line ngspice acts on: {text!r}")
