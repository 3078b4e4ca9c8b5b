"""The op-amp input-error options ``--opamp-offset`` and ``--opamp-bias`` (generate, compare,
tolerance): ``[SECTION=]VALUE`` with SPICE suffixes, repeatable, a bare value for every
section."""

from __future__ import annotations

import argparse
import math

from circuitsim.cli.common import UsageError
from circuitsim.netlist.values import parse_value


def section_value(text: str) -> tuple[str, float]:
    """``[SECTION=]VALUE``: the section name (``"*"`` without one) and a finite number.

    Raises
    ------
    argparse.ArgumentTypeError
        An empty name or a value that is not a finite SPICE number.
    """
    name, sep, value = text.rpartition("=")
    name = name.strip() if sep else "*"
    try:
        number = parse_value(value)
        if not name or not math.isfinite(number):
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected [SECTION=]VALUE (U1A=3m, or 3m for every section), got {text!r}"
        ) from None
    return name, number


def add_opamp_error_options(parser: argparse.ArgumentParser) -> None:
    """``--opamp-offset`` and ``--opamp-bias`` (both need ``--opamp tl074``)."""
    parser.add_argument(
        "--opamp-offset",
        type=section_value,
        action="append",
        default=[],
        metavar="[SECTION=]VOLTS",
        help="input offset voltage of a TL074 section (U1A=3m) or of every section (3m; "
        "datasheet typical 3 mV); repeatable, a named section overrides the bare value "
        "(needs --opamp tl074; default none)",
    )
    parser.add_argument(
        "--opamp-bias",
        type=section_value,
        action="append",
        default=[],
        metavar="[SECTION=]AMPS",
        help="input bias current into each input of a TL074 section (U1A=30p) or of every "
        "section (30p, the datasheet typical); repeatable (needs --opamp tl074; default none)",
    )


def opamp_errors(args: argparse.Namespace) -> dict[str, dict[str, float]]:
    """``{"opamp_offset": ..., "opamp_bias": ...}`` for SynthesisOptions, checked.

    Raises
    ------
    UsageError
        An offset or bias given with an op-amp other than tl074.
    """
    offsets, bias = dict(args.opamp_offset), dict(args.opamp_bias)
    if (offsets or bias) and args.opamp != "tl074":
        given = "--opamp-offset" if offsets else "--opamp-bias"
        raise UsageError(
            f"{given} needs --opamp tl074 (the {args.opamp} op-amp has no input errors)"
        )
    return {"opamp_offset": offsets, "opamp_bias": bias}
