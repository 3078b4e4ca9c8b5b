"""Monte Carlo over part tolerances and op-amp offsets: what a bench build of the circuit does.

    System --synthesize once--> base Circuit + ScaleMap
        --draw (seeded)--> N circuits: every R and C off by its own relative error, every TL074
                           section with its own input offset
            |-- mapping check of each (cheap) --> realized A --> realized critical speed
            |-- simulate_variants (compiled loop, threads) --> traces --> metrics vs the ODE
        --> distributions, yield at the thresholds, JSON, histograms

Distributions. ``uniform``: a part of tolerance t is off by e ~ U(-t, t) (relative), an offset
of size v is U(-v, v) volts. ``gaussian``: a tolerance is three standard deviations (e ~ N(0,
(t/3)^2): 99.7 % of parts within the marked tolerance), an offset size is one standard
deviation (the datasheet's "typical" taken as sigma). The draws come from
``numpy.random.default_rng(seed)`` in a fixed order (all resistors, then all capacitors, then
all offsets, sample by sample), so a seed gives the same circuits whatever ``workers`` is.
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from circuitsim.compare.comparison import Thresholds
from circuitsim.compare.errors import ComparisonError
from circuitsim.mechanics.system import System
from circuitsim.netlist.circuit import Capacitor, Circuit, Resistor
from circuitsim.synthesis.offsets import apply_opamp_errors, opamp_sections
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.translator import Synthesis, synthesize

DISTRIBUTIONS = ("uniform", "gaussian")

Progress = Callable[[float, str], None]
"""Progress callback: fraction done (0..1) and a short message."""


@dataclass(frozen=True)
class Tolerances:
    """What varies from part to part.

    Attributes
    ----------
    resistor, capacitor : float
        Relative tolerance (0.01 = 1 %).
    offset : float
        Input offset voltage size of every TL074 section, volts (0: none).
    distribution : {"uniform", "gaussian"}
        See the module docstring for what a tolerance means in each.
    """

    resistor: float = 0.01
    capacitor: float = 0.05
    offset: float = 0.0
    distribution: str = "uniform"

    def validated(self) -> Tolerances:
        """Self, or ComparisonError naming the bad field."""
        if self.distribution not in DISTRIBUTIONS:
            raise ComparisonError(
                f"distribution {self.distribution!r}: choose one of {', '.join(DISTRIBUTIONS)}"
            )
        for name in ("resistor", "capacitor"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0 <= value < 1):
                raise ComparisonError(f"{name} tolerance {value!r}: must be in [0, 1)")
        if not (math.isfinite(self.offset) and self.offset >= 0):
            raise ComparisonError(f"offset {self.offset!r}: must be a number of volts >= 0")
        if self.distribution == "gaussian" and max(self.resistor, self.capacitor) >= 0.3:
            # three sigma at 30 % reaches a negative part value within a few million draws
            raise ComparisonError("gaussian tolerances must be below 30 % (3 sigma < 1)")
        return self

    def draw(
        self, rng: np.random.Generator, size: float, shape: tuple[int, ...], offset: bool = False
    ) -> np.ndarray:
        """Relative errors of parts of tolerance ``size`` (or offsets of ``size`` volts with
        ``offset``), shape ``shape``."""
        if size == 0:
            return np.zeros(shape)
        if self.distribution == "uniform":
            return rng.uniform(-size, size, shape)
        return rng.normal(0.0, size if offset else size / 3.0, shape)


@dataclass
class ToleranceSamples:
    """The drawn circuits of a study.

    Attributes
    ----------
    circuits : list of Circuit
    resistor_errors, capacitor_errors : ndarray, shape (N, parts)
        Relative error of each resistor / capacitor (netlist order, names in ``resistors`` and
        ``capacitors``).
    offsets : ndarray, shape (N, sections)
        Volts per op-amp section (names in ``sections``).
    """

    circuits: list[Circuit]
    resistors: list[str]
    capacitors: list[str]
    sections: list[str]
    resistor_errors: np.ndarray
    capacitor_errors: np.ndarray
    offsets: np.ndarray


def draw_circuits(base: Circuit, tolerances: Tolerances, n: int, seed: int) -> ToleranceSamples:
    """``n`` copies of ``base`` with parts drawn within ``tolerances`` (seeded).

    Raises
    ------
    ComparisonError
        Offsets asked for a circuit without TL074 sections.
    """
    tolerances = tolerances.validated()
    rng = np.random.default_rng(seed)
    resistors = [e.name for e in base.elements if isinstance(e, Resistor)]
    capacitors = [e.name for e in base.elements if isinstance(e, Capacitor)]
    sections = [
        name for name, call in opamp_sections(base).items() if call.subcircuit.lower() == "tl074"
    ]
    if tolerances.offset and not sections:
        raise ComparisonError(
            "op-amp offsets need TL074 sections (opamp tl074); this circuit has ideal op-amps"
        )
    r_err = np.empty((n, len(resistors)))
    c_err = np.empty((n, len(capacitors)))
    vos = np.zeros((n, len(sections)))
    for k in range(n):  # sample by sample: the first k circuits do not depend on n
        r_err[k] = tolerances.draw(rng, tolerances.resistor, (len(resistors),))
        c_err[k] = tolerances.draw(rng, tolerances.capacitor, (len(capacitors),))
        if tolerances.offset:
            vos[k] = tolerances.draw(rng, tolerances.offset, (len(sections),), offset=True)
    circuits = []
    for k in range(n):
        circuit = copy.deepcopy(base)
        factors = dict(zip(resistors, 1.0 + r_err[k], strict=True))
        factors.update(zip(capacitors, 1.0 + c_err[k], strict=True))
        for element in circuit.elements:
            if isinstance(element, Resistor):
                element.resistance = float(element.resistance) * factors[element.name]
            elif isinstance(element, Capacitor):
                element.capacitance = float(element.capacitance) * factors[element.name]
        if tolerances.offset:
            apply_opamp_errors(circuit, dict(zip(sections, map(float, vos[k]), strict=True)))
        circuits.append(circuit)
    return ToleranceSamples(circuits, resistors, capacitors, sections, r_err, c_err, vos)


@dataclass
class ToleranceResult:
    """A tolerance study's outcome.

    Attributes
    ----------
    tolerances : Tolerances
    seed, n : int
    critical_speed_model : float or None
        The model's linear critical speed (m/s for the wheelset).
    critical_speed : ndarray, shape (N,)
        Each drawn circuit's realized critical speed (NaN: none in range / no speed hint).
    A_realized : ndarray, shape (N, n, n)
        Each drawn circuit's realized linear part (1/s, model time).
    metrics : dict of str to dict of str to ndarray
        Per state, ``nrmsd_percent``, ``peak_ratio``, ``frequency_ratio``, each shape (N,)
        (empty when not simulated).
    passed : ndarray of bool, shape (N,)
        Every state within ``thresholds``.
    thresholds : Thresholds
    speed : float or None
        The simulated speed (the model's speed parameter), if the model names one.
    timings : dict of str to float
        Wall seconds of ``synthesis``, ``realized`` (mapping checks), ``reference`` (the ODE),
        ``simulation`` (with each circuit's comparison, in the worker threads).
    kernel : str or None
        The compiled kernel the circuits ran on (``"ports"`` or ``"compiled"``, the MNA
        kernel: the one ``simulate`` chooses for the nominal circuit); None when not simulated.
    """

    tolerances: Tolerances
    seed: int
    n: int
    critical_speed_model: float | None
    critical_speed: np.ndarray
    A_realized: np.ndarray
    metrics: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    passed: np.ndarray | None = None
    thresholds: Thresholds | None = None
    timings: dict[str, float] = field(default_factory=dict)
    speed_unit: str = "m/s"
    speed: float | None = None
    kernel: str | None = None

    @property
    def unstable_fraction(self) -> float | None:
        """Fraction of drawn circuits whose realized critical speed is at or below the
        simulated ``speed`` (their linear part grows there); None without a speed."""
        if self.speed is None or not np.isfinite(self.critical_speed).any():
            return None
        return float(np.mean(self.critical_speed <= self.speed))

    @property
    def yield_fraction(self) -> float | None:
        """Fraction of drawn circuits within every threshold (None when not simulated)."""
        return None if self.passed is None else float(np.mean(self.passed))

    def summary(self) -> dict:
        """Statistics of every distribution (mean, std, min, 5/50/95 %, max) as a dict."""
        out = {"critical_speed": describe(self.critical_speed)}
        for state, values in self.metrics.items():
            out[state] = {name: describe(v) for name, v in values.items()}
        return out

    def to_json(self) -> dict:
        """Everything, numbers as lists (NaN as None)."""

        def listed(a) -> list:
            return [None if not math.isfinite(float(x)) else float(x) for x in np.ravel(a)]

        return {
            "tolerances": {
                "resistor": self.tolerances.resistor,
                "capacitor": self.tolerances.capacitor,
                "offset_volts": self.tolerances.offset,
                "distribution": self.tolerances.distribution,
                "convention": (
                    "uniform: U(-t, t); gaussian: a part tolerance is 3 sigma, an offset is 1 sigma"
                ),
            },
            "seed": self.seed,
            "n": self.n,
            "critical_speed_model": self.critical_speed_model,
            "critical_speed": listed(self.critical_speed),
            "speed": self.speed,
            "unstable_fraction": self.unstable_fraction,
            "metrics": {s: {k: listed(v) for k, v in m.items()} for s, m in self.metrics.items()},
            "passed": None if self.passed is None else [bool(p) for p in self.passed],
            "yield": self.yield_fraction,
            "thresholds": None if self.thresholds is None else vars(self.thresholds),
            "summary": self.summary(),
            "timings_s": self.timings,
            "kernel": self.kernel,
        }


def describe(values: np.ndarray) -> dict:
    """mean, std, min, p5, p50, p95, max over the finite values and how many were not."""
    v = np.asarray(values, dtype=float)
    finite = v[np.isfinite(v)]
    if finite.size == 0:
        return {"count": 0, "not_finite": int(v.size)}
    p5, p50, p95 = np.percentile(finite, [5, 50, 95])
    return {
        "count": int(finite.size),
        "not_finite": int(v.size - finite.size),
        "mean": float(np.mean(finite)),
        "std": float(np.std(finite, ddof=1)) if finite.size > 1 else 0.0,
        "min": float(np.min(finite)),
        "p5": float(p5),
        "p50": float(p50),
        "p95": float(p95),
        "max": float(np.max(finite)),
    }


def realized_linear_parts(
    circuits: list[Circuit],
    synthesis: Synthesis,
    system: System,
    progress: Progress | None = None,
) -> tuple[np.ndarray, np.ndarray, float | None]:
    """Each circuit's realized A (mapping check) and critical speed, and the model's.

    ``progress(fraction, message)`` is called after each circuit.

    Returns
    -------
    A : ndarray, shape (N, n, n)
    critical : ndarray, shape (N,)
        NaN where the check found none (no speed hint, or no crossing in range).
    model_critical : float or None
    """
    from circuitsim.synthesis.check import check_mapping

    A = np.empty((len(circuits), system.n, system.n))
    critical = np.full(len(circuits), np.nan)
    model = None
    for k, circuit in enumerate(circuits):
        # no BOM: every coefficient is compared exactly, so the drawn parts show as problems,
        # which are not the point here; the realized A and its critical speed are
        report = check_mapping(circuit, synthesis.scale_map, system)
        A[k] = report.A_realized
        model = report.critical_speed_model
        if report.critical_speed_realized is not None:
            critical[k] = report.critical_speed_realized
        if progress:
            progress((k + 1) / len(circuits), f"realized {k + 1} of {len(circuits)} circuits")
    return A, critical, model


def run_tolerance(
    system: System,
    tolerances: Tolerances,
    n: int = 100,
    seed: int = 0,
    options: SynthesisOptions | None = None,
    simulate: bool = True,
    thresholds: Thresholds | None = None,
    workers: int | None = None,
    progress: Progress | None = None,
    max_step: float | None = None,
) -> ToleranceResult:
    """Draw ``n`` circuits within ``tolerances`` and measure what they realize and simulate.

    Parameters
    ----------
    system : System
        The scenario.
    tolerances : Tolerances
    n : int
        Drawn circuits (>= 1).
    seed : int
        Seed of ``numpy.random.default_rng``: the same seed, the same circuits.
    options : SynthesisOptions, optional
        Translator options of the base circuit (default: ideal op-amps; offsets need
        ``opamp="tl074"``). The base circuit's own values are the nominal parts.
    simulate : bool
        Simulate every drawn circuit (builtin engine, compiled loop, ``workers`` threads) and
        compare with the ODE; False: the realized critical speeds only.
    thresholds : Thresholds, optional
        Default: :meth:`Thresholds.for_opamp` of the options' op-amp (the reproduce ones).
    workers : int, optional
        Simulations at a time (threads).
    progress : callable(fraction, message), optional
    max_step : float, optional
        Largest step of the direct solution the circuits are compared with, model seconds
        (default unbounded).

    Raises
    ------
    ComparisonError, SynthesisError, SolverError
    """
    if not (isinstance(n, int) and n >= 1):
        raise ComparisonError(f"n={n!r}: at least one drawn circuit is needed")
    if not (isinstance(seed, int) and seed >= 0):
        raise ComparisonError(f"seed={seed!r}: must be an integer >= 0")
    options = options or SynthesisOptions()
    thresholds = thresholds or Thresholds.for_opamp(options.opamp)
    timings: dict[str, float] = {}
    started = time.perf_counter()
    synthesis = synthesize(system, options)
    samples = draw_circuits(synthesis.circuit, tolerances, n, seed)
    timings["synthesis"] = time.perf_counter() - started
    if progress:
        progress(0.0, f"{n} circuits drawn (seed {seed}); realized linear parts")
    started = time.perf_counter()
    A, critical, model_critical = realized_linear_parts(
        samples.circuits, synthesis, system, progress
    )
    timings["realized"] = time.perf_counter() - started
    result = ToleranceResult(tolerances, seed, n, model_critical, critical, A, timings=timings)
    hint = (system.circuit_hints or {}).get("speed")
    if isinstance(hint, dict) and hint.get("parameter", "V") in system.parameters:
        result.speed = float(system.parameters[hint.get("parameter", "V")])
    if not simulate:
        return result
    result.thresholds = thresholds
    metrics, passed, kernel = _simulate_and_compare(
        samples.circuits, synthesis, system, thresholds, workers, progress, timings, max_step
    )
    result.metrics, result.passed, result.kernel = metrics, passed, kernel
    return result


METRICS = ("nrmsd_percent", "peak_ratio", "frequency_ratio")
"""The metrics a tolerance study gathers (the ones the reproduce thresholds judge)."""


def state_metrics(reference: dict, circuit: dict, n_points: int = 4096) -> dict:
    """Per state, the metrics of :data:`METRICS` of ``circuit`` against ``reference`` on
    the common grid :func:`~circuitsim.compare.comparison.compare_traces` uses (same values;
    without its phase lag, whose optimisation costs most of a comparison)."""
    from circuitsim.compare import signals
    from circuitsim.compare.mapping import common_grid, resample

    names = [s for s in reference if s in circuit]
    grid = common_grid(reference[names[0]], circuit[names[0]], n_points)
    for name in names[1:]:
        other = common_grid(reference[name], circuit[name], n_points)
        grid = np.linspace(max(grid[0], other[0]), min(grid[-1], other[-1]), n_points)
    out = {}
    for name in names:
        ref, cand = resample(reference[name], grid), resample(circuit[name], grid)
        f_ref = signals.dominant_frequency(grid, ref)
        f_cand = signals.dominant_frequency(grid, cand)
        out[name] = {
            "nrmsd_percent": signals.nrmsd_percent(ref, cand),
            "peak_ratio": signals.peak_ratio(ref, cand),
            "frequency_ratio": float(f_cand / f_ref) if f_ref > 0 else float("nan"),
        }
    return out


def within(values: dict, thresholds: Thresholds) -> bool:
    """True when a state's metrics are within ``thresholds`` (a NaN metric is not judged, as
    in :class:`~circuitsim.compare.comparison.StateMetrics`)."""
    limits = (
        (values["nrmsd_percent"], thresholds.nrmsd_percent),
        (values["peak_ratio"] - 1.0, thresholds.peak_ratio_tolerance),
        (values["frequency_ratio"] - 1.0, thresholds.frequency_ratio_tolerance),
    )
    return not any(
        limit is not None and not math.isnan(v) and abs(v) > limit for v, limit in limits
    )


def _simulate_and_compare(
    circuits, synthesis, system, thresholds, workers, progress, timings, max_step=None
):
    """Every circuit through :func:`~circuitsim.solver.variants.simulate_variants` on the
    kernel ``simulate`` chooses for the nominal circuit, then its metrics against the ODE (one
    reference solution for all); returns (metrics, passed, kernel)."""
    from circuitsim.compare.case import reference_traces
    from circuitsim.compare.mapping import map_waveforms
    from circuitsim.solver.compiled import warm_up
    from circuitsim.solver.variants import simulate_variants, variants_kernel

    states = list(system.states)
    kernel = variants_kernel(synthesis.circuit)
    ready = warm_up((kernel,))
    if ready is not None:
        timings["kernels"] = ready
    started = time.perf_counter()
    _, reference = reference_traces(system, synthesis.t_stop, max_step=max_step)
    timings["reference"] = time.perf_counter() - started
    probes = [f"v({synthesis.scale_map.states[s].node})" for s in states]

    def advance(done: int, total: int) -> None:
        if progress:
            progress(done / total, f"simulated and compared {done} of {total} circuits")

    def reduce(_: int, waves) -> dict:
        # in the worker thread: only the metrics are kept, never N sets of traces
        return state_metrics(reference, map_waveforms(waves, synthesis.scale_map, states))

    started = time.perf_counter()
    values = simulate_variants(
        circuits, probes, workers=workers, progress=advance, reduce=reduce, kernel=kernel
    )
    timings["simulation"] = time.perf_counter() - started
    metrics = {s: {m: np.full(len(values), np.nan) for m in METRICS} for s in states}
    passed = np.zeros(len(values), dtype=bool)
    for k, per_state in enumerate(values):
        passed[k] = all(within(v, thresholds) for v in per_state.values())
        for s, v in per_state.items():
            for name in METRICS:
                metrics[s][name][k] = v[name]
    return metrics, passed, kernel


def plot_tolerance(result: ToleranceResult, path, state: str | None = None, dpi=None):
    """Histograms: the realized critical speed (for a model with one) and, when simulated,
    ``state``'s %NRMSD, peak ratio and frequency ratio against the ODE (thresholds dashed;
    ``state`` default: the first). Each histogram spans its values' robust range
    (:func:`circuitsim.figure_style.robust_range`); circuits outside it are counted in the
    panel's title. Written atomically in the format of ``path``'s suffix at ``dpi`` (PNG
    default: the house style's); returns the Figure.

    Raises
    ------
    ComparisonError
        ``state`` is not one of the simulated states.
    """
    from circuitsim.figure_style import style_context

    with style_context():
        return _plot_tolerance(result, path, state, dpi)


def _plot_tolerance(result: ToleranceResult, path, state: str | None, dpi):
    from circuitsim.figure_style import (
        DOUBLE_COLUMN,
        MARK,
        new_figure,
        robust_range,
        save_figure,
        series_style,
    )

    panels = []  # (kind, title, values, unit)
    if result.critical_speed_model is not None or np.isfinite(result.critical_speed).any():
        panels.append(("critical", "realized critical speed", result.critical_speed,
                       result.speed_unit))  # fmt: skip
    if result.metrics:
        state = state or next(iter(result.metrics))
        if state not in result.metrics:
            raise ComparisonError(f"state {state!r} is not one of {', '.join(result.metrics)}")
        m = result.metrics[state]
        panels += [
            ("nrmsd", f"{state}: NRMSD", m["nrmsd_percent"], "%"),
            ("peak", f"{state}: peak ratio", m["peak_ratio"], ""),
            ("frequency", f"{state}: frequency ratio", m["frequency_ratio"], ""),
        ]
    if not panels:  # no speed and not simulated: say so rather than draw empty axes
        panels.append(("critical", "realized critical speed (the model has none)",
                       result.critical_speed, result.speed_unit))  # fmt: skip
    columns = 2 if len(panels) > 1 else 1
    rows = math.ceil(len(panels) / columns)
    fig = new_figure(DOUBLE_COLUMN, 2.6 * rows + 0.5)
    axes = np.atleast_1d(fig.subplots(rows, columns)).ravel()
    for ax in axes[len(panels) :]:
        ax.set_visible(False)
    th = result.thresholds
    for ax, (kind, title, values, unit) in zip(axes, panels, strict=False):
        finite = np.asarray(values, dtype=float)
        finite = finite[np.isfinite(finite)]
        low, high, below, above = robust_range(finite)
        inside = finite[(finite >= low) & (finite <= high)]
        ax.hist(inside, bins=max(5, min(40, int(np.sqrt(max(inside.size, 1))) * 2)),
                range=(low, high), color=series_style(2)["color"], alpha=0.8)  # fmt: skip
        if kind == "critical" and result.critical_speed_model is not None:
            ax.axvline(result.critical_speed_model, **MARK, label="model")
            ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0))
        notes = []
        if th is not None and kind != "critical":
            notes += _threshold_marks(ax, kind, th, inside)
        ax.locator_params(axis="x", nbins=4)
        if below:
            notes.append(f"off scale: {below} below (min {finite.min():.6g})")
        if above:
            notes.append(f"off scale: {above} above (max {finite.max():.4g})")
        ax.set_title("\n".join([title, *notes]))  # above the axes, never over the bars
        ax.set_xlabel(f"{title.split(': ')[-1]} ({unit})" if unit else title.split(": ")[-1])
        ax.set_ylabel("circuits")
    tol = result.tolerances
    label = (
        f"R {100 * tol.resistor:g} %, C {100 * tol.capacitor:g} %, offsets "
        f"{1e3 * tol.offset:g} mV ({tol.distribution}); N = {result.n}, seed {result.seed}"
    )
    if result.yield_fraction is not None:
        label += f"; yield {100 * result.yield_fraction:.1f} %"
    fig.suptitle(label)
    save_figure(fig, path, dpi)
    return fig


def _threshold_marks(ax, kind: str, th: Thresholds, finite: np.ndarray) -> list[str]:
    """The threshold(s) of a ``kind`` panel (``nrmsd``, ``peak``, ``frequency``) as dashed
    lines, or as a note returned for the title when they lie far outside the drawn values (a
    line there would squeeze the histogram into one pixel)."""
    if kind == "nrmsd":
        edges = [th.nrmsd_percent]
    else:
        tol = th.peak_ratio_tolerance if kind == "peak" else th.frequency_ratio_tolerance
        edges = [1 - tol, 1 + tol]
    low, high = (float(np.min(finite)), float(np.max(finite))) if finite.size else (0.0, 1.0)
    span = max(high - low, 1e-12)
    near = [e for e in edges if low - 3 * span <= e <= high + 3 * span]
    for edge in near:
        ax.axvline(edge, color="#d55e00", ls="--", lw=1)
    if len(near) < len(edges):
        text = ", ".join(f"{e:g}" for e in edges if e not in near)
        return [f"threshold {text} off scale"]
    return []
