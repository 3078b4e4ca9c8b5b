"""The mapping check's result: every compared coefficient, problems, critical speeds."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Entry:
    """One compared coefficient."""

    what: str
    model: float
    realized: float
    allowed: float  # allowed |relative error|
    parts: tuple[str, ...] = ()

    @property
    def error(self) -> float:
        if self.model == 0:
            return abs(self.realized)
        return self.realized / self.model - 1.0

    @property
    def ok(self) -> bool:
        return abs(self.error) <= self.allowed


@dataclass
class MappingReport:
    """What the netlist realizes, beside the model.

    Attributes
    ----------
    A_model, A_realized : ndarray, shape (n, n)
        Linear part, 1/s of model time.
    entries : list of Entry
        Every compared coefficient (A entries, forcing gains and frequencies, constants,
        nonlinear linear parts, |x| gains and offsets, switch times).
    problems : list of str
        Structural problems and out-of-tolerance entries; empty when the check passes.
    warnings : list of str
        E.g. rounding moved the realized critical speed across the simulated speed.
    speed : float or None
        The simulated speed (the model's speed parameter), if the model names one.
    critical_speed_model, critical_speed_realized : float or None
        Critical speed of the model's and of the recomputed linear part (m/s).
    eigenvalues_model, eigenvalues_realized : ndarray, shape (n,)
        Of A_model and A_realized (1/s).
    """

    A_model: np.ndarray
    A_realized: np.ndarray
    entries: list[Entry] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    speed: float | None = None
    critical_speed_model: float | None = None
    critical_speed_realized: float | None = None
    eigenvalues_model: np.ndarray | None = None
    eigenvalues_realized: np.ndarray | None = None

    @property
    def ok(self) -> bool:
        """True when the netlist realizes the model within the reported rounding."""
        return not self.problems

    @property
    def max_error(self) -> float:
        """Largest |relative error| over the compared entries."""
        return max((abs(e.error) for e in self.entries), default=0.0)

    def summary(self) -> str:
        """A few lines for people: verdict, worst entry, critical speeds."""
        lines = [
            f"mapping check: {'OK' if self.ok else 'FAILED'}, {len(self.entries)} coefficients, "
            f"largest relative error {self.max_error:.3g}"
        ]
        if self.critical_speed_model is not None:
            lines.append(
                f"critical speed: model {self.critical_speed_model:.4f}, realized circuit "
                f"{self.critical_speed_realized:.4f} (simulated at {self.speed:g})"
            )
        lines += [f"problem: {p}" for p in self.problems]
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)
