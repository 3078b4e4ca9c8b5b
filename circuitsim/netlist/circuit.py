"""The circuit as data: elements, models, subcircuits and analyses, with no solver in it.

Every room that deals with circuits speaks these types: the SPICE reader produces them, the
writer turns them into text, the translator builds them, the solver flattens and simulates
them. Conventions:

- Node names are strings, ground is ``"0"``. The reader lower-cases node names (SPICE is
  case-insensitive); builders should use lower case too.
- Element names are full SPICE names including the type letter (``"R31"``, ``"XU1A"``,
  ``"VXFG1"``), case kept as written; uniqueness is case-insensitive.
- A value is a ``float`` in SI units, or an :class:`Expression` still to be evaluated against
  ``.param`` values (subcircuit parameters, ``{2*rbase}``). ``flatten`` in this package turns
  every Expression into a float.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Union

from circuitsim.netlist.names import fold


@dataclass(frozen=True)
class Expression:
    """An unevaluated SPICE expression, the text between ``{`` and ``}`` (braces excluded).

    ``included`` names the included file it was read from (None: the netlist itself, or a
    circuit built in Python): messages then name the file instead of quoting the text, as
    the reader does for an included file's lines. It takes no part in comparisons.
    """

    text: str
    included: str | None = field(default=None, compare=False)

    def __str__(self) -> str:
        return "{" + self.text + "}"


Value = Union[float, Expression]  # noqa: UP007 - a runtime alias, read by isinstance users


# --- independent-source waveforms ---------------------------------------------------------


@dataclass(frozen=True)
class Sin:
    """SPICE ``SIN(vo va freq td theta phase)``.

    Value vo + va exp(-theta (t-td)) sin(2 pi f (t-td) + phase) after td.

    Units: volts or amperes, hertz, seconds, 1/seconds, degrees (``phase``, as SPICE writes it).
    Before ``delay`` the value is ``offset + amplitude * sin(phase)``.
    """

    offset: Value
    amplitude: Value
    frequency: Value
    delay: Value = 0.0
    damping: Value = 0.0
    phase: Value = 0.0


@dataclass(frozen=True)
class Pulse:
    """SPICE ``PULSE(v1 v2 td tr tf pw per)``; seconds for the times. ``period`` None: one pulse."""

    initial: Value
    pulsed: Value
    delay: Value = 0.0
    rise: Value = 0.0
    fall: Value = 0.0
    width: Value = float("inf")
    period: Value | None = None


@dataclass(frozen=True)
class Pwl:
    """SPICE ``PWL(t1 v1 t2 v2 ...)``: ``points`` is a tuple of (time s, value) pairs."""

    points: tuple[tuple[Value, Value], ...]


Waveform = Union[Sin, Pulse, Pwl]  # noqa: UP007


# --- elements -----------------------------------------------------------------------------


@dataclass
class Element:
    """Base of all elements: a SPICE name and the nodes it touches, in SPICE order."""

    name: str

    @property
    def nodes(self) -> tuple[str, ...]:
        raise NotImplementedError

    @property
    def letter(self) -> str:
        """The SPICE type letter, upper case (``"R"`` for ``"R31"``)."""
        return self.name[:1].upper()


@dataclass
class TwoTerminal(Element):
    """An element between a positive and a negative node."""

    positive: str
    negative: str

    @property
    def nodes(self) -> tuple[str, ...]:
        return (self.positive, self.negative)


@dataclass
class Resistor(TwoTerminal):
    """``Rname n+ n- value`` (ohms)."""

    resistance: Value


@dataclass
class Capacitor(TwoTerminal):
    """``Cname n+ n- value [IC=v]`` (farads; initial voltage in volts)."""

    capacitance: Value
    ic: Value | None = None


@dataclass
class Inductor(TwoTerminal):
    """``Lname n+ n- value [IC=i]`` (henries; initial current in amperes, n+ to n- inside)."""

    inductance: Value
    ic: Value | None = None


@dataclass
class VoltageSource(TwoTerminal):
    """``Vname n+ n- [DC v] [AC mag [phase]] [waveform]`` (volts; phase in degrees).

    The branch current ``i(Vname)`` flows from n+ through the source to n- (SPICE sign).
    """

    dc: Value = 0.0
    waveform: Waveform | None = None
    ac_magnitude: Value = 0.0
    ac_phase: Value = 0.0


@dataclass
class CurrentSource(TwoTerminal):
    """``Iname n+ n- ...``: current flows from n+ through the source to n- (amperes)."""

    dc: Value = 0.0
    waveform: Waveform | None = None
    ac_magnitude: Value = 0.0
    ac_phase: Value = 0.0


@dataclass
class VoltageControlled(TwoTerminal):
    """Base of E and G: controlled by v(control_positive) - v(control_negative)."""

    control_positive: str
    control_negative: str

    @property
    def nodes(self) -> tuple[str, ...]:
        return (self.positive, self.negative, self.control_positive, self.control_negative)


@dataclass
class Vcvs(VoltageControlled):
    """``Ename n+ n- nc+ nc- gain``: v(n+) - v(n-) = gain * v(nc+, nc-)."""

    gain: Value


@dataclass
class Vccs(VoltageControlled):
    """``Gname n+ n- nc+ nc- gm``: current gm * v(nc+, nc-) from n+ through it to n- (siemens)."""

    transconductance: Value


@dataclass
class CurrentControlled(TwoTerminal):
    """Base of F and H: controlled by the current through voltage source ``control``."""

    control: str


@dataclass
class Cccs(CurrentControlled):
    """``Fname n+ n- vcontrol gain``: current gain * i(vcontrol) from n+ through it to n-."""

    gain: Value


@dataclass
class Ccvs(CurrentControlled):
    """``Hname n+ n- vcontrol r``: v(n+) - v(n-) = r * i(vcontrol) (ohms)."""

    transresistance: Value


@dataclass
class Diode(Element):
    """``Dname anode cathode model [area]``; the model is a ``.model name D(...)``."""

    anode: str
    cathode: str
    model: str
    area: Value = 1.0

    @property
    def nodes(self) -> tuple[str, ...]:
        return (self.anode, self.cathode)


@dataclass
class PolyVoltageControlled(TwoTerminal):
    """Base of ``E``/``G`` ``POLY(n)``: a polynomial in n controlling voltages.

    ``controls`` holds the n (nc+, nc-) node pairs, ``coefficients`` SPICE's p0 p1 ... in
    SPICE's term order (constant, linear terms, then products x_i x_j with i <= j, ...).
    """

    controls: tuple[tuple[str, str], ...]
    coefficients: tuple[Value, ...]

    @property
    def nodes(self) -> tuple[str, ...]:
        return (self.positive, self.negative, *(n for pair in self.controls for n in pair))


@dataclass
class PolyVcvs(PolyVoltageControlled):
    """``Ename n+ n- POLY(n) nc1+ nc1- ... p0 p1 ...``: v(n+, n-) = P(v(nc1), ...)."""


@dataclass
class PolyVccs(PolyVoltageControlled):
    """``Gname n+ n- POLY(n) nc1+ nc1- ... p0 p1 ...``: current P(...) from n+ through it to n-."""


@dataclass
class PolyCurrentControlled(TwoTerminal):
    """Base of ``F``/``H`` ``POLY(n)``: a polynomial in the currents of n voltage sources."""

    controls: tuple[str, ...]
    coefficients: tuple[Value, ...]


@dataclass
class PolyCccs(PolyCurrentControlled):
    """``Fname n+ n- POLY(n) v1 ... p0 p1 ...``: current P(i(v1), ...) from n+ through it to n-."""


@dataclass
class PolyCcvs(PolyCurrentControlled):
    """``Hname n+ n- POLY(n) v1 ... p0 p1 ...``: v(n+, n-) = P(i(v1), ...) (volts)."""


@dataclass
class Jfet(Element):
    """``Jname drain gate source model [area]``; the model is ``.model name NJF|PJF(...)``."""

    drain: str
    gate: str
    source: str
    model: str
    area: Value = 1.0

    @property
    def nodes(self) -> tuple[str, ...]:
        return (self.drain, self.gate, self.source)


@dataclass
class Bjt(Element):
    """``Qname collector base emitter [substrate] model [area]``; ``.model name NPN|PNP(...)``.

    ``substrate`` is None when the line has three nodes (SPICE then ties it to ground).
    """

    collector: str
    base: str
    emitter: str
    model: str
    area: Value = 1.0
    substrate: str | None = None

    @property
    def nodes(self) -> tuple[str, ...]:
        own = (self.collector, self.base, self.emitter)
        return own if self.substrate is None else (*own, self.substrate)


@dataclass
class Switch(VoltageControlled):
    """``Sname n+ n- nc+ nc- model [ON|OFF]``: a voltage-controlled switch, ``.model name SW(...)``.

    ``initial`` is ``"on"``, ``"off"`` or None (the model decides from the control voltage).
    """

    model: str = ""
    initial: str | None = None


@dataclass
class SubcircuitCall(Element):
    """``Xname n1 n2 ... subckt [name=value ...]``: an instance of a ``.subckt``."""

    connections: tuple[str, ...]
    subcircuit: str
    params: dict[str, Value] = field(default_factory=dict)

    @property
    def nodes(self) -> tuple[str, ...]:
        return self.connections


# --- models, subcircuits, analyses --------------------------------------------------------


@dataclass
class Model:
    """``.model name kind(param=value ...)``; ``kind`` upper case (``"D"``, ``"SW"``)."""

    name: str
    kind: str
    params: dict[str, Value] = field(default_factory=dict)


@dataclass
class Subcircuit:
    """``.subckt name port ... [params: name=default ...]`` ... ``.ends``."""

    name: str
    ports: tuple[str, ...]
    elements: list[Element] = field(default_factory=list)
    models: dict[str, Model] = field(default_factory=dict)
    subcircuits: dict[str, Subcircuit] = field(default_factory=dict)
    params: dict[str, Value] = field(default_factory=dict)


@dataclass(frozen=True)
class Transient:
    """``.tran tstep tstop [tstart [tmax]] [uic]`` (seconds)."""

    tstep: float
    tstop: float
    tstart: float = 0.0
    tmax: float | None = None
    uic: bool = False


@dataclass(frozen=True)
class OperatingPoint:
    """``.op``."""


@dataclass(frozen=True)
class AcSweep:
    """``.ac dec|oct|lin points fstart fstop`` (hertz)."""

    variation: str
    points: int
    fstart: float
    fstop: float


Analysis = Union[Transient, OperatingPoint, AcSweep]  # noqa: UP007


@dataclass
class Circuit:
    """A whole netlist.

    Attributes
    ----------
    title : str
        The first line of the netlist.
    elements : list of Element
        Top-level elements in netlist order.
    models : dict of str to Model
        Keys lower case.
    subcircuits : dict of str to Subcircuit
        Keys lower case.
    params : dict of str to Value
        Global ``.param`` definitions, keys lower case, in definition order.
    analyses : list of Analysis
        ``.tran``, ``.op``, ``.ac`` in netlist order.
    initial_conditions : dict of str to Value
        ``.ic v(node)=value``: node name to volts.
    options : dict of str to Value or bool
        ``.options``; a flag without a value is ``True``. Keys lower case.
    control : list of str
        Raw ``.control`` ... ``.endc`` blocks (ngspice only), kept aside, not interpreted.
    source : str or None
        The file the circuit was read from, for error messages and relative includes.
    """

    title: str = ""
    elements: list[Element] = field(default_factory=list)
    models: dict[str, Model] = field(default_factory=dict)
    subcircuits: dict[str, Subcircuit] = field(default_factory=dict)
    params: dict[str, Value] = field(default_factory=dict)
    analyses: list[Analysis] = field(default_factory=list)
    initial_conditions: dict[str, Value] = field(default_factory=dict)
    options: dict[str, Value | bool] = field(default_factory=dict)
    control: list[str] = field(default_factory=list)
    source: str | None = None

    def element(self, name: str) -> Element:
        """The top-level element called ``name`` (case-insensitive); KeyError if none."""
        key = fold(name)
        for element in self.elements:
            if fold(element.name) == key:
                return element
        raise KeyError(name)

    def add(self, *elements: Element) -> None:
        """Append elements at the top level."""
        self.elements.extend(elements)

    @property
    def transient(self) -> Transient | None:
        """The first ``.tran`` analysis, if any."""
        return next((a for a in self.analyses if isinstance(a, Transient)), None)

    def node_names(self) -> list[str]:
        """Top-level node names in first-seen order, ground excluded."""
        seen: dict[str, None] = {}
        for element in self.elements:
            for node in element.nodes:
                if node != "0":
                    seen.setdefault(node, None)
        return list(seen)
