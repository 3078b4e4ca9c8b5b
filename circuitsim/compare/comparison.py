"""Circuit traces against reference traces, state by state, with pass/fail thresholds.

    reference (ODE) traces --+
                             +--> common uniform grid --> per-state metrics --> Comparison
    circuit traces ---------+                                                   (.passed)

The metrics (see :mod:`circuitsim.compare.signals`): %NRMSD, max abs error, peak-amplitude
ratio, dominant-frequency ratio and phase lag (positive = circuit lags the reference).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from circuitsim.compare import signals
from circuitsim.compare.errors import ComparisonError
from circuitsim.compare.mapping import Trace, common_grid, resample


@dataclass(frozen=True)
class Thresholds:
    """Limits a comparison must meet; ``None`` leaves a metric unjudged.

    Attributes
    ----------
    nrmsd_percent : float
        Largest %NRMSD (0.5 for ideal op-amps with exact values; 2 is the target for TL074).
    peak_ratio_tolerance : float
        Largest ``|peak_ratio - 1|`` (0.01 = within 1 %).
    frequency_ratio_tolerance : float
        Largest ``|frequency_ratio - 1|``.
    max_abs_error : float or None
        Largest max abs error, in each state's unit (one number for all states, so off).
    phase_lag_s : float or None
        Largest ``|phase_lag|`` in model seconds.
    """

    nrmsd_percent: float = 0.5
    peak_ratio_tolerance: float = 0.01
    frequency_ratio_tolerance: float = 0.01
    max_abs_error: float | None = None
    phase_lag_s: float | None = None

    @classmethod
    def for_opamp(cls, opamp: str) -> Thresholds:
        """The project's defaults: 0.5 % NRMSD for ideal op-amps, 2 % for real macromodels."""
        return cls() if opamp == "ideal" else cls(nrmsd_percent=2.0)


@dataclass(frozen=True)
class StateMetrics:
    """One state's comparison.

    Attributes
    ----------
    state, unit : str
        Name and SI unit.
    nrmsd_percent : float
        RMS(circuit - reference) / range(reference) x 100.
    max_abs_error : float
        In the state's unit.
    peak_ratio : float
        max|circuit| / max|reference|.
    frequency_ratio : float
        Dominant frequency of the circuit trace / that of the reference.
    phase_lag_s : float
        Model seconds; positive when the circuit lags.
    reference_frequency_hz, circuit_frequency_hz : float
        The dominant frequencies themselves (model time).
    failures : tuple of str
        The metrics beyond their thresholds, e.g. ``("nrmsd_percent",)``.
    error_frequency_hz : float
        Dominant frequency of circuit - reference (model time): says which motion the error is
        made of (the forcing, a free mode ...). NaN for identical traces.
    """

    state: str
    unit: str
    nrmsd_percent: float
    max_abs_error: float
    peak_ratio: float
    frequency_ratio: float
    phase_lag_s: float
    reference_frequency_hz: float
    circuit_frequency_hz: float
    failures: tuple[str, ...] = ()
    error_frequency_hz: float = float("nan")

    @property
    def passed(self) -> bool:
        """True when no judged metric is beyond its threshold."""
        return not self.failures


def _beyond(value: float, limit: float | None) -> bool:
    # A NaN metric (e.g. the frequency of a flat trace) is not judged: no number, no verdict;
    # the table shows it as n/a. An infinite one is a failure.
    return limit is not None and not math.isnan(value) and abs(value) > limit


def measure(
    state: str,
    t: np.ndarray,
    reference: np.ndarray,
    candidate: np.ndarray,
    thresholds: Thresholds,
    unit: str = "",
) -> StateMetrics:
    """Metrics of one state from two traces already on the uniform grid ``t`` (s)."""
    f_ref = signals.dominant_frequency(t, reference)
    f_cand = signals.dominant_frequency(t, candidate)
    frequency_ratio = float(f_cand / f_ref) if np.isfinite(f_ref) and f_ref > 0 else float("nan")
    values = {
        "nrmsd_percent": signals.nrmsd_percent(reference, candidate),
        "max_abs_error": signals.max_abs_error(reference, candidate),
        "peak_ratio": signals.peak_ratio(reference, candidate),
        "frequency_ratio": frequency_ratio,
        "phase_lag_s": signals.phase_lag(t, reference, candidate),
    }
    limits = {
        "nrmsd_percent": (values["nrmsd_percent"], thresholds.nrmsd_percent),
        "max_abs_error": (values["max_abs_error"], thresholds.max_abs_error),
        "peak_ratio": (values["peak_ratio"] - 1.0, thresholds.peak_ratio_tolerance),
        "frequency_ratio": (values["frequency_ratio"] - 1.0, thresholds.frequency_ratio_tolerance),
        "phase_lag_s": (values["phase_lag_s"], thresholds.phase_lag_s),
    }
    failures = tuple(name for name, (value, limit) in limits.items() if _beyond(value, limit))
    return StateMetrics(
        state=state,
        unit=unit,
        reference_frequency_hz=float(f_ref),
        circuit_frequency_hz=float(f_cand),
        failures=failures,
        error_frequency_hz=float(signals.dominant_frequency(t, candidate - reference)),
        **values,
    )


@dataclass
class Comparison:
    """Per-state metrics of a circuit run against a reference.

    Attributes
    ----------
    states : dict of str to StateMetrics
        In the order compared.
    thresholds : Thresholds
        What they were judged against.
    t_start, t_stop : float
        The compared model-time window (s).
    n_points : int
        Points of the common grid.
    label : str
        Free text naming the run (scenario, op-amp, engine).
    """

    states: dict[str, StateMetrics]
    thresholds: Thresholds
    t_start: float
    t_stop: float
    n_points: int
    label: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        """True when every state passed every judged metric."""
        return all(m.passed for m in self.states.values())

    def failures(self) -> list[str]:
        """``"state: metric"`` for each metric beyond its threshold."""
        return [f"{m.state}: {name}" for m in self.states.values() for name in m.failures]

    def table(self) -> str:
        """A plain-text table, one row per state, failing metrics marked with ``*``."""
        header = (
            f"{'state':<10} {'unit':<6} {'NRMSD %':>10} {'max abs err':>12} {'peak ratio':>11} "
            f"{'freq ratio':>11} {'lag (s)':>11}  verdict"
        )
        lines = [header, "-" * len(header)]
        for m in self.states.values():

            def cell(name: str, value: float, fmt: str, width: int, m: StateMetrics = m) -> str:
                text = "n/a" if math.isnan(value) else format(value, fmt)
                return (text + ("*" if name in m.failures else "")).rjust(width)

            lines.append(
                f"{m.state:<10} {m.unit:<6} "
                f"{cell('nrmsd_percent', m.nrmsd_percent, '.4f', 10)} "
                f"{cell('max_abs_error', m.max_abs_error, '.3e', 12)} "
                f"{cell('peak_ratio', m.peak_ratio, '.5f', 11)} "
                f"{cell('frequency_ratio', m.frequency_ratio, '.5f', 11)} "
                f"{cell('phase_lag_s', m.phase_lag_s, '.3e', 11)}  "
                f"{'pass' if m.passed else 'FAIL'}"
            )
        th = self.thresholds
        lines.append(
            f"thresholds: NRMSD <= {th.nrmsd_percent:g} %, |peak ratio - 1| <= "
            f"{th.peak_ratio_tolerance:g}, |freq ratio - 1| <= {th.frequency_ratio_tolerance:g}"
            + (f", max abs err <= {th.max_abs_error:g}" if th.max_abs_error is not None else "")
            + (f", |lag| <= {th.phase_lag_s:g} s" if th.phase_lag_s is not None else "")
            + f"; window {self.t_start:g}..{self.t_stop:g} s, {self.n_points} points"
        )
        return "\n".join(lines)

    def to_json(self) -> dict:
        """A JSON-ready object (NaN and inf become None)."""

        def clean(value):
            if isinstance(value, float) and not math.isfinite(value):
                return None
            if isinstance(value, tuple):
                return list(value)
            return value

        return {
            "label": self.label,
            "passed": self.passed,
            "window_s": [self.t_start, self.t_stop],
            "n_points": self.n_points,
            "thresholds": asdict(self.thresholds),
            "states": {
                name: {key: clean(v) for key, v in asdict(m).items()} | {"passed": m.passed}
                for name, m in self.states.items()
            },
            **({"extra": self.extra} if self.extra else {}),
        }


def compare_traces(
    reference: dict[str, Trace],
    circuit: dict[str, Trace],
    thresholds: Thresholds | None = None,
    n_points: int = 4096,
    units: dict[str, str] | None = None,
    label: str = "",
) -> Comparison:
    """Compare circuit traces with reference traces, state by state.

    Parameters
    ----------
    reference : dict of str to (ndarray, ndarray)
        Per state ``(t, values)`` of the reference (e.g. the ODE solution), model seconds.
    circuit : dict of str to (ndarray, ndarray)
        Per state ``(t, values)`` of the circuit, already in model time and physical units
        (see :func:`~circuitsim.compare.mapping.map_waveforms`).
    thresholds : Thresholds, optional
        Default :class:`Thresholds` ().
    n_points : int
        Points of the common uniform grid over the overlap of the two time ranges.
    units : dict of str to str, optional
        Unit per state, for the table.
    label : str
        Names the run in the table and JSON.

    Returns
    -------
    Comparison
        One :class:`StateMetrics` per state present in both inputs, in the reference's order.

    Raises
    ------
    ComparisonError
        No state in common, a state whose time ranges do not overlap, non-finite values.
    """
    thresholds = thresholds or Thresholds()
    units = units or {}
    names = [s for s in reference if s in circuit]
    if not names:
        raise ComparisonError(
            f"no state in common: reference has {', '.join(reference) or 'none'}, "
            f"circuit has {', '.join(circuit) or 'none'}"
        )
    first = names[0]
    grid = common_grid(reference[first], circuit[first], n_points)
    for name in names[1:]:
        # One window for all states, so the per-state rows describe the same stretch of time.
        other = common_grid(reference[name], circuit[name], n_points)
        grid = np.linspace(max(grid[0], other[0]), min(grid[-1], other[-1]), n_points)
    results = {}
    for name in names:
        try:
            ref_values = resample(reference[name], grid)
            cand_values = resample(circuit[name], grid)
        except ComparisonError as exc:
            raise ComparisonError(f"state {name!r}: {exc}") from None
        results[name] = measure(
            name, grid, ref_values, cand_values, thresholds, units.get(name, "")
        )
    return Comparison(
        states=results,
        thresholds=thresholds,
        t_start=float(grid[0]),
        t_stop=float(grid[-1]),
        n_points=n_points,
        label=label,
    )
