"""The speed knob: resistors that follow a model parameter, as a potentiometer plus a fixed part.

The paper turns the wheelset's speed V by hand: c_y = 7.24e6 / V and c_psi = 4.36e6 / V set the
integrator gains through R33 and R44, and a resistor into an integrator sets its coefficient as
1 / (R C), so R33 and R44 are proportional to V. Which resistors follow the parameter is read
from the model itself, not from a list: every entry A[i, j] of the linear part is evaluated at
the ends of the range and at points between, and each entry that changes (keeping its sign)
gets a knob. Each such resistor becomes a fixed standard resistor ``<name>A`` in series with a
linear potentiometer wired as a variable resistor ``<name>P`` (wiper to one end), whose
rotation fraction f gives

    R(V) = R_fixed + f P,    f(V) = (R(V) - R_fixed) / P,

with R(V) the resistor that realizes A[i, j] at V exactly (the capacitor and the scaling stay
as they are). P is the smallest member of the potentiometer series (E3 or E6) that spans the
range, R_fixed the standard value that puts the range's middle nearest the middle of the
rotation; the fractions at the range's ends are the margins the dial keeps (f > 0 at the low
end and f < 1 at the high end, so a pot's 20 % tolerance on P can be trimmed in the dial). The
netlist holds the potentiometer at its setting for the simulated value.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from circuitsim.mechanics.system import System
from circuitsim.netlist.circuit import Resistor
from circuitsim.synthesis.blocks import BomEntry
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.eseries import SERIES, _decade, _standard, round_to_series
from circuitsim.synthesis.naming import PartNames

#: Potentiometer values per decade (linear taper, as sold).
POT_SERIES = {
    "E3": (1.0, 2.2, 4.7),
    "E6": (1.0, 1.5, 2.2, 3.3, 4.7, 6.8),
}

#: Parameter values sampled between the ends to find the resistors' extremes.
SAMPLES = 61


@dataclass(frozen=True)
class KnobRequest:
    """What the caller asks for: the parameter, its range, how to evaluate the model there.

    Attributes
    ----------
    parameter : str
        Model parameter the knob turns (``"V"``).
    low, high : float
        The range the dial covers (parameter units, low < high).
    linear_part : callable(float) -> ndarray, shape (n, n)
        The model's A at a parameter value (all else as simulated).
    unit : str
        The parameter's unit, for the table (``"m/s"``).
    pot_series : str
        ``"E6"`` (default) or ``"E3"``.
    step : float or None
        Spacing of the dial table's rows (parameter units); None: ten rows.
    """

    parameter: str
    low: float
    high: float
    linear_part: Callable[[float], np.ndarray]
    unit: str = ""
    pot_series: str = "E6"
    step: float | None = None


@dataclass(frozen=True)
class DialSetting:
    """One row of a dial table: the parameter value, the resistance and the rotation."""

    value: float
    resistance: float  # ohm, fixed part plus potentiometer
    fraction: float  # of the potentiometer's rotation, 0..1


@dataclass(frozen=True)
class Knob:
    """One resistor turned into a fixed part plus a potentiometer.

    Attributes
    ----------
    resistor : str
        The paper's name of the resistor it replaces (``"R33"``).
    fixed_part, pot_part : str
        Netlist names of the fixed resistor (``"R33A"``) and the potentiometer (``"R33P"``).
    entry : tuple of str
        (target, source) state names: the knob sets A[target, source].
    fixed : float
        The fixed resistor, ohms (a member of the synthesis series).
    pot : float
        The potentiometer's full resistance, ohms (a member of the pot series).
    scale : float
        Ohms of the exact resistor per 1/|A| (1/s): R(value) = scale / |A(value)|.
    settings : tuple of DialSetting
        The dial table, low to high, the simulated value included.
    setting : DialSetting
        The simulated value's setting (what the netlist holds).
    """

    resistor: str
    fixed_part: str
    pot_part: str
    entry: tuple[str, str]
    fixed: float
    pot: float
    scale: float
    settings: tuple[DialSetting, ...]
    setting: DialSetting

    def fraction(self, resistance: float) -> float:
        """Rotation fraction that gives ``resistance`` ohms (fixed part included)."""
        return (resistance - self.fixed) / self.pot


def pot_value(span: float, series: str) -> float:
    """The smallest potentiometer of ``series`` of at least ``span`` ohms."""
    if series not in POT_SERIES:
        raise SynthesisError(f"unknown potentiometer series {series!r}; choose E3 or E6")
    decade, mantissa = _decade(span)
    for member in (*POT_SERIES[series], 10.0):
        if member >= mantissa * (1 - 1e-12):
            return _standard(member, decade, span)
    raise AssertionError("unreachable: 10.0 bounds every mantissa")


def _fixed_value(low: float, high: float, pot: float, series: str) -> float | None:
    """A standard resistor in [high - pot, low] nearest the centring value, None if none.

    The centring value (low + high - pot) / 2 leaves equal margins of rotation at both ends.
    """
    centre = max((low + high - pot) / 2, (high - pot), low * 1e-3)
    if series == "exact":
        return centre
    decade, _ = _decade(centre)
    candidates = [
        _standard(m, d, centre) for d in (decade - 1, decade, decade + 1) for m in SERIES[series]
    ]
    inside = [c for c in candidates if max(high - pot, 0.0) <= c <= low and c > 0]
    if not inside:
        return None
    return min(inside, key=lambda c: abs(math.log(c / centre)))


def knob_entries(system: System, request: KnobRequest) -> list[tuple[int, int]]:
    """Entries of A that change over the range (the resistors the knob turns).

    Raises
    ------
    SynthesisError
        An entry that changes sign or passes through zero in the range (no resistor follows
        it), or a range that does not hold the simulated value.
    """
    values = np.linspace(request.low, request.high, SAMPLES)
    stack = np.array([np.asarray(request.linear_part(float(v)), dtype=float) for v in values])
    base = np.asarray(system.A, dtype=float)
    entries = []
    for i, j in zip(*np.nonzero(np.any(stack != base, axis=0)), strict=True):
        column = stack[:, i, j]
        if not (np.all(column * base[i, j] > 0)):
            raise SynthesisError(
                f"A[{system.states[i]}, {system.states[j]}] changes sign or vanishes between "
                f"{request.parameter} = {request.low:g} and {request.high:g}: no knob resistor "
                "follows it"
            )
        entries.append((int(i), int(j)))
    return entries


def add_knobs(
    circuit, bom: list[BomEntry], system: System, request: KnobRequest, series: str, value: float
) -> list[Knob]:
    """Replace every resistor that follows ``request.parameter`` with a fixed part and a
    potentiometer set for ``value`` (the simulated parameter value); the BOM likewise.

    Parameters
    ----------
    circuit : Circuit
        The translator's circuit (changed in place).
    bom : list of BomEntry
        Its bill of materials (changed in place).
    system : System
        The model at ``value``.
    request : KnobRequest
    series : str
        Series of the fixed parts (``"E96"``, ``"E24"``, ``"exact"``).
    value : float
        The parameter's simulated value.

    Returns
    -------
    list of Knob
        One per resistor turned.

    Raises
    ------
    SynthesisError
        A bad range or series, the simulated value outside the range, an entry that
        changes sign, or a parameter that moves no entry of A (no resistor follows it).
    """
    if not (math.isfinite(request.low) and math.isfinite(request.high) and
            0 < request.low < request.high):  # fmt: skip
        raise SynthesisError(
            f"speed range {request.low:g}:{request.high:g}: must be two positive numbers, "
            "low below high"
        )
    if not request.low <= value <= request.high:
        raise SynthesisError(
            f"the simulated {request.parameter} = {value:g} {request.unit} is outside the knob's "
            f"range {request.low:g}:{request.high:g}; widen the range or change "
            f"{request.parameter}"
        )
    if request.pot_series not in POT_SERIES:
        raise SynthesisError(
            f"unknown potentiometer series {request.pot_series!r}; choose E3 or E6"
        )
    entries = knob_entries(system, request)
    if not entries:
        raise SynthesisError(
            f"no resistor follows {request.parameter}: no entry of the linear part changes "
            f"between {request.parameter} = {request.low:g} and {request.high:g} "
            f"{request.unit}".rstrip()
            + " (a knob turns resistors; name a parameter the circuit's coefficients depend on)"
        )
    names = PartNames(system)
    knobs = []
    for i, j in entries:
        target, source = system.states[i], system.states[j]
        knobs.append(_turn(circuit, bom, system, request, series, value, names, target, source))
    return knobs


def _turn(circuit, bom, system, request, series, value, names, target, source) -> Knob:
    """One resistor (A[target, source]) into a fixed part plus a potentiometer."""
    index = {s: k for k, s in enumerate(system.states)}
    i, j = index[target], index[source]
    name = names.linear_resistor(target, source)
    parts = [
        e
        for e in circuit.elements
        if e.name.upper() in (name.upper(), f"{name}A".upper(), f"{name}B".upper())
    ]
    if not parts or not all(isinstance(p, Resistor) for p in parts):
        raise SynthesisError(f"no resistor {name} for A[{target}, {source}] in the circuit")
    record = next(e for e in bom if e.part.upper() == parts[0].name.upper())
    ohms = [float(p.resistance) for p in parts]
    if len(parts) == 2 and parts[0].nodes == parts[1].nodes:  # a parallel pair
        total = ohms[0] * ohms[1] / (ohms[0] + ohms[1])
    else:
        total = sum(ohms)
    # the record's realized coefficient is target * exact / total: the exact resistor follows
    exact = record.realized * total / record.target
    scale = exact * abs(float(system.A[i, j]))

    def resistance(v: float) -> float:
        return scale / abs(float(np.asarray(request.linear_part(v))[i, j]))

    sampled = [resistance(float(v)) for v in np.linspace(request.low, request.high, SAMPLES)]
    low, high = min(sampled), max(sampled)
    fixed_series = series if series in SERIES or series == "exact" else "E96"
    pot = pot_value(high - low, request.pot_series)
    fixed = _fixed_value(low, high, pot, fixed_series)
    while fixed is None:  # the interval holds no standard value: a larger potentiometer
        pot = pot_value(pot * 1.0001, request.pot_series)
        fixed = _fixed_value(low, high, pot, fixed_series)
    fixed = round_to_series(fixed, "exact")
    rows = _table_values(request, value)
    settings = tuple(DialSetting(v, resistance(v), (resistance(v) - fixed) / pot) for v in rows)
    setting = next(s for s in settings if s.value == value)
    fixed_name, pot_name = f"{name}A", f"{name}P"
    node_a, node_b = parts[0].positive, parts[-1].negative  # a pair's far ends
    middle = f"{name.lower()}_mid"
    at = circuit.elements.index(parts[0])
    circuit.elements = [e for e in circuit.elements if e not in parts]
    circuit.elements[at:at] = [
        Resistor(fixed_name, node_a, middle, fixed),
        Resistor(pot_name, middle, node_b, float(f"{setting.resistance - fixed:.12g}")),
    ]
    realized = record.target * exact / (fixed + float(f"{setting.resistance - fixed:.12g}"))
    role = record.role.split("; series pair")[0].split("; parallel pair")[0]
    where = bom.index(record)
    bom[:] = [e for e in bom if e.part.upper() not in {p.name.upper() for p in parts}]
    bom[where:where] = [
        BomEntry(fixed_name, fixed, "ohm", fixed_series,
                 f"{role}; fixed part of the {request.parameter} knob with {pot_name}",
                 record.target, realized),
        BomEntry(pot_name, setting.resistance - fixed, "ohm", request.pot_series,
                 f"{role}; {_ohms(pot)} linear potentiometer wired as a variable resistor, set "
                 f"to {setting.fraction:.4f} of its rotation for {request.parameter} = "
                 f"{value:g} {request.unit} (the dial table: .knob.csv)".replace("  ", " "),
                 nominal=pot),
    ]  # fmt: skip
    return Knob(name, fixed_name, pot_name, (target, source), fixed, pot, scale, settings,
                setting)  # fmt: skip


def _table_values(request: KnobRequest, value: float) -> list[float]:
    """The dial table's parameter values: the ends, a round step between, the simulated one."""
    step = request.step or _round_step((request.high - request.low) / 10)
    first = math.ceil(request.low / step - 1e-9) * step
    values = {float(request.low), float(request.high), float(value)}
    v = first
    while v < request.high - 1e-9 * step:
        values.add(float(f"{v:.12g}"))
        v += step
    return sorted(values)


def _round_step(raw: float) -> float:
    """1, 2 or 5 times a power of ten, at most ``raw``."""
    decade = 10.0 ** math.floor(math.log10(raw))
    return max(m * decade for m in (1, 2, 5) if m * decade <= raw * (1 + 1e-12))


def _ohms(value: float) -> str:
    """``10 kOhm`` (shop notation)."""
    for factor, prefix in ((1e6, "M"), (1e3, "k"), (1.0, "")):
        if value >= factor:
            return f"{value / factor:g} {prefix}Ohm"
    return f"{value:g} Ohm"


def knob_table_text(knobs: list[Knob], request: KnobRequest) -> str:
    """The dial tables as CSV: ``resistor,pot,fixed,<parameter>,resistance,fraction`` rows."""
    unit = f" ({request.unit})" if request.unit else ""
    lines = [f"resistor,potentiometer (ohm),fixed (ohm),{request.parameter}{unit},"
             "resistance (ohm),fraction"]  # fmt: skip
    for knob in knobs:
        for s in knob.settings:
            lines.append(
                f"{knob.resistor},{knob.pot!r},{knob.fixed!r},{s.value!r},{s.resistance!r},"
                f"{s.fraction!r}"
            )
    return "\n".join(lines) + "\n"


def knob_summary(knobs: list[Knob], request: KnobRequest | None) -> list[str]:
    """One line per knob: the parts, the range's dial ends and the simulated setting."""
    if request is None:
        return []
    unit = f" {request.unit}" if request.unit else ""
    lines = []
    for k in knobs:
        first, last = k.settings[0], k.settings[-1]
        lines.append(
            f"knob {k.resistor} = {k.fixed_part} {_ohms(k.fixed)} + {k.pot_part} {_ohms(k.pot)} "
            f"pot: {request.parameter} {first.value:g}..{last.value:g}{unit} at dial "
            f"{first.fraction:.3f}..{last.fraction:.3f}; set to {k.setting.fraction:.4f} for "
            f"{k.setting.value:g}{unit}"
        )
    return lines
