"""Physical lines to logical lines, and the file side of ``.include``/``.lib``.

Part of :mod:`circuitsim.netlist.reader` (whose docstring states the rules): continuation
lines joined, comments stripped, ``.control`` blocks set aside raw, reading stopped at
``.end``; include targets parsed, files read, ``.lib`` sections selected.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from circuitsim.inputfile import NETLIST_BYTES, InputTooLargeError, read_text
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.names import fold
from circuitsim.netlist.reader_elements import Line

__all__ = [
    "Control",
    "strip_comment",
    "logical_lines",
    "include_target",
    "read_file",
    "select_sections",
]


# --- physical lines to logical lines ------------------------------------------------------


@dataclass
class Control:
    """A raw ``.control`` ... ``.endc`` block."""

    line: Line
    text: str


def strip_comment(text: str) -> str:
    cut = text.find(";")
    if cut >= 0:
        text = text[:cut]
    # ngspice: '$' starts a comment at the start of a word (not inside a name like a$b)
    for i, ch in enumerate(text):
        if ch == "$" and (i == 0 or text[i - 1] in " \t,"):
            return text[:i]
    return text


def logical_lines(text: str, file: str, has_title: bool) -> tuple[str, list[Line | Control]]:
    """Join continuations, drop comments, set ``.control`` blocks aside, stop at ``.end``."""
    physical = text.splitlines()
    title = ""
    start = 0
    if has_title:
        title = physical[0].lstrip("\ufeff").strip() if physical else ""
        start = 1
    out: list[Line | Control] = []
    current: tuple[int, str] | None = None
    i = start
    while i < len(physical):
        number = i + 1
        raw = physical[i].lstrip("\ufeff") if i == 0 else physical[i]
        stripped = raw.strip()
        i += 1
        if not stripped or stripped.startswith("*"):
            continue
        if stripped.startswith("+"):
            if current is None:
                raise NetlistError(
                    "continuation line '+' with no line before it to continue",
                    file=file,
                    line=number,
                    text=raw,
                )
            current = (current[0], current[1] + " " + strip_comment(stripped[1:]))
            continue
        if current is not None:
            out.append(Line(file, current[0], current[1].strip()))
            current = None
        body = strip_comment(stripped).strip()
        if not body:
            continue
        keyword = fold(body.split()[0])
        if keyword == ".control":
            block: list[str] = []
            # ngspice ends the block at any line that starts with .endc (".endc;x", ".endcs"
            # too): matched the same way, so that no card is read into the block by mistake
            while i < len(physical) and not fold(physical[i].strip()).startswith(".endc"):
                block.append(physical[i].rstrip())
                i += 1
            if i >= len(physical):
                raise NetlistError(".control block without .endc", file=file, line=number, text=raw)
            i += 1
            out.append(Control(Line(file, number, body), "\n".join(block)))
            continue
        if keyword == ".end":
            _nothing_after_end(physical, i, file)
            break
        current = (number, body)
    if current is not None:
        out.append(Line(file, current[0], current[1].strip()))
    return title, out


def _nothing_after_end(physical: list[str], start: int, file: str) -> None:
    """Refuse cards after ``.end`` (from 0-based line ``start`` on): tools disagree on them.

    ngspice 39 turns ``.end`` into a comment and reads every line after it (measured: a
    resistor after ``.end`` changed v(b) from 0.5 to 0.001), while SPICE3 and LTspice stop
    at ``.end``. Blank lines, comments and further ``.end`` lines are allowed.
    """
    for index in range(start, len(physical)):
        body = strip_comment(physical[index].strip()).strip()
        if not body or body.startswith("*") or fold(body.split()[0]) == ".end":
            continue
        raise NetlistError(
            "a card after .end: ngspice reads the lines after .end while other SPICE "
            "simulators ignore them, so the netlist is ambiguous; move the card before .end "
            "or delete it",
            file=file,
            line=index + 1,
            text=physical[index],
        )


# --- include handling ---------------------------------------------------------------------


def include_target(line: Line, rest: str, what: str) -> tuple[str, str | None]:
    """The file (quotes removed) and, for ``.lib``, the optional section name."""
    rest = rest.strip()
    if not rest:
        raise line.error(f"{what} needs a file name")
    if rest[0] in "\"'":
        end = rest.find(rest[0], 1)
        if end < 0:
            raise line.error(f"unbalanced quote in {what} file name")
        path, tail = rest[1:end], rest[end + 1 :].split()
    else:
        parts = rest.split()
        path, tail = parts[0], parts[1:]
    if not path:
        raise line.error(f"{what} needs a file name")
    if len(tail) > 1 or (tail and what == ".include"):
        raise line.error(f"unexpected {' '.join(tail)!r} after the file name of {what}")
    return path, (fold(tail[0]) if tail else None)


def read_file(line: Line | None, path: Path, file: str) -> str:
    """The text of a netlist (``line`` None) or of the file ``line`` includes; at most
    :data:`~circuitsim.inputfile.NETLIST_BYTES` of it is read (a device too)."""
    try:
        return read_text(path, NETLIST_BYTES, "a netlist file")
    except InputTooLargeError as exc:
        if line is None:
            raise NetlistError(exc.reason, file=file) from None
        raise line.error(f"cannot read {path}: {exc.reason}") from None
    except (OSError, UnicodeDecodeError) as exc:
        if line is None:
            raise NetlistError(f"cannot read netlist: {exc}", file=file) from None
        raise line.error(f"cannot read {path}: {exc}") from None


def select_sections(
    lines: list[Line | Control], section: str | None, where: Line | None, path: Path
) -> list[Line | Control]:
    """Keep the lines outside ``.lib name``/``.endl`` sections, or only those of ``section``."""

    def lib_words(entry: Line | Control) -> list[str] | None:
        if isinstance(entry, Line):
            words = entry.text.split()
            if fold(words[0]) == ".lib" and len(words) == 2:
                return words
        return None

    # endl_after[i]: some .endl follows entry i (a suffix scan, so many .lib lines stay linear)
    endl_after = [False] * (len(lines) + 1)
    for index in range(len(lines) - 1, -1, -1):
        entry = lines[index]
        is_endl = isinstance(entry, Line) and fold(entry.text.split()[0]) == ".endl"
        endl_after[index] = endl_after[index + 1] or is_endl
    kept: list[Line | Control] = []
    inside: str | None = None
    found = False
    for index, entry in enumerate(lines):
        words = lib_words(entry)
        if inside is None and words is not None and endl_after[index + 1]:
            inside = fold(words[1])
            found = found or inside == section
            continue
        if isinstance(entry, Line) and fold(entry.text.split()[0]) == ".endl":
            if inside is None:
                raise entry.error(".endl without a .lib section before it")
            inside = None
            continue
        if (inside is None and section is None) or (inside is not None and inside == section):
            kept.append(entry)
    if section is not None and not found:
        assert where is not None
        raise where.error(f"library section {section!r} not found in {path}")
    return kept
