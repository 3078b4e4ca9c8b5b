"""Small-signal AC analysis (``.ac``): every device linearized at the operating point.

The transient engine solves ``(G + a0 C + J(x)) x = ...`` where ``a0`` is the integration
method's leading coefficient, the factor that turns a charge into its current (``qdot = a0 q
+ hist``). In the frequency domain ``d/dt`` is ``j omega``, so the small-signal admittance
matrix is the same Jacobian with ``a0`` replaced by ``j omega``:

    Y(omega) = J0 + j omega C,    J0 = dI/dx,   C = dQ/dx   (both at the operating point).

Both come from the devices' own ``load`` (and the assembled linear stamps), evaluated twice at
the operating point: once with ``a0 = 0`` (J0) and once with ``a0 = A`` (J0 + A C). The
engine never asks a family what it is, and a device's small-signal model is by construction
the one its transient uses (junction and depletion capacitances included; a switch in its
state at the operating point). ``A`` is ``2 pi fstop``, so that the rounding left by the
difference is below one unit in the last place of ``|Y|``'s entries at the top of the sweep.

Excitation: the ``AC mag [phase]`` of independent sources (phase in degrees), stamped by the
source families' :meth:`~circuitsim.solver.devices.base.DeviceFamily.ac_source` hook.

Results follow ngspice's ``.print ac`` names, as the ngspice runner returns them: over the
frequency axis (Hz, in ``Waveforms.time``), ``vm(node)``/``vp(node)`` (magnitude, V; phase,
degrees) and ``im(vname)``/``ip(vname)`` for voltage-source branch currents.
"""

from __future__ import annotations

import math

import numpy as np

from circuitsim.netlist.circuit import AcSweep
from circuitsim.solver.context import Stamps, StepContext
from circuitsim.solver.errors import CircuitInputError, SingularMatrixError
from circuitsim.solver.layout import with_ground
from circuitsim.solver.system import MnaSystem

# the most frequencies one sweep may ask for (each is one complex solve; a typo such as
# `.ac dec 1e9 ...` should not run for hours)
MAX_POINTS = 1_000_000


def ac_frequencies(sweep: AcSweep, reltol: float = 1e-3) -> np.ndarray:
    """The frequencies of an ``.ac`` sweep, Hz, as SPICE steps through them.

    ``dec``: ``floor(decades * points)`` equal ratios from ``fstart`` to ``fstop`` (ngspice
    39's rule: the sweep ends on ``fstop``; a range below one step gives ``fstart`` alone);
    ``oct``: each frequency the previous times ``2**(1/points)``; ``lin``: ``points`` in all,
    evenly spaced (from 3 points: ngspice gives 1 or 2 points as the start frequency alone). The
    sweep ends at the last frequency within ``fstop`` plus a tolerance of ``reltol`` of one
    step (ngspice's ACan), so a grid that lands on ``fstop`` up to rounding includes it.

    Raises
    ------
    CircuitInputError
        A bad sweep: unknown variation, points < 1, a start frequency <= 0 on a
        logarithmic sweep, fstop < fstart, or more than MAX_POINTS frequencies.
    """
    variation = sweep.variation.lower()
    points, fstart, fstop = int(sweep.points), float(sweep.fstart), float(sweep.fstop)
    where = f".ac {variation} {points} {fstart:g} {fstop:g}"
    if variation not in ("dec", "oct", "lin"):
        raise CircuitInputError(f"{where}: the variation must be dec, oct or lin")
    if points < 1:
        raise CircuitInputError(f"{where}: the number of points must be at least 1")
    if not (math.isfinite(fstart) and math.isfinite(fstop)) or fstop < fstart:
        raise CircuitInputError(f"{where}: the stop frequency must be at least the start")
    if variation == "lin":
        # ngspice steps by (fstop - fstart) / (points - 1) only from 3 points: 1 or 2 points
        # give the start frequency alone
        if points <= 2:
            return np.array([fstart])
        if points > MAX_POINTS:
            raise CircuitInputError(f"{where}: more than {MAX_POINTS} frequencies")
        delta = (fstop - fstart) / (points - 1)
        out, freq, tol = [], fstart, delta * reltol
        while freq <= fstop + tol and delta > 0:
            out.append(freq)
            freq += delta
        return np.array(out or [fstart])
    if fstart <= 0.0:
        raise CircuitInputError(f"{where}: a logarithmic sweep needs a start frequency > 0")
    if variation == "dec":
        # ngspice 39: a whole number of equal ratios from fstart to fstop, so the sweep ends
        # on fstop; points per decade is rounded down to fit
        steps = math.floor(abs(math.log10(fstop / fstart)) * points)
        if steps == 0:
            return np.array([fstart])
        if steps + 1 > MAX_POINTS:
            raise CircuitInputError(f"{where}: {steps + 1} frequencies, more than {MAX_POINTS}")
        delta = math.exp(math.log(fstop / fstart) / steps)
    else:
        delta = math.exp(math.log(2.0) / points)
        expected = math.log(fstop / fstart) / math.log(delta) + 1
        if expected > MAX_POINTS:
            raise CircuitInputError(f"{where}: {expected:.3g} frequencies, more than {MAX_POINTS}")
    out, freq, tol = [], fstart, delta * fstop * reltol
    while freq <= fstop + tol:
        out.append(freq)
        freq *= delta
    return np.array(out)


def _jacobian(system: MnaSystem, x_ext: np.ndarray, ctx: StepContext):
    """G + a0 C_linear + discrete stamps + every nonlinear family's load at x (dense ndarray
    or scipy CSC, as the system is)."""
    _, base = system.base_matrix(ctx, clamp_ic=False)
    stamps = Stamps()
    scratch = np.zeros(system.size)
    for family in system.nonlinear:
        family.load(x_ext, ctx, stamps, scratch)
    if system.dense:
        matrix = np.array(base, dtype=float, copy=True)
        if stamps.items or stamps.ports:
            flat, values = stamps.flat(system.size)
            np.add.at(matrix.ravel(), flat, values)
        return matrix
    import scipy.sparse as sp

    rows, cols, values = stamps.triplets()
    return (base + sp.csc_matrix((values, (rows, cols)), shape=base.shape)).tocsc()


def small_signal_matrices(system: MnaSystem, x: np.ndarray, a0: float = 1.0):
    """The conductance and capacitance matrices at the operating point x.

    Parameters
    ----------
    system : MnaSystem
        After the operating point was accepted into its devices.
    x : ndarray, shape (n,)
        The operating point.
    a0 : float
        The probe coefficient, 1/s (see the module docstring).

    Returns
    -------
    conductance, capacitance : ndarray or scipy sparse matrix, shape (n, n)
        dI/dx (S, and 1 for voltage-source rows) and dQ/dx (F, H for inductor fluxes).
    """
    x_ext = with_ground(x)
    ctx = StepContext(system.n_charges)
    ctx.dc, ctx.first_iteration = False, True
    conductance = _jacobian(system, x_ext, ctx)
    ctx.a0 = float(a0)
    capacitance = (_jacobian(system, x_ext, ctx) - conductance) / ctx.a0
    return conductance, capacitance


def excitation(system: MnaSystem) -> np.ndarray:
    """The AC right-hand side, complex, shape (n,): every source's ``AC mag phase``."""
    rhs = np.zeros(system.size, dtype=complex)
    for family in system.families:
        family.ac_source(rhs)
    return rhs


def ac_solutions(system: MnaSystem, x: np.ndarray, frequencies: np.ndarray) -> np.ndarray:
    """The small-signal solution at each frequency, complex, shape (len(frequencies), n).

    Raises
    ------
    SingularMatrixError
        Y(omega) is singular at some frequency (names it).
    """
    top = float(np.max(frequencies)) if frequencies.size else 1.0
    conductance, capacitance = small_signal_matrices(system, x, max(2 * math.pi * top, 1.0))
    rhs = excitation(system)
    out = np.zeros((frequencies.size, system.size), dtype=complex)
    if not np.any(rhs):
        return out
    if system.dense:
        for k, f in enumerate(frequencies):
            matrix = conductance + (2j * math.pi * f) * capacitance
            try:
                out[k] = np.linalg.solve(matrix, rhs)
            except np.linalg.LinAlgError:
                raise SingularMatrixError(_singular(system, f)) from None
        return out
    from scipy.sparse.linalg import splu

    for k, f in enumerate(frequencies):
        matrix = (conductance + (2j * math.pi * f) * capacitance).tocsc()
        try:
            out[k] = splu(matrix).solve(rhs)
        except RuntimeError:
            raise SingularMatrixError(_singular(system, f)) from None
    return out


def _singular(system: MnaSystem, frequency: float) -> str:
    return f"{system.describe_singular(None)} in the AC analysis at {frequency:.6g} Hz"


def ac_signals(system: MnaSystem, solutions: np.ndarray, names: list[str]) -> dict:
    """Magnitude and phase (degrees) of the signals ``names`` (``v(a)`` -> ``vm(a)``,
    ``vp(a)``; ``i(v1)`` -> ``im(v1)``, ``ip(v1)``), in their order."""
    signals: dict[str, np.ndarray] = {}
    for name in names:
        index = system.signals[name]
        values = solutions[:, index] if index >= 0 else np.zeros(solutions.shape[0], complex)
        inner = name[1:]
        signals[name[0] + "m" + inner] = np.abs(values)
        signals[name[0] + "p" + inner] = np.degrees(np.angle(values))
    return signals
