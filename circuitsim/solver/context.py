"""What one Newton solve needs to know besides x: the analysis, the integration and stamps.

A :class:`StepContext` travels from the analysis (operating point or transient step) through
Newton to every device family's ``load``. Families with a nonlinear charge call
:meth:`StepContext.integrate`, which turns charge and capacitance into current and companion
conductance with the integration method's coefficients: devices never integrate themselves.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from circuitsim.solver.layout import MatrixPattern, VectorPattern

_CONDUCTANCE_SIGNS = np.array([[1.0], [-1.0], [-1.0], [1.0]])  # (p,p) (p,n) (n,p) (n,n)


class Stamps:
    """Matrix stamps collected from device families.

    ``items`` are (pattern, values) pairs. ``ports`` are conductances between node pairs,
    recorded as such (pattern, p, n, g) so that the engine can treat them as a low-rank update
    of the matrix; :meth:`triplets` and :meth:`flat` include them like any other stamp.
    """

    def __init__(self) -> None:
        self.items: list[tuple[MatrixPattern, np.ndarray]] = []
        self.ports: list[tuple[MatrixPattern, np.ndarray, np.ndarray, np.ndarray]] = []

    def add(self, pattern: MatrixPattern, values) -> None:
        """Add ``values`` (broadcast to ``pattern.shape``) at the pattern's positions."""
        self.items.append((pattern, pattern.select(values)))

    def add_conductances(
        self, pattern: MatrixPattern, p: np.ndarray, n: np.ndarray, g: np.ndarray
    ) -> None:
        """Conductances ``g`` (S, shape (m,)) between nodes p and n (``-1`` ground).

        ``pattern`` is ``two_terminal_pattern(p, n)``, made once by the family.
        """
        self.ports.append((pattern, p, n, g))

    def _all(self) -> list[tuple[MatrixPattern, np.ndarray]]:
        if not self.ports:
            return self.items
        converted = [(pat, pat.select(_CONDUCTANCE_SIGNS * g)) for pat, _, _, g in self.ports]
        return self.items + converted

    def flat(self, size: int) -> tuple[np.ndarray, np.ndarray]:
        """All stamps as (row * size + col, values), for a C-ordered (size, size) matrix."""
        items = self._all()
        if len(items) == 1:
            pattern, values = items[0]
            return pattern.flat_indices(size), values
        return (
            np.concatenate([p.flat_indices(size) for p, _ in items]),
            np.concatenate([v for _, v in items]),
        )

    def triplets(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All stamps as (rows, cols, values), each shape (n,)."""
        items = self._all()
        if not items:
            empty = np.zeros(0, dtype=np.intp)
            return empty, empty, np.zeros(0)
        return (
            np.concatenate([p.rows for p, _ in items]),
            np.concatenate([p.cols for p, _ in items]),
            np.concatenate([v for _, v in items]),
        )


@dataclass
class StepContext:
    """State of one Newton solve.

    Attributes
    ----------
    time : float
        Seconds (0 for an operating point).
    dc : bool
        True for operating points: capacitors open, inductors shorted (a0 = 0, hist = 0).
    a0 : float
        Leading integration coefficient, 1/s: qdot = a0 q + hist.
    hist : ndarray, shape (n_charges,)
        History part of each charge's derivative, amperes (or volts for fluxes).
    q, qdot : ndarray, shape (n_charges,)
        Charges and their derivatives at the latest evaluation (written by integrate and by
        the engine for linear charges).
    source_scale : float
        Factor on all independent sources (source stepping), 1 normally.
    gshunt : float
        Extra conductance from every node to ground (gmin stepping), siemens.
    init_junction : bool
        First iteration of an operating point: junctions start at their critical voltage.
    first_iteration : bool
        First Newton iteration of this solve (limiting compares against accepted state).
    noncon : int
        Count of devices that declare the iterate not converged (limiting, switch changes).
    x_previous : ndarray or None
        The Newton iterate before the last one (set by ``newton``).
    """

    n_charges: int
    time: float = 0.0
    dc: bool = True
    a0: float = 0.0
    hist: np.ndarray = field(default=None)  # type: ignore[assignment]
    q: np.ndarray = field(default=None)  # type: ignore[assignment]
    qdot: np.ndarray = field(default=None)  # type: ignore[assignment]
    source_scale: float = 1.0
    gshunt: float = 0.0
    init_junction: bool = False
    first_iteration: bool = True
    noncon: int = 0
    x_previous: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = self.n_charges
        self.hist = np.zeros(n) if self.hist is None else self.hist
        self.q = np.zeros(n) if self.q is None else self.q
        self.qdot = np.zeros(n) if self.qdot is None else self.qdot

    def integrate(
        self, slots: np.ndarray, charge: np.ndarray, capacitance: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Current and companion conductance of nonlinear charges (NIintegrate's role).

        Parameters
        ----------
        slots : ndarray of int, shape (m,)
            The family's charge slots.
        charge : ndarray, shape (m,)
            Charges at the present iterate, coulombs.
        capacitance : ndarray, shape (m,)
            dq/dv at the present iterate, farads.

        Returns
        -------
        current : ndarray, shape (m,)
            dq/dt by the integration formula, amperes (0 in DC).
        conductance : ndarray, shape (m,)
            d(current)/dv = a0 * capacitance, siemens.
        """
        self.q[slots] = charge
        current = self.a0 * charge + self.hist[slots]
        self.qdot[slots] = current
        return current, self.a0 * capacitance


def add_vector(rhs: np.ndarray, pattern: VectorPattern, values) -> None:
    """``rhs[pattern rows] += values`` (a named helper for families' right-hand sides)."""
    pattern.add(rhs, values)
