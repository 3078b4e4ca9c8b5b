"""The project's main job: the paper's figures and a validation report, in one run.

    scenarios (V = 55 m/s; f = 3, 5, 10 Hz; flange off/on)
        |-- ODE (kink events) ----------------------------> Fig. 4, reference traces
        |-- circuit per {ideal, tl074} x {exact, E96} ----> netlist + scale file + BOM
                |-- engines {builtin, ngspice} -----------> traces --> metrics vs ODE
    free response at 54 and 57 m/s ----------------------> Fig. 3
    eigenvalues against speed, realized critical speeds -> stability figure
    everything ------------------------------------------> report.md, metrics.json, Fig. 6

The cases are independent, so they run in a process pool (``workers``, default every core;
the cases and their jobs: :mod:`.reproduce_cases`).
Each engine run that cannot happen here is a row saying ``not available: <reason>``, never a
number. Progress goes through the ``progress`` callback; the library prints nothing.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from circuitsim.atomic import write_text_atomic
from circuitsim.compare.case import engine_available
from circuitsim.compare.comparison import Comparison, Thresholds, compare_traces
from circuitsim.compare.mapping import Trace
from circuitsim.studies.reproduce_cases import (
    PAPER_SCENARIOS,
    CircuitInfo,
    Scenario,
    Variant,
    circuit_job,
    free_job,
    ode_job,
    schematic_job,
)

OPAMPS = ("ideal", "tl074")
SERIES = ("exact", "E96")
# the hunting diagram in the report: a coarse grid around the critical speed, short steps
HUNTING_SPEEDS = (54.0, 55.0, 56.0, 57.0, 58.0)
HUNTING_PUSH, HUNTING_SETTLE, HUNTING_RECORD = 0.005, 2.0, 1.0
# the tolerance section: a few tens of circuits of the first scenario (docs/tolerances.md)
TOLERANCE_SAMPLES = 40
FREE_SPEEDS = (54.0, 57.0)


@dataclass
class Row:
    """One scenario x variant: the comparison, or why there is none."""

    scenario: Scenario
    variant: Variant
    status: str
    comparison: Comparison | None = None
    simulation_s: float = float("nan")
    points: int = 0


@dataclass
class Reproduction:
    """Everything a run produced (what :mod:`circuitsim.studies.report` renders)."""

    out_dir: Path
    scenarios: tuple[Scenario, ...]
    rows: list[Row]
    circuits: dict[tuple[str, str, str], CircuitInfo]
    engines: dict[str, str | None]
    critical_speed: float
    hunting_frequency: float
    ode_summary: dict[str, dict[str, float]]
    free_summary: dict[float, float]
    figures: dict[str, str] = field(default_factory=dict)
    wall_s: float = 0.0
    workers: int = 1
    mode_frequency: dict[float, float] = field(default_factory=dict)
    kernel_warm_up_s: float | None = None  # the builtin engine's kernels made ready, s
    hunting: dict | None = None  # the hunting diagram's summary (HuntingResult.summary)
    knobs: list = field(default_factory=list)  # the speed knob of the drawn circuit
    knob_netlist: str = ""
    schematic_problem: str | None = None
    tolerance: dict | None = None  # the Monte Carlo's summary (studies.tolerance_report)
    frequency: dict | None = None  # FRF and stepped sine (studies.frequency_report)


# --- the run -------------------------------------------------------------------------------


def reproduce(
    out_dir: str | os.PathLike,
    progress: Callable[[str], None] | None = None,
    scenarios: tuple[Scenario, ...] = PAPER_SCENARIOS,
    opamps: tuple[str, ...] = OPAMPS,
    series: tuple[str, ...] = SERIES,
    engines: tuple[str, ...] = ("builtin", "ngspice"),
    free_speeds: tuple[float, ...] = FREE_SPEEDS,
    workers: int | None = None,
    hunting_speeds: tuple[float, ...] = HUNTING_SPEEDS,
    tolerance_samples: int = TOLERANCE_SAMPLES,
    frequency_response: bool = True,
    stepped_sine_frequencies: tuple[float, ...] | None = None,
    n_points: int = 4096,
    skip: dict[tuple[str, str], str] | None = None,
    ngspice_timeout: float | None = None,
    figure_format: str = "png",
    dpi: float | None = None,
) -> Reproduction:
    """Run the paper's cases and write figures, netlists, report.md and metrics.json.

    Parameters
    ----------
    out_dir : path-like
        Created if missing: ``report.md``, ``metrics.json``, ``figures/*.png``,
        ``netlists/<scenario>-<opamp>-<series>.{cir,scale.json,bom.csv,order.csv}``.
    progress : callable, optional
        Called with one line per finished step.
    scenarios, opamps, series, engines : tuples
        What to run (defaults: the six paper scenarios x {ideal, tl074} x {exact, E96} x
        {builtin, ngspice}); an engine that cannot run here gives "not available" rows.
    free_speeds : tuple of float
        Speeds of the free-response figure (m/s); empty to skip it.
    hunting_speeds : tuple of float
        Increasing speeds of the hunting bifurcation diagram (m/s; ODE and builtin circuit,
        flange on and off, up then down: :mod:`circuitsim.studies.hunting`); empty to skip it.
    tolerance_samples : int
        Circuits of the tolerance section (1 % resistors, 5 % capacitors, the first
        scenario: :mod:`circuitsim.studies.tolerance_report`); 0 to skip it.
    frequency_response : bool
        The frequency-response section (:mod:`circuitsim.studies.frequency_report`): the
        FRF inside the clearance on every available engine and a stepped sine with the
        flange on.
    stepped_sine_frequencies : tuple of float, optional
        Its stepped sine's frequencies, Hz (default ``STEPPED_SINE_FREQUENCIES``; empty:
        the FRF alone).
    workers : int, optional
        Processes (default: every core).
    n_points : int
        Common-grid points of each comparison.
    skip : dict of (engine, op-amp) to str, optional
        Pairs not run, each reported with its reason (default: none; a full run takes about
        a minute on two cores, docs/validation.md).
    ngspice_timeout : float, optional
        Seconds before each ngspice run is stopped (default 300); a run stopped is a
        "failed" row naming the limit.
    figure_format : str
        Format of the figures (``png``, ``svg``, ``pdf``: their files' suffix).
    dpi : float, optional
        Resolution of PNG figures, dots per inch (default
        :data:`circuitsim.figure_style.DEFAULT_DPI`).

    Returns
    -------
    Reproduction
    """
    from circuitsim.compare.paper_figures import plot_free_response, plot_growth_rate
    from circuitsim.mechanics import critical_speed, eigenvalues, load_model
    from circuitsim.studies.report import render_report, reproduction_json

    say = progress or (lambda message: None)
    started = time.perf_counter()
    out = Path(out_dir)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    (out / "netlists").mkdir(parents=True, exist_ok=True)
    workers = workers or os.cpu_count() or 1
    available = {engine: engine_available(engine) for engine in engines}
    for engine, reason in available.items():
        say(f"engine {engine}: {'available' if reason is None else reason}")

    model = load_model()
    v_c, f_h = critical_speed(model)
    say(f"model critical speed {v_c:.4f} m/s, hunting frequency {f_h:.3f} Hz")
    fmt = figure_format
    jobs, skipped = _plan(
        out, scenarios, opamps, series, engines, free_speeds, available, skip or {},
        ngspice_timeout, fmt, dpi,
    )  # fmt: skip
    warm_up_s = None
    initializer = None
    if "builtin" in engines and available["builtin"] is None:
        # built here once (first use after an install), then loaded by each worker before its
        # first job: no row's simulation time includes either
        from circuitsim.solver.compiled import warm_up

        warm_up_s = warm_up()
        if warm_up_s is not None:
            say(f"compiled kernels ready in {warm_up_s:.1f} s")
            initializer = warm_up
    outcomes = _run_jobs(jobs, workers, initializer, say, fmt)
    figures = outcomes.figures
    rows, circuits, traces_by = _compared_rows(outcomes, skipped, n_points)
    rows.sort(key=lambda r: _row_order(r, scenarios, opamps, series, engines))

    if outcomes.free:
        plot_free_response(out / "figures" / f"fig3-free-response.{fmt}", outcomes.free, dpi=dpi)
        figures["fig3"] = f"figures/fig3-free-response.{fmt}"
    speeds = np.linspace(40.0, 70.0, 301)
    rates = eigenvalues(model, "V", speeds)[:, 0].real
    realized: dict[str, list[float]] = {}
    for (_, _, s), info in sorted(circuits.items()):
        realized.setdefault(f"{s} circuits", []).append(info.critical_speed_realized)
    plot_growth_rate(
        out / "figures" / f"critical-speed.{fmt}", speeds, rates, v_c, realized, dpi=dpi
    )
    figures["critical-speed"] = f"figures/critical-speed.{fmt}"
    hunting = None
    if hunting_speeds:
        figure = out / "figures" / f"hunting.{fmt}"
        hunting = _hunting_diagram(model, v_c, hunting_speeds, figure, dpi)
        figures["hunting"] = f"figures/hunting.{fmt}"
        say(f"hunting diagram: {len(hunting_speeds)} speeds, {hunting['wall_s']:.1f} s")
    tolerance = None
    if tolerance_samples and scenarios:
        from circuitsim.studies.tolerance_report import tolerance_study

        first = scenarios[0]
        tolerance = tolerance_study(first.system(model), first.title, tolerance_samples,
                                    out / "figures" / f"tolerance.{fmt}", workers, dpi)  # fmt: skip
        figures["tolerance"] = f"figures/tolerance.{fmt}"
        say(f"tolerance: {tolerance_samples} circuits, {tolerance['wall_s']:.1f} s")
    frequency = None
    if frequency_response:
        from circuitsim.studies.frequency_report import (
            STEPPED_SINE_FREQUENCIES,
            frequency_study,
        )

        steps = stepped_sine_frequencies
        frequency = frequency_study(
            model, available, out / "figures" / f"frf.{fmt}",
            out / "figures" / f"stepped-sine.{fmt}",
            STEPPED_SINE_FREQUENCIES if steps is None else tuple(steps), dpi,
        )  # fmt: skip
        figures["frf"] = f"figures/frf.{fmt}"
        if "stepped_sine" in frequency:
            figures["stepped_sine"] = f"figures/stepped-sine.{fmt}"
        say(f"frequency response: {frequency['wall_s']:.1f} s")
    _fig6_figures(out, scenarios, engines, outcomes.references, traces_by, figures, fmt, dpi)
    say("figures written")

    # Frequency of the slowest (hunting) mode at each simulated speed, Hz: what a free-motion
    # difference between circuit and ODE oscillates at.
    modes = {}
    for speed in sorted({sc.speed for sc in scenarios}):
        slowest = eigenvalues(model, "V", [speed])[0, 0]
        modes[speed] = float(abs(slowest.imag) / (2 * np.pi))
    result = Reproduction(
        out,
        tuple(scenarios),
        rows,
        circuits,
        available,
        v_c,
        f_h,
        outcomes.ode_summary,
        outcomes.free_summary,
        figures,
        time.perf_counter() - started,
        workers,
    )
    result.mode_frequency = modes
    if outcomes.schematic is not None:
        result.knobs, result.knob_netlist, result.schematic_problem = outcomes.schematic
        if result.schematic_problem is not None:
            figures.pop("schematic", None)
    result.kernel_warm_up_s = warm_up_s
    result.hunting = hunting
    result.tolerance = tolerance
    result.frequency = frequency
    write_text_atomic(out / "metrics.json", json.dumps(reproduction_json(result), indent=1) + "\n")
    write_text_atomic(out / "report.md", render_report(result))
    result.wall_s = time.perf_counter() - started
    say(f"report and metrics written ({result.wall_s:.1f} s)")
    return result


_JOBS = {"circuit": circuit_job, "ode": ode_job, "free": free_job, "schematic": schematic_job}
# rough CPU seconds of a circuit job measured here, by (engine, op-amp); others 0.8 s
_COST = {("builtin", "ideal"): 9.0, ("builtin", "tl074"): 1000.0, ("ngspice", "tl074"): 3.5}


def _plan(out, scenarios, opamps, series, engines, free_speeds, available, skip, timeout, fmt, dpi):
    """The pool's jobs as (kind, arguments), the longest first so that the workers finish
    together, and the rows not run as asked by ``skip`` (each with its reason). The first
    available engine's circuit jobs write the netlists."""
    jobs, skipped = [], []
    writer = next((e for e in engines if available[e] is None), engines[0] if engines else None)
    for engine in sorted(engines, key=lambda e: e != "builtin"):
        for opamp in sorted(opamps, key=lambda o: o == "ideal"):
            for s in series:
                for scenario in scenarios:
                    variant = Variant(opamp, s, engine)
                    reason = skip.get((engine, opamp))
                    if reason is not None and engine != writer:
                        skipped.append(Row(scenario, variant, reason))
                        continue
                    path = None
                    if engine == writer:
                        path = str(out / "netlists" / f"{scenario.name}-{opamp}-{s.lower()}.cir")
                    jobs.append(("circuit", (scenario, variant, path, reason, timeout)))
    ode_jobs = [
        ("ode", (sc, str(out / "figures" / f"fig4-{sc.name}.{fmt}"), dpi)) for sc in scenarios
    ]
    free_jobs = [("free", (speed,)) for speed in free_speeds]
    drawn = next((sc for sc in scenarios if sc.flange), scenarios[0] if scenarios else None)
    if drawn is not None and 40.0 <= drawn.speed <= 70.0:
        free_jobs.append(("schematic", (drawn, str(out))))

    def cost(job) -> float:
        return _COST.get((job[1][1].engine, job[1][1].opamp), 0.8)

    jobs.sort(key=lambda job: -cost(job))
    everything = [j for j in jobs if cost(j) > 1.5]
    everything += ode_jobs + free_jobs + [j for j in jobs if j not in everything]
    return everything, skipped


@dataclass
class _Outcomes:
    """What the pool's jobs returned, by kind, and the figures they drew."""

    references: dict[str, dict[str, Trace]] = field(default_factory=dict)
    ode_summary: dict[str, dict] = field(default_factory=dict)
    free: dict[float, Trace] = field(default_factory=dict)
    free_summary: dict[float, float] = field(default_factory=dict)
    circuits: list[tuple] = field(default_factory=list)  # circuit_job's returns
    schematic: tuple | None = None  # schematic_job's (knobs, netlist, problem)
    figures: dict[str, str] = field(default_factory=dict)


def _run_jobs(jobs, workers: int, initializer, say, fmt: str = "png") -> _Outcomes:
    """Run ``jobs`` in a pool of ``workers`` processes, one progress line per finished job."""
    got = _Outcomes()
    with ProcessPoolExecutor(max_workers=workers, initializer=initializer) as pool:
        futures = {pool.submit(_JOBS[kind], *args): (kind, args) for kind, args in jobs}
        for done, future in enumerate(as_completed(futures), start=1):
            kind, args = futures[future]
            value = future.result()
            count = f"[{done}/{len(jobs)}]"
            if kind == "ode":
                name, traces, summary = value
                got.references[name], got.ode_summary[name] = traces, summary
                got.figures[f"fig4-{name}"] = f"figures/fig4-{name}.{fmt}"
                say(f"{count} ODE {args[0].title}: max |y| {summary['max_abs_y_mm']:.3f} mm")
            elif kind == "schematic":
                got.schematic = value
                got.figures["schematic"] = "figures/schematic.png"
                say(f"{count} schematic and speed knob: {value[2] or 'drawn'}")
            elif kind == "free":
                speed, trace, peak = value
                got.free[speed], got.free_summary[speed] = trace, peak
                say(f"{count} free response at {speed:g} m/s: max |y| over 9-10 s {peak:.4g} m")
            else:
                got.circuits.append(value)
                variant, scenario, status, _, _, elapsed, _ = value
                timing = f" ({elapsed:.1f} s)" if status == "ok" else ""
                say(f"{count} {scenario.title} | {variant.label}: {status}{timing}")
    return got


def _compared_rows(outcomes: _Outcomes, skipped: list[Row], n_points: int):
    """Every circuit job's row, compared with its scenario's ODE reference where it ran; the
    written netlists by (scenario, op-amp, series); the mapped traces by (scenario, variant)."""
    rows, circuits, traces_by = list(skipped), {}, {}
    units = {"y": "m", "psi": "rad", "y_dot": "m/s", "psi_dot": "rad/s"}
    for variant, scenario, status, traces, info, elapsed, points in outcomes.circuits:
        if info is not None:
            circuits[(scenario.name, variant.opamp, variant.series)] = info
        comparison = None
        if status == "ok":
            comparison = compare_traces(
                outcomes.references[scenario.name],
                traces,
                Thresholds.for_opamp(variant.opamp),
                n_points,
                units,
                f"{scenario.title} | {variant.label}",
            )
            traces_by[(scenario.name, variant)] = traces
        rows.append(Row(scenario, variant, status, comparison, elapsed, points))
    return rows, circuits, traces_by


def _fig6_figures(
    out: Path, scenarios, engines, references, traces_by, figures, fmt="png", dpi=None
) -> None:
    """Per scenario, the chosen circuits (:func:`_fig6_variants`) over the ODE, with errors."""
    from circuitsim.compare.plots import plot_overlay

    for scenario in scenarios:
        curves = {}
        for variant in _fig6_variants(engines):
            if (scenario.name, variant) in traces_by:
                curves[variant.label] = traces_by[(scenario.name, variant)]
        if curves:
            name = f"fig6-{scenario.name}"
            plot_overlay(
                out / "figures" / f"{name}.{fmt}",
                references[scenario.name],
                curves,
                states=["y", "y_dot"],
                units={"y": "mm", "y_dot": "m/s"},
                scales={"y": 1000.0},
                title=f"circuit over ODE: {scenario.title}",
                errors=True,
                dpi=dpi,
            )
            figures[name] = f"figures/{name}.{fmt}"


def _hunting_diagram(model, v_c: float, speeds, path: Path, dpi: float | None = None) -> dict:
    """The hunting bifurcation diagram of the wheelset (free response from a 5 mm push), its
    figure written to ``path``; returns its summary with ``wall_s``."""
    from circuitsim.studies.hunting import run_hunting
    from circuitsim.studies.hunting_plot import plot_hunting
    from circuitsim.studies.hunting_result import HuntingSettings

    started = time.perf_counter()

    def free(speed: float, flange: bool):
        return model.system(
            parameters={"V": speed, "a": 0.0, "y0": HUNTING_PUSH},
            nonlinear={name: flange for name in model.nonlinear_terms},
        )

    settings = HuntingSettings(settle=HUNTING_SETTLE, record=HUNTING_RECORD)
    result = run_hunting(free, np.asarray(speeds, dtype=float), "V", "m/s", settings,
                         linear_critical=v_c)  # fmt: skip
    plot_hunting(result, path, dpi)
    return {**result.summary(), "wall_s": time.perf_counter() - started}


def _fig6_variants(engines: tuple[str, ...]) -> list[Variant]:
    """The circuits drawn over the ODE: the ideal exact design on our engine, and the paper's
    realistic one (TL074, E96 values) on the referee."""
    chosen = [Variant("ideal", "exact", "builtin"), Variant("tl074", "E96", "ngspice")]
    if "builtin" not in engines:
        chosen[0] = Variant("ideal", "exact", "ngspice")
    return chosen


def _row_order(row: Row, scenarios, opamps, series, engines) -> tuple[int, int, int, int]:
    return (
        scenarios.index(row.scenario),
        opamps.index(row.variant.opamp),
        series.index(row.variant.series),
        engines.index(row.variant.engine),
    )
