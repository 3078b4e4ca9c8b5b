"""The translator: a :class:`~circuitsim.mechanics.system.System` in, an op-amp circuit out.

Every state x_i is an inverting integrator followed by a unity inverter::

    node <s>_sum : the integrator's summing junction (virtual ground)
    node <s>_neg : integrator output, carries -G_i x_i   (capacitor C_i from here to <s>_sum)
    node <s>     : inverter output,   carries +G_i x_i   (the scale file points here, G_i > 0)

so with circuit time tau = t / K the integrator realizes

    d(G_i x_i)/dtau = (1/C_i) sum_k v_k / R_k,

and each model coefficient becomes a resistor: a linear term A_ij x_j is a resistor from the
+x_j node (A_ij > 0) or the -x_j node (A_ij < 0) with 1/(R C_i) = K G_i |A_ij| / G_j; a
forcing input its SIN or PWL source through its own resistor
(:mod:`~circuitsim.synthesis.inputs`); the constant b0 a DC source; a piecewise-linear term
its signal (:mod:`circuitsim.synthesis.pwl`) through a switch and a resistor. Component
values, names and scaling: :mod:`~circuitsim.synthesis.eseries`,
:mod:`~circuitsim.synthesis.naming`, :mod:`~circuitsim.synthesis.scaling`. The whole design is
described in docs/translator.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from circuitsim.mechanics.system import System
from circuitsim.netlist.circuit import (
    Capacitor,
    Circuit,
    Model,
    Pwl,
    Switch,
    Transient,
    VoltageSource,
)
from circuitsim.netlist.tidy import round_derived
from circuitsim.synthesis.blocks import BomEntry, Builder
from circuitsim.synthesis.bounds import HARD_RANGE, check_buildable, refuse_unrealizable
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.eseries import CAPACITOR_DECADES
from circuitsim.synthesis.inputs import Generator, add_forcing
from circuitsim.synthesis.naming import PartNames, node_name
from circuitsim.synthesis.offsets import apply_opamp_errors
from circuitsim.synthesis.opamp_library import install, load_opamp
from circuitsim.synthesis.opamps import add_opamp
from circuitsim.synthesis.options import SWING_LIMIT, SynthesisOptions
from circuitsim.synthesis.pwl import TermBuilder
from circuitsim.synthesis.scalemap import ScaleMap, StateScale
from circuitsim.synthesis.scaling import choose_scaling, direct_solution
from circuitsim.synthesis.timestep import StepChoice, choose_step


@dataclass
class Synthesis:
    """What the translator produced.

    Attributes
    ----------
    circuit : Circuit
        The netlist, with a ``.tran`` over the run (``uic``) and ``.ic`` on integrator outputs.
    scale_map : ScaleMap
        Node and volts per unit of every state, and the time scale.
    bom : list of BomEntry
        Every resistor and capacitor, with the coefficient it sets and its rounding error.
    warnings : list of str
        Clipping, out-of-range resistors, all-zero states ...
    t_stop : float
        Model seconds covered by the ``.tran``.
    node_peaks : dict of str to float
        Predicted peak |v| of the state nodes over the run (V), from the direct solution.
    step : StepChoice
        The ``.tran`` maximum step and the mode or forcing that set it
        (:mod:`circuitsim.synthesis.timestep`).
    generators : list of Generator
        The forcing inputs' voltage sources and their volts per unit of input
        (:mod:`circuitsim.synthesis.inputs`).
    """

    circuit: Circuit
    scale_map: ScaleMap
    bom: list[BomEntry]
    warnings: list[str] = field(default_factory=list)
    t_stop: float = 0.0
    node_peaks: dict[str, float] = field(default_factory=dict)
    step: StepChoice | None = None
    generators: list[Generator] = field(default_factory=list)

    @property
    def max_error(self) -> float:
        """Largest |coefficient error| over the bill of materials (0 for exact values)."""
        errors = [abs(e.error) for e in self.bom if not math.isnan(e.error)]
        return max(errors, default=0.0)


@dataclass
class _Input:
    """One resistor into an integrator: 1/(R C) must equal ``gain`` (1/s of circuit time)."""

    name: str
    node: str
    gain: float
    target: float  # the model coefficient this resistor sets
    role: str
    series_extra: float = 0.0
    switch: tuple | None = None  # (switch name, signal node, control node, model name)


def synthesize(
    system: System,
    options: SynthesisOptions | None = None,
    *,
    peaks: bool = True,
    trajectory: tuple[np.ndarray, np.ndarray] | None = None,
) -> Synthesis:
    """Compile ``system`` into an op-amp circuit.

    Parameters
    ----------
    system : System
        The model at its parameter values (enabled nonlinear terms and forcing only).
    options : SynthesisOptions, optional
        Defaults: ideal op-amps, ``abs`` blocks, auto scaling to 5 V, real time, E96.
    peaks : bool
        Predict the nodes' peaks from the direct solution and warn where they exceed the
        op-amps' swing (default). False skips the direct solution when the scaling does not
        need it (every range given, or unity scaling): ``node_peaks`` is then empty and no
        swing warning is made (a sweep's variants, which share the scaling of the sweep).
    trajectory : tuple of ndarray, optional
        ``(t, x)`` of :func:`~circuitsim.synthesis.scaling.direct_solution` for this system
        and the options' ``t_stop``, if the caller already has it (a sweep's middle value);
        computed here when needed otherwise.

    Returns
    -------
    Synthesis

    Raises
    ------
    SynthesisError
        A bad option or a model the translator cannot realize.
    """
    options = (options or SynthesisOptions()).validated()
    hints = system.circuit_hints or {}
    t_stop = float(options.t_stop or hints.get("t_stop", 5.0))
    if options.time_scale is None:  # the model file's [circuit] time_scale, else real time
        options = replace(options, time_scale=float(hints.get("time_scale", 1.0)))
    if not (math.isfinite(t_stop) and t_stop > 0):
        raise SynthesisError(f"t_stop must be a positive number of seconds, got {t_stop:g}")
    K = options.time_scale
    unknown = sorted(set(options.ranges) - set(system.states))
    if unknown:
        raise SynthesisError(
            f"ranges given for unknown state(s) {', '.join(unknown)}; "
            f"the model's states are {', '.join(system.states)}"
        )
    if options.scaling != "unity":  # unity: the paper's mapping, built as asked (see below)
        refuse_unrealizable(system, options)  # before the direct solution below integrates
    needed = options.scaling != "unity" and len(options.ranges) < system.n
    if trajectory is None and (peaks or needed):
        trajectory = direct_solution(system, t_stop, options.scaling_wall_time)
    scaling = choose_scaling(system, options, t_stop, trajectory)
    G = scaling.volts_per_unit
    warnings = list(scaling.warnings)

    names = PartNames(system)
    circuit = Circuit(title=f"{system.name}: op-amp analog computer generated by circuitsim")
    opamp_kind = options.opamp
    if options.opamp == "lib":
        opamp_kind = install(circuit, load_opamp(options.opamp_lib, options.opamp_subckt))
    # no part of a series pair below what the buildability check accepts
    builder = Builder(
        circuit,
        options.series_key,
        opamp_kind,
        options.pair_tolerance,
        (options.r_min / HARD_RANGE, options.r_max * HARD_RANGE),
    )
    states = list(system.states)
    nodes = {s: (node_name(s), node_name(s) + "_neg") for s in states}
    inputs: dict[str, list[_Input]] = {s: [] for s in states}

    for i, target in enumerate(states):
        for j, source in enumerate(states):
            a = float(system.A[i, j])
            if a == 0:
                continue
            inputs[target].append(
                _Input(
                    names.linear_resistor(target, source),
                    nodes[source][0 if a > 0 else 1],
                    K * G[i] * abs(a) / G[j],
                    a,
                    f"{source} -> {target} integrator (A[{target}, {source}])",
                )
            )
    step = choose_step(system, K, t_stop, options.points_per_period)
    generators = add_forcing(
        system, circuit, names, inputs, _Input, G, K, options, t_stop, step.tmax
    )
    _add_constants(system, circuit, names, inputs, G, K)
    first_block, first_bom = len(circuit.elements), len(builder.bom)
    signals = _add_nonlinear(system, builder, names, nodes, inputs, G, K, options)
    blocks = {id(e) for e in circuit.elements[first_block:]}
    block_bom = {id(e) for e in builder.bom[first_bom:]}

    tmax = step.tmax
    for i, state in enumerate(states):
        _add_integrator(builder, names, state, nodes[state], inputs[state], options, warnings)
        x0 = 0.0 if system.x0 is None else float(system.x0[i])
        circuit.initial_conditions[nodes[state][1]] = float(-G[i] * x0) + 0.0
    # the netlist and the BOM read: supplies, the state sections, then the nonlinear blocks
    supplies = [e for e in circuit.elements if e.name.upper() in ("VCC", "VEE")]
    circuit.elements = (
        supplies
        + [e for e in circuit.elements if id(e) not in blocks and e not in supplies]
        + [e for e in circuit.elements if id(e) in blocks and e not in supplies]
    )
    builder.bom.sort(key=lambda entry: id(entry) in block_bom)
    for cap in (e for e in circuit.elements if isinstance(e, Capacitor)):
        cap.ic = circuit.initial_conditions[cap.positive]
    circuit.analyses.append(Transient(tstep=tmax, tstop=t_stop / K, tmax=tmax, uic=True))
    if options.scaling != "unity":  # unity scaling is the paper's mapping, asked for as it is
        check_buildable(circuit, options, {e.part.lower(): e.role for e in builder.bom})

    node_peaks: dict[str, float] = {}
    if trajectory is not None:
        _predicted_peaks(trajectory[1], G, states, nodes, signals, options, node_peaks, warnings)
    scale_map = ScaleMap(
        time_scale=K,
        states={
            s: StateScale(nodes[s][0], float(G[i]), system.units[i] if system.units else "")
            for i, s in enumerate(states)
        },
    )
    round_derived(circuit)  # SIN(0 13.2 3), not 13.200000000000001 (float noise of K * a)
    apply_opamp_errors(circuit, options.opamp_offset, options.opamp_bias)
    return Synthesis(
        circuit, scale_map, builder.bom, warnings, t_stop, node_peaks, step, generators
    )


def _predicted_peaks(x, G, states, nodes, signals, options, node_peaks, warnings) -> None:
    """Each state node's and summed signal's peak |v| (V) over the direct solution ``x``
    (shape (n, m)) into ``node_peaks``, and a warning for each beyond the op-amps' swing."""
    limit = SWING_LIMIT[options.opamp]
    for i, state in enumerate(states):
        peak = float(G[i] * np.max(np.abs(x[i])))
        node_peaks[nodes[state][0]] = node_peaks[nodes[state][1]] = peak
        if peak > limit:
            warnings.append(
                f"state {state} peaks at {peak:.3g} V, beyond the {options.opamp} op-amp's "
                f"{limit:g} V swing: it will clip ("
                + (
                    "use auto scaling"
                    if options.scaling == "unity"
                    else f"a smaller swing or a larger --range for {state} lowers it"
                )
                + ")"
            )
    for term, signal in signals:
        # the summed signal swings beta * max|s(x)| whether or not its switch is closed
        peak = float(signal.beta * np.max(np.abs(term.value(x))))
        node_peaks[signal.node] = peak
        if peak > limit:
            warnings.append(
                f"the {term.name} signal ({signal.node}) peaks at {peak:.3g} V, beyond the "
                f"{options.opamp} op-amp's {limit:g} V swing: it will clip"
            )
        for inner in signal.inner:
            peak = inner.peak(x)
            node_peaks[inner.node] = peak
            if peak > limit:
                rows = [s for s, r in zip(states, inner.row, strict=True) if r]
                warnings.append(
                    f"the {term.name} {inner.what} ({inner.node}) peaks at {peak:.3g} V, beyond "
                    f"the {options.opamp} op-amp's {limit:g} V swing: it will clip (its offset "
                    f"alone is {abs(inner.alpha * inner.offset):.3g} V; a larger --range for "
                    f"{', '.join(rows)} lowers it)"
                )


def _add_constants(system, circuit, names, inputs, G, K) -> None:
    """b0 as a DC source of +-1 V through a resistor."""
    for i, b in enumerate(np.asarray(system.b0, dtype=float)):
        if b == 0:
            continue
        target = system.states[i]
        source = names.generic(f"VB{i + 1}", f"constant into {target}")
        node = source.lower()
        circuit.add(VoltageSource(source, node, "0", dc=math.copysign(1.0, b)))
        inputs[target].append(
            _Input(
                names.constant_resistor(target),
                node,
                K * G[i] * abs(b),
                float(b),
                f"constant -> {target} integrator (b0[{target}])",
            )
        )


def _add_nonlinear(system, builder, names, nodes, inputs, G, K, options) -> list:
    """Each piecewise-linear term: its signal, then a switch and a resistor per entry.

    Returns (term, TermSignal) pairs.
    """
    built = []
    terms = TermBuilder(builder, list(system.states), nodes, G, options.r_unit)
    circuit = builder.circuit
    for t, term in enumerate(system.nonlinear, start=1):
        signal = terms.build(term, options.nonlinear)
        built.append((term, signal))
        direction = np.asarray(term.direction, dtype=float)
        used = np.flatnonzero(direction)
        prefix = node_name(term.name).upper()
        model = f"SW_{prefix}"
        circuit.models[model.lower()] = Model(
            model,
            "SW",
            {"vt": 0.5, "vh": 0.0, "ron": options.switch_ron, "roff": options.switch_roff},
        )
        control = f"{prefix.lower()}_ctl"
        for i in used:
            target = system.states[i]
            node = signal.node if np.sign(direction[i]) == signal.sigma else signal.negated
            switch = names.switch(term.name, t, target, several=used.size > 1)
            inputs[target].append(
                _Input(
                    names.nonlinear_resistor(target, term.name, t),
                    f"{prefix.lower()}_sw{i + 1}",
                    K * G[i] * abs(direction[i]) / signal.beta,
                    float(direction[i]),
                    f"{term.name} -> {target} integrator (direction[{target}]), via {switch}",
                    series_extra=options.switch_ron,
                    switch=(switch, node, control, model),
                )
            )
        source = names.generic(f"V{prefix}_CTL", f"switch control of {term.name}")
        if term.t_on is None or term.t_on <= 0:
            circuit.add(VoltageSource(source, control, "0", dc=1.0))
        elif math.isinf(term.t_on):  # never: the block is there, the switch stays open
            circuit.add(VoltageSource(source, control, "0", dc=0.0))
        else:
            t_on = float(f"{term.t_on / K:.12g}")
            ramp = float(f"{t_on * 1e-4:.6g}")
            circuit.add(
                VoltageSource(
                    source,
                    control,
                    "0",
                    waveform=Pwl(((0.0, 0.0), (t_on, 0.0), (t_on + ramp, 1.0))),
                )
            )

    return built


def _choose_capacitor(gains: list[float], options: SynthesisOptions) -> float:
    """The decade capacitor that keeps R = 1/(gain C) inside [r_min, r_max] best.

    Worked in decades (log10 R = -log10 gain - log10 C): a gain of 1e-320 1/s has a resistor
    beyond the float range, which must still get a cost, not a math domain error.
    """
    low, high = math.log10(options.r_min), math.log10(options.r_max)
    mid = (low + high) / 2

    def cost(c: float) -> tuple[float, float]:
        outside = inside = 0.0
        for g in gains:
            r = -math.log10(g) - math.log10(c)
            outside += max(0.0, low - r, r - high)
            inside += (r - mid) ** 2
        return (round(outside, 9), inside)

    return min(CAPACITOR_DECADES, key=cost)


def _is_linear(inp: _Input) -> bool:
    """An A entry's resistor from a state node: a parallel pair may replace it (a switched or
    forcing path stays one resistor per path, as the mapping check reads it)."""
    return inp.switch is None and "(A[" in inp.role


def _check_gains(state: str, inputs: list[_Input]) -> None:
    """Refuse an input whose resistor 1/(gain C) is no number for any capacitor decade.

    A coefficient such as 1e-320 (or one that the time and amplitude scales push past the
    float range) would otherwise end as a division by zero or an infinite resistance.
    """
    for inp in inputs:
        gain = float(inp.gain)
        smallest = gain * min(CAPACITOR_DECADES)  # 0 when it underflows
        if not (math.isfinite(gain) and smallest > 0 and math.isfinite(1.0 / smallest)):
            raise SynthesisError(
                f"{inp.role}: the coefficient {inp.target:.3g} becomes {inp.gain:.3g} 1/s of "
                f"circuit time with the scales, which no resistor into the integrator of {state} "
                "can realize; set so small a coefficient to 0, or change the scaling "
                "(--range, --time-scale)"
            )


def _add_integrator(builder, names, state, state_nodes, state_inputs, options, warnings) -> None:
    """Integrator (op-amp, capacitor, input resistors, switches) and inverter of one state."""
    circuit = builder.circuit
    plus, minus = state_nodes
    junction, inv_junction = plus + "_sum", plus + "_inv"
    if not state_inputs:
        warnings.append(f"state {state} has no inputs: its integrator only holds x0")
    _check_gains(state, state_inputs)
    capacitance = _choose_capacitor([inp.gain for inp in state_inputs] or [1.0], options)
    cap = names.capacitor(state)
    circuit.add(Capacitor(cap, minus, junction, capacitance))
    builder.bom.append(
        BomEntry(cap, capacitance, "F", "decade", f"integrator capacitor of {state}")
    )
    for inp in state_inputs:
        ideal = 1.0 / (inp.gain * capacitance)
        far = inp.node
        if inp.switch is not None:
            switch, signal, control, model = inp.switch
            circuit.add(Switch(switch, signal, inp.node, control, "0", model=model))
        total = builder.place_resistor(
            inp.name, far, junction, ideal, inp.role, inp.target, inp.series_extra,
            parallel=_is_linear(inp),
            pair_tolerance=builder.chain_tolerance if inp.switch is not None else None,
        )  # fmt: skip
        if not options.r_min <= total <= options.r_max:
            warnings.append(
                f"{inp.name} = {total:.4g} ohm is outside {options.r_min:g}..{options.r_max:g} "
                f"ohm ({inp.role})"
            )
    add_opamp(circuit, names.opamp_section(state, "integrator"), "0", junction, minus,
              builder.opamp_kind)  # fmt: skip
    r_in, r_fb = names.inverter_resistors(state)
    for name, a, b, role in (
        (r_in, minus, inv_junction, f"inverter input of {state}"),
        (r_fb, inv_junction, plus, f"inverter feedback of {state}"),
    ):
        builder.place_resistor(name, a, b, options.r_unit, role, series="exact")
    add_opamp(circuit, names.opamp_section(state, "inverter"), "0", inv_junction, plus,
              builder.opamp_kind)  # fmt: skip
