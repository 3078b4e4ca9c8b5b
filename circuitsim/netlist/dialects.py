"""What differs between the SPICE dialects the writer emits: ngspice, LTspice, Multisim.

Each :class:`Dialect` is plain data read by :mod:`circuitsim.netlist.writer`; the sources of
each rule (and which rules could not be tried here) are listed in docs/netlists.md.

- ngspice (tested live, ngspice 39): ``**`` and ``^`` both raise to a power; in ``.param``
  expressions ``log`` is the natural logarithm (checked: ``{log(100)}`` gives 4.60517), so the
  writer spells it ``ln``; ``.subckt ... params: a=1`` with defaults; ``.control`` blocks.
- LTspice (published help, not run here): ``^`` is Boolean XOR, ``**`` is the power operator;
  ``ln``/``log`` natural, ``log10``; switch model parameters written ``Ron Roff Vt Vh``; no
  ``.control`` blocks; ``.options plotwinsize=0`` (no lossy waveform compression).
- Multisim (SPICE3f5/XSPICE based, not run here; NI's "Compatibility Modes" help): ``**`` is
  the power operator in its default mode (``^`` too, but ``^`` turns into XOR under
  ``.SYNTAX PS``), ``log`` is natural in ``.param`` but base 10 in B sources and in MS/XS mode,
  so ``ln`` again; subcircuit instances take PSpice's ``params:`` keyword; node names are kept
  to letters, digits and ``_``; no ``.control`` blocks.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from circuitsim.netlist.errors import NetlistError


@dataclass(frozen=True)
class Dialect:
    """The spelling rules of one simulator's netlist language.

    Attributes
    ----------
    name : str
        ``"ngspice"``, ``"ltspice"`` or ``"multisim"``.
    power : str
        The operator written for "raise to a power" in ``{...}`` expressions.
    control_blocks : bool
        Whether ``.control`` ... ``.endc`` blocks are understood (ngspice only).
    model_param_names : dict of (str, str) to str
        ``(model kind, lower-case parameter)`` to the spelling written; others are written in
        lower case.
    instance_params_keyword : bool
        Whether ``X`` lines write ``params:`` before their ``name=value`` pairs.
    node_pattern : str
        Regular expression a node name must match in full; others are renamed.
    width : int
        Longest line written before breaking onto a ``+`` continuation line (characters).
    options : tuple of (str, str)
        ``.options`` the dialect always writes (unless the circuit sets them itself), such as
        LTspice's ``plotwinsize=0``, which turns off its lossy waveform compression.
    print_card : bool
        Whether the writer's output nodes also get a ``.print tran`` line beside ``.save``:
        ngspice in batch mode (``ngspice -b FILE``, no ``-r``) runs no analysis without a
        ``.print`` and prints its table; gnucap reads the same line. LTspice has no
        ``.print`` (its help lists ``.save`` only); it and Multisim write a rawfile of the
        saved vectors.
    """

    name: str
    power: str
    control_blocks: bool
    model_param_names: dict[tuple[str, str], str] = field(default_factory=dict)
    instance_params_keyword: bool = False
    node_pattern: str = r"[A-Za-z0-9_.\-+:#!<>\[\]/]+"
    width: int = 80
    options: tuple[tuple[str, str], ...] = ()
    print_card: bool = False


DIALECTS: dict[str, Dialect] = {
    "ngspice": Dialect(name="ngspice", power="**", control_blocks=True, print_card=True),
    "ltspice": Dialect(
        name="ltspice",
        power="**",
        control_blocks=False,
        model_param_names={
            ("SW", "ron"): "Ron",
            ("SW", "roff"): "Roff",
            ("SW", "vt"): "Vt",
            ("SW", "vh"): "Vh",
        },
        # LTspice compresses waveforms lossily unless plotwinsize=0 (its help, .OPTIONS:
        # "Number of data points to compress in one window. Set to zero to disable
        # compression"); our results are post-processed, so compression is off.
        options=(("plotwinsize", "0"),),
    ),
    "multisim": Dialect(
        name="multisim",
        power="**",
        control_blocks=False,
        model_param_names={
            ("SW", "ron"): "RON",
            ("SW", "roff"): "ROFF",
            ("SW", "vt"): "VT",
            ("SW", "vh"): "VH",
        },
        instance_params_keyword=True,
        node_pattern=r"[A-Za-z0-9_]+",
    ),
}


def get_dialect(name: str) -> Dialect:
    """The dialect called ``name`` (case-insensitive); NetlistError naming the choices if none."""
    try:
        return DIALECTS[name.lower()]
    except KeyError:
        choices = ", ".join(DIALECTS)
        raise NetlistError(f"unknown dialect {name!r}; choose one of {choices}") from None


# A power operator (``**`` before ``*`` so the longest match wins) or an identifier followed
# by an opening parenthesis (a function call).
_POWER_OR_CALL = re.compile(r"\*\*|\^|\b([A-Za-z_][A-Za-z0-9_]*)(\s*\()")


def rewrite_expression(text: str, dialect: Dialect) -> str:
    """The expression ``text`` (no braces) spelled for ``dialect``.

    ``log(x)`` becomes ``ln(x)`` (our expressions, like ngspice's ``.param``, read ``log`` as
    the natural logarithm; LTspice agrees but SPICE3-derived tools do not, so the unambiguous
    name is written), and both power operators become ``dialect.power``.
    """

    def replace(match: re.Match) -> str:
        if match.group(1) is None:
            return dialect.power
        name = match.group(1)
        if name.lower() == "log":
            return "ln("
        return match.group(0)

    return _POWER_OR_CALL.sub(replace, text)


def model_param_name(kind: str, param: str, dialect: Dialect) -> str:
    """The spelling of model parameter ``param`` of a ``kind`` model in ``dialect``."""
    return dialect.model_param_names.get((kind.upper(), param.lower()), param.lower())
