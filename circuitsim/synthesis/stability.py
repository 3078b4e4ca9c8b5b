"""Critical speed of a linear part whose speed-dependent entries scale as 1/V.

The wheelset's creep damping c_y = 7.24e6 / V and c_psi = 4.36e6 / V are the only places the
forward speed V enters A, i.e. the entries A[y_dot, y_dot] and A[psi_dot, psi_dot] (in the
circuit: R33 and R44, proportional to V). Given A at speed V, A at speed V' has those entries
multiplied by V / V'; the critical speed is where the largest real part of the eigenvalues
crosses zero. The model file names the entries: ``[circuit] speed = {parameter = "V",
entries = [["y_dot", "y_dot"], ["psi_dot", "psi_dot"]]}``.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq


def growth_rate(A: np.ndarray, entries: list[tuple[int, int]], speed: float, at: float) -> float:
    """Largest real part of the eigenvalues (1/s) of ``A`` moved from ``speed`` to ``at``."""
    B = np.array(A, dtype=float)
    for i, j in entries:
        B[i, j] *= speed / at
    return float(np.max(np.linalg.eigvals(B).real))


def critical_speed(
    A: np.ndarray,
    entries: list[tuple[int, int]],
    speed: float,
    bracket: tuple[float, float] = (0.05, 20.0),
    scan: int = 400,
) -> float | None:
    """The lowest speed at which the linear part becomes unstable, or None if none in range.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Linear part at ``speed`` (1/s).
    entries : list of (int, int)
        Entries proportional to 1/speed.
    speed : float
        The speed A was evaluated at (m/s).
    bracket : (float, float)
        Search range as multiples of ``speed``.
    scan : int
        Points of the logarithmic scan before the root is refined.
    """
    if not entries:
        return None
    grid = speed * np.geomspace(bracket[0], bracket[1], scan)
    rates = [growth_rate(A, entries, speed, v) for v in grid]
    for k in range(1, scan):
        if rates[k - 1] < 0 <= rates[k]:
            return float(
                brentq(lambda v: growth_rate(A, entries, speed, v), grid[k - 1], grid[k],
                       xtol=1e-12, rtol=1e-13)
            )  # fmt: skip
    return None
