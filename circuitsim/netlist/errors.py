"""Errors raised while reading, writing or checking circuits."""

from __future__ import annotations

import re

MAX_WORD = 80
"""A run of non-blank characters longer than this is cut in a message (a 1 MB token once made
a 2 MB message)."""

MAX_LINE = 200
"""The offending source line is shown up to this many characters."""

_LONG_WORD = re.compile(rf"\S{{{MAX_WORD + 1},}}")


def shorten(text: str, limit: int = MAX_LINE) -> str:
    """``text`` with long words cut and the whole cut to ``limit`` characters, saying so."""
    text = _LONG_WORD.sub(lambda m: f"{m[0][: MAX_WORD // 2]}...({len(m[0])} characters)", text)
    if len(text) > limit:
        text = f"{text[:limit]}... ({len(text)} characters)"
    return text


class NetlistError(ValueError):
    """A netlist could not be read or a circuit is malformed.

    The message (``str(error)``) is ``file:line: message`` followed by the offending line; long
    words and lines are cut there (:func:`shorten`), while the attributes keep the whole text.

    Parameters
    ----------
    message : str
        What is wrong and what was expected.
    file : str, optional
        The netlist file (``"<string>"`` for text given directly).
    line : int, optional
        1-based line number in ``file`` (the first physical line of a continued line).
    text : str, optional
        The offending source text.
    """

    def __init__(
        self,
        message: str,
        file: str | None = None,
        line: int | None = None,
        text: str | None = None,
    ):
        self.message = message
        self.file = file
        self.line = line
        self.text = text
        where = file or "<netlist>"
        if line is not None:
            where = f"{where}:{line}"
        full = f"{where}: {shorten(message, 4 * MAX_LINE)}"
        if text:
            full += f"\n    {shorten(text.strip())}"
        super().__init__(full)

    def without_source_text(self) -> NetlistError:
        """The same error without the source line and with its words masked in the message.

        For errors in included files: the file may be anything the netlist names
        (``.include /etc/passwd``), and its content must not reach whoever sees the message.
        Words of the line (3 characters or longer) are replaced by ``<...>`` inside the
        message's quoted parts (where messages quote the source); file and line number stay,
        so the author can look the line up.
        """
        words = sorted(set(re.split(r"[\s(){}=,;'\"]+", self.text or "")), key=len, reverse=True)
        words = [w for w in words if len(w) >= 3]

        def mask(quoted: re.Match) -> str:
            part = quoted[0]
            for word in words:
                part = part.replace(word, "<...>")
            return part

        message = _QUOTED.sub(mask, self.message)
        if message != self.message:
            message += " (the line is not shown: an included file)"
        return NetlistError(message, self.file, self.line)


_QUOTED = re.compile(r"'[^']*'|\"[^\"]*\"")
