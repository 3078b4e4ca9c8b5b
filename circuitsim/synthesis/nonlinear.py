"""Piecewise-linear blocks from op-amps and diodes: precision |x| and the dead zone.

Both are built from the precision half-wave stage: an inverting amplifier whose feedback goes
through one diode while the other diode catches the output when the input has the other sign,
so the diode drops sit inside the loop and the kink is sharp (to about the op-amp's error).
With input current u / R into the summing junction ``s``, resistor R from ``s`` to the stage
output ``h`` and the op-amp output ``o``::

    "max" orientation:  diode o -> s  and  diode h -> o      h = -max(u, 0)
    "min" orientation:  diode s -> o  and  diode o -> h      h = -min(u, 0)

(``a -> b``: anode a, cathode b.) An inverting summer then adds the pieces. All op-amps have
their non-inverting input grounded; the blocks work with ``ideal`` and ``tl074`` sections
(:mod:`circuitsim.synthesis.opamps`) and the 1N4148-like diode.

Names are formed from ``prefix`` (upper case as given) so the translator can keep its own
names for the integrators: op-amp sections ``X<prefix>A``, ``X<prefix>B``, ``X<prefix>C``;
resistors ``R<prefix>_1``, ``R<prefix>_2`` ...; diodes ``D<prefix>_1`` ...; bias sources
``V<prefix>_B`` (|x| offset) or ``V<prefix>_P`` / ``V<prefix>_N`` (dead zone, +eta and -eta);
internal nodes ``<prefix lower>_s1``, ``_h1`` ... E.g. prefix ``"ABS1"`` gives XABS1A, XABS1B,
RABS1_1 .. RABS1_5, DABS1_1, DABS1_2 and nodes abs1_s1, abs1_o1, abs1_h1, abs1_s2.

Measured transfer curves and the zero-crossing glitch against frequency: docs/parts.md.
"""

from __future__ import annotations

import re

from circuitsim.netlist.circuit import Circuit, Diode, Resistor, VoltageSource
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.opamps import (
    SUPPLY_NODES,
    SUPPLY_VOLTS,
    add_opamp,
    check_kind,
    ensure_diode_model,
    ensure_supplies,
)

_PREFIX = re.compile(r"^[A-Za-z0-9_]+$")


def add_precision_abs(
    circuit: Circuit,
    prefix: str,
    input_node: str,
    output_node: str,
    resistance: float,
    kind: str,
    *,
    offset_volts: float = 0.0,
    sign: int = 1,
) -> list[str]:
    """Add a precision full-wave rectifier: v(out) = sign * |v(in) + offset_volts|.

    Two op-amp sections, two diodes: a precision half-wave stage (A) gives
    h = -max(u, 0) (sign +1) or h = -min(u, 0) (sign -1) with u = v(in) + offset_volts, and
    an inverting summer (B) with input resistors R (from the input and the offset) and R/2
    (from h) and feedback R gives out = -(u + 2 h) = sign * |u|.

    Parameters
    ----------
    circuit : Circuit
        Changed in place (elements, the diode model, the op-amp subcircuit, supplies).
    prefix : str
        Letters, digits, underscores; names are formed from it (module docstring).
    input_node, output_node : str
        Node names. The input sees the two input resistors R (load R/2 to virtual ground).
    resistance : float
        R, ohms (> 0). Every resistor is R except the summer's R/2.
    kind : {"ideal", "tl074"}
        Op-amp kind.
    offset_volts : float, optional
        Added to the input before rectifying, volts, through a DC source ``V<prefix>_B``
        and two more resistors R (one per stage). With it the flange form
        |y + eta| - |y - eta| needs no extra summing amplifier.
    sign : {1, -1}, optional
        +1: out = +|u|; -1: out = -|u| (both diodes reversed).

    Returns
    -------
    list of str
        The op-amp section names used, ``[X<prefix>A, X<prefix>B]``.

    Raises
    ------
    SynthesisError
        Bad prefix, resistance, kind or sign, or a name already used.
    """
    kind = check_kind(kind)
    _check_common(prefix, resistance)
    if sign not in (1, -1):
        raise SynthesisError(f"sign must be +1 or -1, got {sign!r}")
    p, n = prefix, prefix.lower()
    diode = ensure_diode_model(circuit)
    opamps = [f"X{p}A", f"X{p}B"]
    s1, o1, h1, s2 = f"{n}_s1", f"{n}_o1", f"{n}_h1", f"{n}_s2"
    r = float(resistance)
    circuit.add(Resistor(f"R{p}_1", input_node, s1, r), Resistor(f"R{p}_2", s1, h1, r))
    circuit.add(*_half_wave_diodes(p, 1, s1, o1, h1, diode, "max" if sign == 1 else "min"))
    add_opamp(circuit, opamps[0], "0", s1, o1, kind)
    circuit.add(
        Resistor(f"R{p}_3", input_node, s2, r),
        Resistor(f"R{p}_4", h1, s2, r / 2.0),
        Resistor(f"R{p}_5", s2, output_node, r),
    )
    if offset_volts:
        bias = f"{n}_b"
        circuit.add(
            VoltageSource(f"V{p}_B", bias, "0", dc=float(offset_volts)),
            Resistor(f"R{p}_6", bias, s1, r),
            Resistor(f"R{p}_7", bias, s2, r),
        )
    add_opamp(circuit, opamps[1], "0", s2, output_node, kind)
    return opamps


def add_dead_zone(
    circuit: Circuit,
    prefix: str,
    input_node: str,
    output_node: str,
    eta_volts: float,
    resistance: float,
    kind: str,
    *,
    bias: str = "sources",
) -> list[str]:
    """Add a dead zone: v(out) = 0 for |v(in)| <= eta, v(in) - eta above, v(in) + eta below.

    Three op-amp sections, four diodes: stage A (bias -eta, "max" diodes) gives
    h_p = -max(v(in) - eta, 0), stage B (bias +eta, "min" diodes) gives
    h_n = -min(v(in) + eta, 0), and an inverting summer C with three equal resistors gives
    out = -(h_p + h_n). The block is odd in its input, so -deadzone(y) is deadzone(-y): feed
    the inverted signal for the other sign. k * deadzone(y, eta) is the flange force
    k y - (k/2)(|y + eta| - |y - eta|) in one block.

    Parameters
    ----------
    circuit : Circuit
        Changed in place.
    prefix : str
        Letters, digits, underscores; names are formed from it (module docstring).
    input_node, output_node : str
        Node names.
    eta_volts : float
        Half-width of the dead zone, volts (> 0).
    resistance : float
        R, ohms (> 0): input, stage feedback and summer resistors.
    kind : {"ideal", "tl074"}
        Op-amp kind.
    bias : {"sources", "supplies"}, optional
        ``"sources"``: DC sources ``V<prefix>_P`` (+eta) and ``V<prefix>_N`` (-eta) feed the
        bias through resistors R (exact; works for both kinds). ``"supplies"``: the bias
        current comes from the +/-15 V supply nodes through R * 15 / eta (as one would build
        it; only with ``tl074``, whose supplies are in the circuit; the bias then follows
        the supply voltage).

    Returns
    -------
    list of str
        The op-amp section names used, ``[X<prefix>A, X<prefix>B, X<prefix>C]``.

    Raises
    ------
    SynthesisError
        Bad prefix, resistance, eta, kind or bias, or a name already used.
    """
    kind = check_kind(kind)
    _check_common(prefix, resistance)
    if not eta_volts > 0:
        raise SynthesisError(f"dead-zone half-width must be > 0 V, got {eta_volts!r}")
    if bias not in ("sources", "supplies"):
        raise SynthesisError(f"bias must be 'sources' or 'supplies', got {bias!r}")
    if bias == "supplies" and kind == "ideal":
        raise SynthesisError("bias from the supplies needs real op-amps (kind 'tl074' or 'lib:')")
    p, n = prefix, prefix.lower()
    r = float(resistance)
    diode = ensure_diode_model(circuit)
    opamps = [f"X{p}A", f"X{p}B", f"X{p}C"]
    if bias == "sources":
        plus, minus, r_bias = f"{n}_vp", f"{n}_vn", r
        circuit.add(
            VoltageSource(f"V{p}_P", plus, "0", dc=float(eta_volts)),
            VoltageSource(f"V{p}_N", minus, "0", dc=-float(eta_volts)),
        )
    else:
        ensure_supplies(circuit)
        plus, minus = SUPPLY_NODES
        r_bias = r * SUPPLY_VOLTS / float(eta_volts)
    s1, o1, h1 = f"{n}_s1", f"{n}_o1", f"{n}_h1"
    s2, o2, h2 = f"{n}_s2", f"{n}_o2", f"{n}_h2"
    s3 = f"{n}_s3"
    # Two mirrored biased half-wave stages: the first passes what exceeds +eta, the second
    # what falls below -eta (bias from the opposite supply rail).
    stages = ((1, minus, (s1, o1, h1), "max", opamps[0]), (4, plus, (s2, o2, h2), "min", opamps[1]))
    for first, rail, (s, o, h), side, section in stages:
        circuit.add(
            Resistor(f"R{p}_{first}", input_node, s, r),
            Resistor(f"R{p}_{first + 1}", rail, s, r_bias),
            Resistor(f"R{p}_{first + 2}", s, h, r),
        )
        circuit.add(*_half_wave_diodes(p, 1 + 2 * (first > 1), s, o, h, diode, side))
        add_opamp(circuit, section, "0", s, o, kind)
    circuit.add(
        Resistor(f"R{p}_7", h1, s3, r),
        Resistor(f"R{p}_8", h2, s3, r),
        Resistor(f"R{p}_9", s3, output_node, r),
    )
    add_opamp(circuit, opamps[2], "0", s3, output_node, kind)
    return opamps


def _half_wave_diodes(
    prefix: str, first: int, junction: str, opamp_out: str, out: str, model: str, which: str
) -> tuple[Diode, Diode]:
    """The two diodes of a precision half-wave stage, numbered ``first`` and ``first + 1``.

    ``"max"``: h = -max(u, 0) (the catch diode conducts for u < 0, the output diode for
    u > 0); ``"min"``: both reversed, h = -min(u, 0).
    """
    catch, through = f"D{prefix}_{first}", f"D{prefix}_{first + 1}"
    if which == "max":
        return Diode(catch, opamp_out, junction, model), Diode(through, out, opamp_out, model)
    return Diode(catch, junction, opamp_out, model), Diode(through, opamp_out, out, model)


def _check_common(prefix: str, resistance: float) -> None:
    if not isinstance(prefix, str) or not _PREFIX.match(prefix):
        raise SynthesisError(
            f"block prefix {prefix!r} must be letters, digits and underscores (e.g. 'ABS1')"
        )
    if not (isinstance(resistance, int | float) and resistance > 0):
        raise SynthesisError(
            f"block resistance must be a positive number of ohms, got {resistance!r}"
        )
