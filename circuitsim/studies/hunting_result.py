"""The hunting study's results: its settings, each branch's steps (one path, one sweep
direction, flange on or off) and what is read from them - where the motion stops decaying,
the nonlinear critical speeds, the circuit's agreement with the ODE - as a summary and a CSV.
How the steps are run: :mod:`circuitsim.studies.hunting`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from circuitsim.studies.errors import StudyError

DIRECTIONS = ("up", "down")
PATHS = ("ode", "circuit")


class HuntingError(StudyError):
    """A hunting study that cannot run as asked (bad speeds, settings or model): bad input."""


@dataclass(frozen=True)
class HuntingSettings:
    """How each speed step runs and is measured.

    Attributes
    ----------
    settle : float
        Model seconds run before the amplitude is measured (> 0).
    record : float
        Model seconds over which the amplitude (max |state|) is measured (> 0).
    threshold : float
        Smallest amplitude counted as a limit cycle, in the state's unit.
    bound : float
        Amplitude past which the response counts as unbounded, the state's unit.
    repush : float
        A step whose amplitude is below ``repush * push`` hands the push to the next step
        (0: strict continuation).
    max_step : float or None
        Largest step of the direct solution, model seconds (None: unbounded).
    """

    settle: float = 3.0
    record: float = 1.0
    threshold: float = 0.0
    bound: float = math.inf
    repush: float = 0.01
    max_step: float | None = None

    def check(self) -> None:
        """Raise HuntingError naming the setting that is not a usable number."""
        for name in ("settle", "record"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise HuntingError(f"{name} must be a positive number of seconds, got {value!r}")
        if not self.threshold >= 0 or not self.bound > self.threshold:
            raise HuntingError(
                f"need 0 <= threshold < bound, got threshold {self.threshold!r}, bound "
                f"{self.bound!r}"
            )
        if not (math.isfinite(self.repush) and 0 <= self.repush < 1):
            raise HuntingError(f"repush must be in [0, 1), got {self.repush!r}")
        step = self.max_step
        if step is not None and not (math.isfinite(step) and step > 0):
            raise HuntingError(f"max_step must be a positive number of seconds, got {step!r}")


@dataclass
class HuntingBranch:
    """One sweep direction on one path with the flange on or off.

    Attributes
    ----------
    path : {"ode", "circuit"}
    direction : {"up", "down"}
    flange : bool
    speeds : ndarray, shape (k,)
        In the order run (decreasing for ``down``).
    amplitude : ndarray, shape (k,)
        max |state| over each step's record window, the state's unit.
    status : list of str
        ``decaying``, ``steady``, ``growing`` or ``unbounded``.
    pushed : ndarray of bool, shape (k,)
        Steps that started from the push (the first, and those after a dead or unbounded
        step) rather than from the previous final state.
    wall : float
        Wall seconds of the branch.
    """

    path: str
    direction: str
    flange: bool
    speeds: np.ndarray
    amplitude: np.ndarray
    status: list[str]
    pushed: np.ndarray
    wall: float = 0.0

    def cycle(self, threshold: float) -> np.ndarray:
        """Steps holding a limit cycle: steady, amplitude >= threshold; bool, shape (k,).

        None with the flange off: the system is then linear, and a linear system has no
        limit cycle (a slow decay or growth near its critical speed only reads as steady).
        """
        steady = np.array([s == "steady" for s in self.status], dtype=bool)
        return steady & (self.amplitude >= threshold) & self.flange

    def onset(self) -> float | None:
        """Where the motion stops dying out: up, the lowest speed from which no later step
        decays; down, the lowest speed the run of non-decaying steps from the top reaches
        (None: the last step up, or the first step down, decays)."""
        alive = np.array([s != "decaying" for s in self.status], dtype=bool)
        edge = _edge(alive, self.direction)
        return None if edge is None else float(self.speeds[edge])

    def critical(self, threshold: float) -> float | None:
        """The nonlinear critical speed on this branch: the :meth:`onset` when the run of
        non-decaying steps it starts holds a limit cycle (:meth:`cycle`), else None (the
        motion grows without a cycle: the flange-off wheelset)."""
        alive = np.array([s != "decaying" for s in self.status], dtype=bool)
        edge = _edge(alive, self.direction)
        if edge is None:
            return None
        run = slice(edge, None) if self.direction == "up" else slice(0, edge + 1)
        return float(self.speeds[edge]) if self.cycle(threshold)[run].any() else None


def _edge(mask: np.ndarray, direction: str) -> int | None:
    """Index where the run of True steps at the top speed ends (its lowest speed): for an up
    branch the run ending the array, for a down branch the run starting it."""
    if direction == "up":
        if not mask.size or not mask[-1]:
            return None
        dead = np.flatnonzero(~mask)
        return int(dead[-1] + 1) if dead.size else 0
    if not mask.size or not mask[0]:
        return None
    dead = np.flatnonzero(~mask)
    return int(dead[0] - 1) if dead.size else mask.size - 1


@dataclass
class HuntingResult:
    """Both paths, both directions, flange on and off.

    Attributes
    ----------
    parameter, unit : str
        The speed-like parameter (``"V"``, ``"m/s"``).
    state, state_unit : str
        The state measured (``"y"``, ``"m"``).
    push : float
        The first state's start value, its unit.
    settings : HuntingSettings
    linear_critical : float or None
        The linear critical speed (mechanics.stability), if the linear part loses stability
        in the bracket searched.
    branches : list of HuntingBranch
    timings : dict of str to float
        Wall seconds: ``ode``, ``synthesis``, ``circuit``, ``kernels`` (compiled loop ready).
    changed : dict of bool to list of str
        The elements restamped between speeds, per flange setting.
    """

    parameter: str
    unit: str
    state: str
    state_unit: str
    push: float
    settings: HuntingSettings
    linear_critical: float | None = None
    branches: list[HuntingBranch] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    changed: dict = field(default_factory=dict)

    def branch(self, path: str, direction: str, flange: bool) -> HuntingBranch | None:
        """The branch asked for, or None."""
        for b in self.branches:
            if (b.path, b.direction, b.flange) == (path, direction, flange):
                return b
        return None

    def critical(self, path: str, flange: bool) -> tuple[float | None, float | None]:
        """The nonlinear critical speeds (appearing sweeping up, vanishing sweeping down; see
        :meth:`HuntingBranch.critical`)."""
        found = []
        for direction in DIRECTIONS:
            b = self.branch(path, direction, flange)
            found.append(None if b is None else b.critical(self.settings.threshold))
        return found[0], found[1]

    def onset(self, path: str, flange: bool) -> tuple[float | None, float | None]:
        """Where the motion stops dying out, up and down (:meth:`HuntingBranch.onset`)."""
        found = []
        for direction in DIRECTIONS:
            b = self.branch(path, direction, flange)
            found.append(None if b is None else b.onset())
        return found[0], found[1]

    def agreement(self, direction: str, flange: bool) -> dict[str, float] | None:
        """Circuit against ODE amplitudes on one branch, over the steps bounded on both:
        ``max_abs`` (the state's unit), ``nrmsd`` (RMS difference over the ODE amplitudes'
        range, a fraction) and ``steps`` compared; None without both paths."""
        ode, circuit = (self.branch(p, direction, flange) for p in PATHS)
        if ode is None or circuit is None:
            return None
        pairs = zip(ode.status, circuit.status, strict=True)
        bounded = np.array([a != "unbounded" and b != "unbounded" for a, b in pairs])
        if not bounded.any():
            return {"max_abs": math.nan, "nrmsd": math.nan, "steps": 0}
        a, b = ode.amplitude[bounded], circuit.amplitude[bounded]
        spread = float(np.ptp(a)) or float(np.max(np.abs(a))) or 1.0
        return {
            "max_abs": float(np.max(np.abs(b - a))),
            "nrmsd": float(np.sqrt(np.mean((b - a) ** 2)) / spread),
            "steps": int(bounded.sum()),
        }

    def summary(self) -> dict:
        """The critical speeds, agreement and costs as JSON-ready data (None: not found)."""
        flanges = {}
        for flange in sorted({b.flange for b in self.branches}, reverse=True):
            entry: dict = {}
            for path in PATHS:
                if self.branch(path, "up", flange) is None:
                    continue
                up, down = self.critical(path, flange)
                grows_up, grows_down = self.onset(path, flange)
                entry[path] = {
                    "cycle_appears_up": up,
                    "cycle_vanishes_down": down,
                    "stops_decaying_up": grows_up,
                    "stops_decaying_down": grows_down,
                }
            entry["circuit_vs_ode"] = {d: self.agreement(d, flange) for d in DIRECTIONS}
            flanges["on" if flange else "off"] = entry
        steps = sum(b.speeds.size for b in self.branches)
        return {
            "parameter": self.parameter,
            "unit": self.unit,
            "linear_critical": self.linear_critical,
            "settle_s": self.settings.settle,
            "record_s": self.settings.record,
            "threshold": self.settings.threshold,
            "push": self.push,
            "speeds": sorted({float(v) for b in self.branches for v in b.speeds}),
            "steps": steps,
            "flange": flanges,
            "timings_s": dict(self.timings),
        }

    def csv_text(self) -> str:
        """Header and one row per step of every branch, full precision."""
        unit = f" ({self.unit})" if self.unit else ""
        state_unit = f" ({self.state_unit})" if self.state_unit else ""
        header = (
            f"{self.parameter}{unit},direction,path,flange,amplitude_{self.state}{state_unit},"
            "status,cycle,pushed"
        )
        rows = [header]
        for b in self.branches:
            cycle = b.cycle(self.settings.threshold)
            for k, speed in enumerate(b.speeds):
                rows.append(
                    f"{float(speed)!r},{b.direction},{b.path},{'on' if b.flange else 'off'},"
                    f"{float(b.amplitude[k])!r},{b.status[k]},{int(cycle[k])},{int(b.pushed[k])}"
                )
        return "\n".join(rows) + "\n"
