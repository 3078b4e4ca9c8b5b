"""The reproduction's cases and the jobs that run them (:mod:`circuitsim.studies.reproduce`).

A :class:`Scenario` is one forced-response case of the paper's Fig. 4, a :class:`Variant` how
its circuit is built and simulated. The jobs (module-level, so that the process pool can
pickle them) each run one case and never raise: the ODE reference of a scenario, a free
response, a scenario's circuit on one engine (with its netlist, scale file, BOM and mapping
check when it is the one written), the schematic with its speed knob.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from circuitsim.compare.case import engine_available, run_engine
from circuitsim.compare.mapping import Trace, map_waveforms


@dataclass(frozen=True)
class Scenario:
    """One forced-response case of the paper's Fig. 4 (built-in wheelset model).

    Attributes
    ----------
    frequency : float
        Excitation frequency, Hz.
    flange : bool
        Flange force (switch S1) on.
    speed : float
        Forward speed V, m/s.
    amplitude : float
        Equivalent track displacement a, m.
    t_stop : float
        Model seconds simulated.
    """

    frequency: float
    flange: bool
    speed: float = 55.0
    amplitude: float = 0.040
    t_stop: float = 5.0

    @property
    def name(self) -> str:
        """File-name friendly, e.g. ``f3-flange-on``."""
        return f"f{self.frequency:g}-flange-{'on' if self.flange else 'off'}"

    @property
    def title(self) -> str:
        """For figure titles and the report."""
        return (
            f"V = {self.speed:g} m/s, f = {self.frequency:g} Hz, "
            f"flange {'on' if self.flange else 'off'}"
        )

    def system(self, model):
        """The scenario's System of ``model`` (options speed, freq, amplitude)."""
        parameters = model.option_parameters(
            {"speed": self.speed, "freq": self.frequency, "amplitude": self.amplitude}
        )
        return model.system(
            parameters=parameters, nonlinear={n: self.flange for n in model.nonlinear_terms}
        )


PAPER_SCENARIOS = tuple(Scenario(f, on) for f in (3.0, 5.0, 10.0) for on in (False, True))


@dataclass(frozen=True)
class Variant:
    """How a scenario's circuit is built and simulated."""

    opamp: str
    series: str
    engine: str

    @property
    def label(self) -> str:
        return f"{self.engine}, {self.opamp}, {self.series}"


@dataclass
class CircuitInfo:
    """A written netlist: its scaling, BOM and mapping check."""

    scenario: Scenario
    opamp: str
    series: str
    netlist: str
    scale_map: object
    bom: list
    warnings: list[str]
    check_ok: bool
    check_summary: str
    max_coefficient_error: float
    critical_speed_model: float | None
    critical_speed_realized: float | None
    growth_rate_model: float | None = None
    growth_rate_realized: float | None = None
    # (coefficient, model value, realized value, relative error, parts) from the mapping check
    coefficients: list[tuple[str, float, float, float, str]] = field(default_factory=list)


def ode_job(
    scenario: Scenario, figure: str | None, dpi: float | None = None
) -> tuple[str, dict[str, Trace], dict]:
    from circuitsim.compare.case import reference_traces
    from circuitsim.compare.figures import plot_response
    from circuitsim.mechanics import load_model

    system = scenario.system(load_model())
    result, traces = reference_traces(system, scenario.t_stop)
    if figure is not None:
        plot_response(figure, result, title=f"ODE: {scenario.title}", samples=4001, dpi=dpi)
    summary = {
        "max_abs_y_mm": 1e3 * result.max_abs("y"),
        "y_end_mm": 1e3 * float(result.sol(scenario.t_stop)[result.states.index("y")]),
        "max_abs_y_dot": result.max_abs("y_dot"),
        "kinks": int(len(result.kinks)),
    }
    return scenario.name, traces, summary


def free_job(speed: float, t_stop: float = 10.0) -> tuple[float, Trace, float]:
    from circuitsim.mechanics import load_model, solve

    model = load_model()
    system = model.system(
        parameters={**model.option_parameters({"speed": speed, "y0": 0.005})},
        nonlinear={n: False for n in model.nonlinear_terms},
        forcing={n: False for n in model.forcing_terms},
    )
    result = solve(system, t_span=(0.0, t_stop))
    t = np.linspace(0.0, t_stop, 10001)
    y = result.sol(t)[result.states.index("y")]
    return speed, (t, y), result.max_abs("y", t_stop - 1.0, t_stop)


def circuit_job(
    scenario: Scenario,
    variant: Variant,
    netlist: str | None,
    skip_reason: str | None = None,
    ngspice_timeout: float | None = None,
) -> tuple[Variant, Scenario, str, dict | None, CircuitInfo | None, float, int]:
    """Synthesize (and, with ``netlist``, write and check) then simulate unless told to skip
    the simulation; never raises."""
    from circuitsim.mechanics import load_model
    from circuitsim.synthesis.options import SynthesisOptions

    info = None
    try:
        system = scenario.system(load_model())
        options = SynthesisOptions(
            opamp=variant.opamp, series=variant.series, t_stop=scenario.t_stop
        )
        if netlist is not None:
            from circuitsim.synthesis.generate import generate

            generated = generate(system, netlist, options)
            synthesis, report, path = generated.synthesis, generated.report, generated.netlist
            info = CircuitInfo(
                scenario,
                variant.opamp,
                variant.series,
                str(netlist),
                synthesis.scale_map,
                synthesis.bom,
                generated.warnings,
                report.ok,
                report.summary(),
                report.max_error,
                report.critical_speed_model,
                report.critical_speed_realized,
                _largest_real(report.eigenvalues_model),
                _largest_real(report.eigenvalues_realized),
                [(e.what, e.model, e.realized, e.error, "+".join(e.parts))
                 for e in report.entries],
            )  # fmt: skip
        else:
            from circuitsim.synthesis.translator import synthesize

            synthesis, path = synthesize(system, options), None
        reason = engine_available(variant.engine)
        if skip_reason is not None:
            return variant, scenario, skip_reason, None, info, float("nan"), 0
        if reason is not None:
            return variant, scenario, f"not available: {reason}", None, info, float("nan"), 0
        started = time.perf_counter()
        waves = run_engine(variant.engine, synthesis.circuit, path, ngspice_timeout)
        elapsed = time.perf_counter() - started
        traces = map_waveforms(waves, synthesis.scale_map, list(system.states))
        return variant, scenario, "ok", traces, info, elapsed, len(waves.time)
    except Exception as exc:  # noqa: BLE001 - a failed case is a row of the report, not a crash
        message = " ".join(str(exc).split())[:300]
        return variant, scenario, f"failed: {type(exc).__name__}: {message}", None, info, 0.0, 0


def schematic_job(scenario: Scenario, out: str, low: float = 40.0, high: float = 70.0):
    """The paper's circuit as one would build it (TL074 sections, E96 parts, the speed knob
    over ``low``-``high`` m/s): netlist, BOMs, dial table and the editable KiCad schematic
    (with its SPICE library) in ``out``/netlists, the drawing (PNG and SVG) in
    ``out``/figures. Returns (knobs, netlist, problem); never raises (a failure is the
    report's sentence, not a crash)."""
    from functools import cache

    from circuitsim.mechanics import load_model
    from circuitsim.synthesis.generate import generate
    from circuitsim.synthesis.knob import KnobRequest
    from circuitsim.synthesis.options import SynthesisOptions
    from circuitsim.synthesis.schematic import save_schematic

    try:
        model = load_model()
        system = scenario.system(model)

        @cache
        def linear_part(speed: float):
            return replace(scenario, speed=speed).system(model).A

        netlist = Path(out) / "netlists" / f"{scenario.name}-tl074-e96-knob.cir"
        generated = generate(
            system,
            netlist,
            SynthesisOptions(opamp="tl074", series="E96", t_stop=scenario.t_stop),
            knob=KnobRequest("V", low, high, linear_part, "m/s"),
            schematic=Path(out) / "figures" / "schematic.png",
            kicad=netlist.with_suffix(".kicad_sch"),
        )
        save_schematic(
            generated.synthesis.circuit,
            Path(out) / "figures" / "schematic.svg",
            list(system.states),
            generated.synthesis.bom,
        )
        return generated.knobs, str(netlist), None
    except Exception as exc:  # noqa: BLE001 - reported, not raised
        return [], "", f"{type(exc).__name__}: {' '.join(str(exc).split())[:300]}"


def _largest_real(eigenvalues) -> float | None:
    """Largest real part (1/s): the decay (negative) or growth rate of the slowest mode."""
    if eigenvalues is None or len(eigenvalues) == 0:
        return None
    return float(np.max(np.real(eigenvalues)))
