"""Case folding of SPICE names and keywords the way ngspice does it: ASCII letters only.

ngspice lower-cases a netlist with C's ``tolower``, which changes ``A``-``Z`` and nothing
else, so ``K`` (U+212A KELVIN SIGN) and ``k`` are two different nodes there. Python's
``str.lower`` maps the Kelvin sign to ``k`` (and ``İ`` to two characters), which would merge
nodes ngspice keeps apart; every comparison of names in this package goes through
:func:`fold` instead.
"""

from __future__ import annotations

__all__ = ["fold"]


def fold(text: str) -> str:
    """``text`` with the ASCII capitals ``A``-``Z`` lowered and every other character kept.

    >>> fold("R1") , fold("\\u212a") == "k"
    ('r1', False)
    """
    if text.isascii():
        return text.lower()
    return "".join(ch.lower() if "A" <= ch <= "Z" else ch for ch in text)
