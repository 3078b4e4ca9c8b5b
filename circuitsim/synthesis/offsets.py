"""Input offset voltage and bias current of the op-amp sections, and what they cost.

A real TL074 section has an input offset voltage of a few millivolts and input bias currents
of tens of picoamperes (the library's ``TL074`` subcircuit takes them as the parameters
``vos``, ``ib`` and ``ios``; docs/parts.md). In an analog computer an offset at an
integrator's input is a constant input to that state's equation, so it shifts the state's
equilibrium; how much that matters depends on the volts per unit of the scaling: with the
paper's unity scaling (1 V per metre) a 3 mV offset is 3 mm of a displacement that swings by a
few centimetres.

Two things live here:

- :func:`apply_opamp_errors` sets the parameters on the sections of a generated circuit, by the
  paper's section names (``U1A``) or ``*`` for every section not named;
- :func:`offset_shift` measures, on the circuit itself, the equilibrium shift of every state
  that given offsets cause: the DC operating point with the offsets minus the one without
  (capacitors open: every integrator's summing junction carries no net current, which is the
  realized model's equilibrium ``A x + b = 0`` with the offsets' constant inputs in ``b``).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from dataclasses import dataclass

from circuitsim.netlist.circuit import Circuit, SubcircuitCall
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.opamps import SUBCIRCUIT_OF_KIND
from circuitsim.synthesis.scalemap import ScaleMap

#: Datasheet-typical input errors of a TL074C section at 25 C (Motorola/ON Semiconductor
#: TL071C/TL072C/TL074C data sheet, "Electrical characteristics", VCC = +/-15 V, VCM = 0):
#: input offset voltage 3.0 mV typical (10 mV max), input bias current 30 pA typical (200 pA
#: max), input offset current 5.0 pA typical (50 pA max).
TL074_TYPICAL_OFFSET = 3e-3
TL074_TYPICAL_BIAS = 30e-12
TL074_TYPICAL_OFFSET_CURRENT = 5e-12

ALL_SECTIONS = "*"
"""The key that sets every section not named on its own."""

_PARAMETER = {"offset": "vos", "bias": "ib", "offset_current": "ios"}
_TL074 = SUBCIRCUIT_OF_KIND["tl074"].lower()


def opamp_sections(circuit: Circuit) -> dict[str, SubcircuitCall]:
    """The op-amp sections of ``circuit`` by section name (``"U1A"`` for call ``XU1A``),
    upper case, in netlist order."""
    kinds = {name.lower() for name in SUBCIRCUIT_OF_KIND.values()} | {"opamp_offset_estimate"}
    return {
        e.name[1:].upper(): e
        for e in circuit.elements
        if isinstance(e, SubcircuitCall) and e.subcircuit.lower() in kinds
    }


def check_section_values(values: Mapping[str, float], what: str, unit: str) -> None:
    """SynthesisError unless every value of ``values`` (section name to ``unit``) is finite."""
    for name, value in values.items():
        if not (isinstance(value, int | float) and math.isfinite(value)):
            raise SynthesisError(
                f"op-amp {what} {name}={value!r}: must be a finite number of {unit}"
            )


def apply_opamp_errors(
    circuit: Circuit,
    offsets: Mapping[str, float] | None = None,
    bias: Mapping[str, float] | None = None,
    offset_current: Mapping[str, float] | None = None,
) -> None:
    """Set input offset voltage and bias currents on the TL074 sections of ``circuit``.

    Parameters
    ----------
    circuit : Circuit
        Changed in place: each named section's call gets ``vos``, ``ib``, ``ios``.
    offsets : mapping of str to float, optional
        Section name (``"U1A"``, case-insensitive, with or without the call's ``X``) or
        ``"*"`` (every section not named) to input offset voltage, volts.
    bias : mapping of str to float, optional
        The same keys to input bias current into each input pin, amperes.
    offset_current : mapping of str to float, optional
        The same keys to input offset current, amperes (in+ draws ib + ios/2, in- ib - ios/2).

    Raises
    ------
    SynthesisError
        A name that is no op-amp section of the circuit (the message lists them), a value that
        is not finite, or a non-zero value for an ideal op-amp (it has no input errors).
    """
    sections = opamp_sections(circuit)
    given = {"offset": offsets or {}, "bias": bias or {}, "offset_current": offset_current or {}}
    for what, values in given.items():
        unit = "volts" if what == "offset" else "amperes"
        check_section_values(values, what.replace("_", " "), unit)
        by_name = {_section_key(k): float(v) for k, v in values.items()}
        unknown = [k for k in by_name if k != ALL_SECTIONS and k not in sections]
        if unknown:
            raise SynthesisError(
                f"op-amp {what.replace('_', ' ')} for {', '.join(unknown)}: no such op-amp "
                f"section (the circuit has {', '.join(sections) or 'none'})"
            )
        default = by_name.get(ALL_SECTIONS)
        for name, call in sections.items():
            value = by_name.get(name, default)
            if value is None:
                continue
            if call.subcircuit.lower() != _TL074:
                if value != 0:
                    raise SynthesisError(
                        f"op-amp {what.replace('_', ' ')} for {name}: an ideal op-amp has no "
                        "input errors; generate with the tl074 op-amp (--opamp tl074)"
                    )
                continue
            call.params[_PARAMETER[what]] = value


def _section_key(name: str) -> str:
    key = str(name).strip().upper()
    return key[1:] if key.startswith("X") and len(key) > 1 and key != ALL_SECTIONS else key


@dataclass(frozen=True)
class OffsetShift:
    """How far given op-amp offsets move each state's equilibrium.

    Attributes
    ----------
    offset : float
        The input offset voltage put on every section, volts.
    shift : dict of str to float
        Per state, the equilibrium shift in the state's unit (signed).
    volts : dict of str to float
        The same at the state's node, volts.
    """

    offset: float
    shift: dict[str, float]
    volts: dict[str, float]

    def percent_of(self, ranges: Mapping[str, float]) -> dict[str, float]:
        """|shift| in % of each state's range (its unit; states without a range left out)."""
        return {
            s: 100.0 * abs(v) / ranges[s] for s, v in self.shift.items() if ranges.get(s, 0) > 0
        }


#: The op-amp of the offset estimate: the ideal op-amp (a gain-1e6 VCVS) with the TL074's
#: offset source in series with in+. The equilibrium shift does not depend on the op-amp's
#: dynamics, and two unknowns per section keep the estimate cheap on a 128-mass chain.
OFFSET_ESTIMATE_OPAMP = """.subckt OPAMP_OFFSET_ESTIMATE inp inm out params: vos=0
VOS inp1 inp {vos}
EOUT out 0 inp1 inm 1e6
.ends OPAMP_OFFSET_ESTIMATE
"""


def with_offset_sources(circuit: Circuit) -> Circuit:
    """A copy of ``circuit`` whose op-amp sections (ideal or TL074) are
    :data:`OFFSET_ESTIMATE_OPAMP`, connections kept, without analyses."""
    from circuitsim.netlist.reader import parse_netlist

    model = parse_netlist(f"* offset estimate\n{OFFSET_ESTIMATE_OPAMP}.end\n")
    name, subckt = next(iter(model.subcircuits.items()))
    result = copy.deepcopy(circuit)
    result.analyses = []
    sections = {id(call) for call in opamp_sections(result).values()}
    for k, e in enumerate(result.elements):
        if id(e) in sections:
            inp, inm, out = e.connections[0], e.connections[1], e.connections[-1]
            result.elements[k] = SubcircuitCall(e.name, (inp, inm, out), subckt.name, {})
    result.subcircuits[name] = subckt
    return result


def offset_shift(circuit: Circuit, scale_map: ScaleMap, offset: float) -> OffsetShift:
    """The equilibrium shift of every state when every op-amp section has input offset
    ``offset`` (volts), measured as two DC operating points of the circuit (its sections
    replaced by :data:`OFFSET_ESTIMATE_OPAMP`).

    Parameters
    ----------
    circuit : Circuit
        A generated circuit (its ``.tran`` and initial conditions are not used).
    scale_map : ScaleMap
        Its state nodes and volts per unit.
    offset : float
        Volts, on every section at once (the same sign: the shifts of a linear part add).

    Returns
    -------
    OffsetShift

    Raises
    ------
    SolverError
        The operating point did not converge.
    """
    from circuitsim.solver import operating_point

    base = with_offset_sources(circuit)
    shifted = copy.deepcopy(base)
    for call in opamp_sections(shifted).values():
        call.params["vos"] = float(offset)
    nodes = {s: scale.node.lower() for s, scale in scale_map.states.items()}
    probes = [f"v({n})" for n in nodes.values()]
    at_rest = operating_point(base).signals
    moved = operating_point(shifted).signals
    volts = {s: float(moved[p][-1] - at_rest[p][-1]) for s, p in zip(nodes, probes, strict=True)}
    shift = {s: v / scale_map.states[s].volts_per_unit for s, v in volts.items()}
    return OffsetShift(offset, shift, volts)


def kink_volts(system, scale_map: ScaleMap) -> list[tuple[str, float]]:
    """Each kink of the model's piecewise-linear terms as the voltage its block must resolve:
    ``alpha * |offset|`` with ``alpha = min_j G_j / |row_j|`` over the states of the kink's
    argument (the scale of the argument summer, :mod:`circuitsim.synthesis.pwl`), volts.

    Returns
    -------
    list of (str, float)
        (term name, volts) per kink with a non-zero offset.
    """
    G = [scale_map.states[s].volts_per_unit for s in system.states]
    found = []
    for term in system.nonlinear:
        for piece in term.abs_terms:
            used = [j for j, r in enumerate(piece.row) if r != 0]
            if piece.offset == 0 or not used:
                continue
            alpha = min(G[j] / abs(float(piece.row[j])) for j in used)
            found.append((term.name, alpha * abs(float(piece.offset))))
    return found


SHOWN_STATES = 3
"""States a warning names (the largest shifts first)."""


def offset_warning(
    synthesis, system, offset: float = TL074_TYPICAL_OFFSET, threshold: float = 0.01
) -> str | None:
    """A warning when an input offset of ``offset`` volts on every op-amp section matters at
    the synthesis' scaling, or None.

    It matters when it shifts some state's equilibrium by more than ``threshold`` of the
    state's predicted peak (:func:`offset_shift`, measured on the circuit) or when it is more
    than ``threshold`` of the voltage at which a piecewise-linear term's kink sits
    (:func:`kink_volts`): the |x| blocks then bend at the wrong place.

    Parameters
    ----------
    synthesis : Synthesis
        Its circuit, scale map and predicted node peaks (no peaks: only the kinks are judged).
    system : System
        The model the circuit realizes.
    offset : float
        Volts (default the TL074's datasheet-typical 3 mV).
    threshold : float
        Relative size that is reported (default 1 %).
    """
    sm = synthesis.scale_map
    parts = []
    peaks = {
        s: synthesis.node_peaks[scale.node] / scale.volts_per_unit
        for s, scale in sm.states.items()
        if synthesis.node_peaks.get(scale.node, 0) > 0
    }
    if peaks:
        shift = offset_shift(synthesis.circuit, sm, offset)
        large = sorted(
            ((p, s) for s, p in shift.percent_of(peaks).items() if p > 100 * threshold),
            reverse=True,
        )
        for percent, state in large[:SHOWN_STATES]:
            unit = sm.states[state].unit
            size = f"{percent:.3g} %" if percent < 1e4 else "over 100 times"
            parts.append(
                f"{state}'s equilibrium by {abs(shift.shift[state]):.3g} {unit} "
                f"({size} of its peak {peaks[state]:.3g} {unit})"
            )
        if len(large) > SHOWN_STATES:
            parts.append(f"{len(large) - SHOWN_STATES} more states' by over {100 * threshold:g} %")
    worst: dict[str, float] = {}
    for name, volts in kink_volts(system, sm):
        worst[name] = min(worst.get(name, math.inf), volts)
    for name, volts in worst.items():
        if offset > threshold * volts:
            parts.append(
                f"the {name} term's kinks (at {volts * 1e3:.3g} mV) by {100 * offset / volts:.3g} %"
            )
    if not parts:
        return None
    return (
        f"op-amp input offsets matter at this scaling: {offset * 1e3:g} mV on every section "
        f"(a typical TL074's) moves {'; '.join(parts)}. Auto scaling (--scaling auto) makes "
        "the signals volts, not millivolts; docs/tolerances.md"
    )
