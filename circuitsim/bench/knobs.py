"""The bench's knobs: which model parameters the circuit realizes so that they can be turned
while it runs, and the circuit and the System at a set of knob values.

A knob is a potentiometer, a generator setting or a switch of the real circuit:

- ``speed``, ``freq``, ``amplitude``: the parameters the model's ``[options]`` table maps
  these scenario options to (the wheelset: V, which sets R33 and R44; f and a, the sine
  generator XFG1);
- one switch per piecewise-linear term (the wheelset: ``flange``, switch S1), open or closed;
- every other parameter whose change moves only resistor values (the wheelset: m, I, k:
  found by translating the model at the parameter +10 % and comparing the circuits), or the
  ones the model file's ``[circuit] knobs`` list names.

Only primary parameters (numbers in the file) are knobs: a parameter written as an expression
(the bogie's ``c_y = "2*f22/V"``) follows the knobs it reads, in the circuit and in the
bench's ODE alike, unless the scenario set it to a number of its own (``--param c_y=...``).
A number knob that moves no resistor (a parameter the circuit does not realize) is refused.

Every circuit of a session is translated with the same amplitude scales (the ranges of the
first translation), so that a node voltage means the same physical value all along; a
change that would rewire the circuit or change a capacitor is refused (:class:`BenchError`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

from circuitsim.bench.errors import BenchError
from circuitsim.mechanics.errors import ModelError
from circuitsim.mechanics.model import Model
from circuitsim.mechanics.parameters import evaluate_parameters
from circuitsim.mechanics.system import Sinusoid, System
from circuitsim.netlist.circuit import Capacitor, Circuit, Resistor, VoltageSource
from circuitsim.solver.engine import flat_circuit
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.knob import Knob as Potentiometer
from circuitsim.synthesis.knob import KnobRequest, add_knobs
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.translator import Synthesis, synthesize

#: Relative step of a parameter when finding which parts it sets.
PROBE_STEP = 0.1

#: The scenario options that become knobs, in the order the page shows them.
OPTION_KNOBS = ("speed", "freq", "amplitude")


@dataclass(frozen=True)
class Knob:
    """One knob of the bench.

    Attributes
    ----------
    name : str
        The API's name (``"speed"``, ``"flange"``, ``"k"``).
    kind : str
        ``"number"`` (a parameter in its unit) or ``"switch"`` (a piecewise-linear term on/off).
    parameter : str or None
        The model parameter a number knob sets (``"V"``); None for a switch.
    unit, description : str
        From the model file.
    parts : tuple of str
        The circuit parts it sets (``("R33", "R44")``, ``("S1",)``, the generator).
    """

    name: str
    kind: str
    parameter: str | None
    unit: str = ""
    description: str = ""
    parts: tuple[str, ...] = ()


@dataclass
class BenchSetup:
    """What a session runs: the model, its scenario and the translator options.

    Attributes
    ----------
    model : Model
    coefficients : str or None
        Coefficient set (None: the model's default).
    parameters : dict of str to float
        The starting value of every primary parameter (a number in the file) and of each
        derived one the scenario set to a number of its own (the scenario applied); the other
        derived parameters are evaluated from these at every knob setting.
    switches : dict of str to bool
        Each piecewise-linear term on (closed switch) or off at the start.
    forcing : dict of str to bool or None
        The forcing groups on/off, as ``Model.system`` takes them (None: the file's).
    x0 : dict of str to float
        Starting state, SI units (missing states 0).
    options : SynthesisOptions
        Translator options (``series="exact"`` makes each knob a potentiometer set to any
        value; a rounded series may rewire a pair R33 -> R33A + R33B, which is refused).
    pot : KnobRequest, optional
        The resistors that follow this parameter (the wheelset's speed: R33, R44) as a fixed
        part plus a potentiometer over the request's range (``--speed-range``); values
        outside it are refused.
    """

    model: Model
    coefficients: str | None
    parameters: dict[str, float]
    switches: dict[str, bool]
    forcing: dict[str, bool] | None = None
    x0: dict[str, float] = field(default_factory=dict)
    options: SynthesisOptions = field(default_factory=lambda: SynthesisOptions(series="exact"))
    pot: KnobRequest | None = None

    @classmethod
    def from_system(
        cls,
        model: Model,
        system: System,
        options: SynthesisOptions,
        coefficients=None,
        pot: KnobRequest | None = None,
    ) -> BenchSetup:
        """The setup of a System built from ``model`` (the CLI's scenario options)."""
        on = {term.name for term in system.nonlinear}
        x0 = (
            {}
            if system.x0 is None
            else dict(zip(system.states, map(float, system.x0), strict=True))
        )
        forcing = {name: False for name in model.forcing_terms}
        forcing.update({force.name: True for force in system.forcing if force.name})
        if not any(forcing.values()):  # e.g. a zero amplitude: keep the file's groups
            forcing = None
        return cls(
            model,
            coefficients,
            given_parameters(model, system.parameters),
            {name: name in on for name in model.nonlinear_terms},
            forcing,
            x0,
            options,
            pot,
        )

    @property
    def amplitude_parameter(self) -> str | None:
        """The parameter the ``amplitude`` option sets (the wheelset: a), if any."""
        return self.model.options.get("amplitude")

    def system(self, parameters: dict[str, float], switches: dict[str, bool]) -> System:
        """The System at these values: every piecewise-linear term present, an open switch as
        a term that never switches in (``t_on = inf``), as in the circuit.

        Raises
        ------
        BenchError
            A value the model refuses (its message).
        """
        try:
            system = self.model.system(
                self.coefficients,
                parameters,
                {name: True for name in self.model.nonlinear_terms},
                self.x0,
                forcing=self.forcing,
            )
        except ModelError as exc:
            raise BenchError(str(exc)) from None
        terms = tuple(
            term if switches.get(term.name, True) else replace(term, t_on=math.inf)
            for term in system.nonlinear
        )
        unsupported = [
            f.name or type(f).__name__ for f in system.forcing if not isinstance(f, Sinusoid)
        ]
        if unsupported:
            raise BenchError(
                f"the bench runs sinusoidal forcing only; forcing {', '.join(unsupported)} is "
                "a time series (run it with compare or simulate)"
            )
        return replace(system, nonlinear=terms)

    def reference_amplitude(self) -> float | None:
        """The amplitude every circuit is translated with (the generator is then set to the
        knob's share of it): the starting value, else the model file's default, else 1."""
        name = self.amplitude_parameter
        if name is None:
            return None
        for value in (self.parameters.get(name, 0.0), self.model.parameter_info[name].value):
            if value:
                return abs(float(value))
        return 1.0


def given_parameters(model: Model, values: dict[str, float]) -> dict[str, float]:
    """Of a System's parameter values, those a run gives: every primary parameter, and each
    derived one whose value is not what its expression gives at the others (the scenario set
    it to a number of its own).

    Parameters
    ----------
    model : Model
    values : dict of str to float
        Every parameter's value (``System.parameters``), in their units.

    Returns
    -------
    dict of str to float
        In the model file's order.
    """
    info = model.parameter_info
    primary = {n: float(v) for n, v in values.items() if info[n].expression is None}
    followed = evaluate_parameters(info, primary, model.file)
    return {
        name: float(value)
        for name, value in values.items()
        if info[name].expression is None or not _same(followed[name], float(value))
    }


def _same(a: float, b: float) -> bool:
    """Equal to rounding (an expression evaluated twice at the same values)."""
    return a == b or abs(a - b) <= 1e-12 * max(abs(a), abs(b))


class Translated(NamedTuple):
    """A circuit of the bench and its potentiometers (empty without ``setup.pot``)."""

    synthesis: Synthesis
    pots: list[Potentiometer]


def synthesize_at(
    setup: BenchSetup,
    parameters: dict[str, float],
    switches: dict[str, bool],
    options: SynthesisOptions,
    first: bool = False,
) -> Translated:
    """The circuit at these knob values, the generator at the reference amplitude; with
    ``setup.pot``, the resistors that follow its parameter as fixed parts plus potentiometers
    set for its value (:func:`~circuitsim.synthesis.knob.add_knobs`).

    ``first``: the session's first translation, which chooses the scales (auto scaling from
    the direct solution); later ones pass ``options`` with every range fixed.

    Raises
    ------
    BenchError
        The model or the translator refuses the values (a potentiometer's value outside its
        range among them).
    """
    amplitude = setup.amplitude_parameter
    if amplitude is not None:
        parameters = {**parameters, amplitude: setup.reference_amplitude()}
    system = setup.system(parameters, switches)
    try:
        synthesis = synthesize(system, options, peaks=first)
        pots = []
        if setup.pot is not None:
            value = parameters[setup.pot.parameter]
            pots = add_knobs(synthesis.circuit, synthesis.bom, system, setup.pot, options.series,
                             value)  # fmt: skip
    except (SynthesisError, ModelError) as exc:
        raise BenchError(str(exc)) from None
    except (ValueError, ArithmeticError) as exc:  # a potentiometer with no span left
        raise BenchError(f"the potentiometers cannot realize these values ({exc})") from None
    return Translated(synthesis, pots)


def fixed_ranges(synthesis: Synthesis, options: SynthesisOptions) -> SynthesisOptions:
    """``options`` with each state's range set so that the translator chooses the volts per
    unit of ``synthesis`` again (auto scaling floors swing/range to an E24 value: a range a
    hair below swing/G keeps G)."""
    if options.scaling == "unity":
        return options
    ranges = {
        name: options.swing / abs(scale.volts_per_unit) * (1 - 1e-9)
        for name, scale in synthesis.scale_map.states.items()
    }
    return replace(options, ranges=ranges)


def differences(old: Circuit, new: Circuit) -> dict[str, tuple[float, float]]:
    """The resistor values (ohms) that differ between two flat circuits of one wiring.

    Raises
    ------
    BenchError
        The wiring differs (an element added, removed or moved) or a capacitor changed: a
        knob turns a potentiometer or a switch, it does not rebuild the circuit.
    """
    if [(e.name, type(e), e.nodes) for e in old.elements] != [
        (e.name, type(e), e.nodes) for e in new.elements
    ]:
        added = {e.name for e in new.elements} ^ {e.name for e in old.elements}
        detail = f" (parts {', '.join(sorted(added)[:6])})" if added else ""
        raise BenchError(f"these values change the circuit's wiring{detail}, not only its values")
    changed = {}
    for a, b in zip(old.elements, new.elements, strict=True):
        if isinstance(a, Resistor) and a.resistance != b.resistance:
            changed[a.name] = (float(a.resistance), float(b.resistance))
        elif isinstance(a, Capacitor) and a.capacitance != b.capacitance:
            raise BenchError(
                f"these values change capacitor {a.name} ({a.capacitance:g} F -> "
                f"{b.capacitance:g} F); the bench turns resistors and switches only"
            )
    return changed


def find_knobs(setup: BenchSetup, options: SynthesisOptions, base: Synthesis) -> list[Knob]:
    """The knobs of ``setup``'s model (see the module's description), in the page's order.

    ``options`` has the session's fixed ranges; ``base`` is the circuit at the start.

    Raises
    ------
    BenchError
        The model file's ``[circuit] knobs`` names a parameter written as an expression (it
        follows the parameters it reads; those are the knobs).
    """
    model = setup.model
    info = model.parameter_info
    hints = setup.system(setup.parameters, setup.switches).circuit_hints or {}
    listed = hints.get("knobs")
    derived = [name for name in listed or () if name in info and info[name].expression]
    if derived:
        name = derived[0]
        raise BenchError(
            f"{model.file}: circuit.knobs: {name} is computed from other parameters "
            f"({name} = {info[name].expression.expression.text!r}) and follows them; list the "
            "parameters it reads instead"
        )
    flat = flat_circuit(base.circuit)
    knobs = []
    for option in OPTION_KNOBS:
        name = model.options.get(option)
        if name is None or info[name].expression is not None:
            continue  # a derived parameter follows its own knobs
        if option == "speed":  # the generator's settings may follow the speed too
            parts = _parts_set_by(setup, options, flat, name, resistors_only=False)
        else:
            parts = tuple(
                e.name
                for e in flat.elements
                if isinstance(e, VoltageSource) and type(e.waveform).__name__ == "Sin"
            )
        knobs.append(Knob(option, "number", name, info[name].unit, info[name].description, parts))
    switch_parts = hints.get("switches", {})
    for term in model.nonlinear_terms:
        part = switch_parts.get(term)
        knobs.append(
            Knob(
                term,
                "switch",
                None,
                "",
                f"piecewise-linear term {term} on/off",
                (part,) if part else (),
            )
        )
    taken = {k.parameter for k in knobs}
    for name in listed if listed is not None else info:
        if name in taken or name not in info or info[name].expression is not None:
            continue
        if name not in setup.parameters:
            continue
        parts = _parts_set_by(setup, options, flat, name)
        if parts:
            knobs.append(Knob(name, "number", name, info[name].unit, info[name].description, parts))
    return knobs


def _parts_set_by(
    setup: BenchSetup,
    options: SynthesisOptions,
    flat: Circuit,
    name: str,
    resistors_only: bool = True,
) -> tuple[str, ...]:
    """The resistors a parameter sets (empty if it sets none; with ``resistors_only``, empty
    also if it changes a source)."""
    value = setup.parameters.get(name, 0.0)
    if not value:
        return ()
    for step in (PROBE_STEP, -PROBE_STEP):  # down where up leaves a potentiometer's range
        probe = {**setup.parameters, name: value * (1 + step)}
        try:
            other = flat_circuit(
                synthesize_at(setup, probe, setup.switches, options).synthesis.circuit
            )
            changed = differences(flat, other)
            break
        except BenchError:
            continue
    else:
        return ()
    if resistors_only and not _same_sources(flat, other):
        return ()
    return tuple(changed)


def _same_sources(a: Circuit, b: Circuit) -> bool:
    """Whether every voltage source is the same in both circuits (only resistors moved)."""
    return all(
        (x.dc, x.waveform) == (y.dc, y.waveform)
        for x, y in zip(a.elements, b.elements, strict=True)
        if isinstance(x, VoltageSource)
    )
