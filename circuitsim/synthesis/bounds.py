"""Buildable scales: every signal, bias and resistor of the circuit within what parts allow.

Auto scaling brings each state's peak to the swing. A state that barely moves (the far masses
of a long chain driven at one end: peaks of 1e-20 m) would then get 1e20 V per metre, its |x|
blocks bias sources of 1e20 V and its integrator resistors of milliohms; ideal op-amps have no
swing to warn about, and the engine stops on such a circuit. Two rules lower scales (never
raise them), each change named in a warning:

1. **Blocks within the rails.** An |x| or dead-zone block realizes alpha |r . x + offset| with
   alpha = min_j G_j / |r_j| and a bias source of alpha |offset|: its output is kept within
   ``BLOCK_MARGIN`` of the op-amps' swing, and with ideal op-amps within that of
   ``BUILDABLE_VOLTS``, the swing of the op-amps a built circuit would use on +-15 V rails.
2. **Resistors within one range per integrator.** Integrator i's input resistors set gains
   G_i |A_ij| / G_j (times K): a decade capacitor can bring them into [r_min, r_max] only if
   their spread is at most r_max / r_min. Where it is larger, the scale that makes a gain
   too small is lowered: the input's G_j, or G_i itself when the smallest gain is the state's
   own (damping) term, which no scale changes.

What still falls outside after the scales are set - a resistor beyond ``HARD_RANGE`` times the
preferred range, a bias source beyond the rails - is refused by :func:`check_buildable` with
the part, its value and what sets it.

Some coefficients are beyond every scale: :func:`refuse_unrealizable` refuses them before the
direct solution that sets the scales is integrated (a stiffness of 1e30 would otherwise keep
it stepping until its step limit). Two quantities no amplitude scale changes bound what parts
can build: a state's own coefficient A_ii (its integrator's gain K |A_ii| is one resistor and
one capacitor whatever G is) and the spectral radius rho of the model's matrix in each region
(the circuit's matrix is K D A D^-1 with D = diag(G), the same eigenvalues times K). An
integrator input gains at most g_max = 1 / (R_lo C_lo) (the smallest resistor ``check_buildable``
accepts, the smallest capacitor decade); every entry of the circuit's matrix is a sum of at
most 1 + T + P such inputs (the A entry, T terms' linear parts, P |x| blocks, whose inputs
gain at most 1 by :func:`fit_blocks`' alpha), so rho K <= n (1 + T + P) g_max for any
buildable circuit of n states.
"""

from __future__ import annotations

import math

import numpy as np

from circuitsim.mechanics.system import System
from circuitsim.netlist.circuit import Circuit, Resistor, VoltageSource
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.eseries import CAPACITOR_DECADES, floor_to_series
from circuitsim.synthesis.options import SWING_LIMIT, SynthesisOptions
from circuitsim.synthesis.timestep import MAX_REGIONS, fastest_mode

#: Block outputs are kept at or below this fraction of the swing (a clipped output sits just
#: below the swing; the margin keeps the block's diodes and summer off the rail).
BLOCK_MARGIN = 0.9

#: Largest signal or bias (V) of a buildable circuit: a TL074's swing on +-15 V rails.
BUILDABLE_VOLTS = 13.0

#: A resistor more than this factor outside [r_min, r_max] is refused (inside it: a warning).
HARD_RANGE = 100.0


def block_limit(options: SynthesisOptions) -> float:
    """Largest block output (V): ``BLOCK_MARGIN`` of the op-amps' swing or of the rails."""
    return BLOCK_MARGIN * min(SWING_LIMIT[options.opamp], BUILDABLE_VOLTS)


def fit_blocks(system: System, options, gains, peaks, x, warnings) -> None:
    """Rule 1 (in place): lower the scales of states whose blocks would pass the limit.

    ``x`` (shape (n, m)) is the direct solution, or None when every range was given (then
    |r . x + offset| <= sum_j |r_j| peak_j + |offset|).
    """
    limit = block_limit(options)
    pieces = [
        (term.name, np.asarray(piece.row, dtype=float), float(piece.offset))
        for term in system.nonlinear
        for piece in term.abs_terms
        if piece.gain != 0 and np.any(piece.row)
    ]
    if not pieces:
        return
    peak_of = []
    for _, row, offset in pieces:
        if x is not None:
            peak_of.append(float(np.max(np.abs(row @ x + offset))))
        else:
            peak_of.append(float(np.sum(np.abs(row) * peaks) + abs(offset)))
    before = gains.copy()
    blamed: dict[int, set[str]] = {}
    for _ in range(len(pieces) * len(gains) + 1):  # scales only fall: this ends
        lowered = False
        for (name, row, _), peak in zip(pieces, peak_of, strict=True):
            used = np.flatnonzero(row)
            alpha = float(min(gains[j] / abs(row[j]) for j in used))
            if alpha * peak <= limit:
                continue
            factor = limit / (alpha * peak)
            for j in used:
                gains[j] = floor_to_series(gains[j] * factor, "E24")
                blamed.setdefault(int(j), set()).add(name)
            lowered = True
        if not lowered:
            break
    ideal = not math.isfinite(SWING_LIMIT[options.opamp])
    what = (
        f"{BUILDABLE_VOLTS:g} V (the swing of op-amps on +-15 V rails: ideal op-amps have none, "
        "a built circuit does)"
        if ideal
        else f"the {options.opamp} op-amp's {SWING_LIMIT[options.opamp]:g} V swing"
    )
    for j in sorted(blamed):
        warnings.append(
            f"state {system.states[j]} scaled to {gains[j]:.3g} V per unit instead of "
            f"{before[j]:.3g}, so that the |x| blocks of {', '.join(sorted(blamed[j]))} (with "
            f"their offsets) stay within {BLOCK_MARGIN:g} of {what}"
        )


def fit_spread(system: System, options, gains, warnings) -> None:
    """Rule 2 (in place): lower scales until each integrator's A-entry gains span at most
    r_max / r_min."""
    A = np.asarray(system.A, dtype=float)
    spread = options.r_max / options.r_min
    before = gains.copy()
    n = system.n
    for _ in range(4 * n * n + 1):  # scales only fall, each by at least one E24 step
        changed = False
        for i in range(n):
            inputs = np.flatnonzero(A[i])
            if inputs.size < 2:
                continue
            gain = np.abs(A[i, inputs]) * gains[i] / gains[inputs]
            small, large = int(np.argmin(gain)), int(np.argmax(gain))
            if gain[large] <= spread * gain[small] * (1 + 1e-12):
                continue
            # the small gain comes from input j (G_i |A_ij| / G_j: a smaller G_j raises it)
            # or from the state's own term, which no scale changes (then a smaller G_i lowers
            # every other gain into this integrator): the same factor does either
            j = int(inputs[small])
            factor = spread * gain[small] / gain[large]
            new = floor_to_series(gains[j] * factor, "E24")
            if new >= gains[j]:  # the E24 floor of a factor just below 1
                new = floor_to_series(gains[j] * 0.95, "E24")
            gains[j] = new
            changed = True
        if not changed:
            break
    for j in np.flatnonzero(gains < before):
        warnings.append(
            f"state {system.states[j]} scaled to {gains[j]:.3g} V per unit instead of "
            f"{before[j]:.3g}, so that the input resistors of each integrator it takes part in "
            f"span at most {options.r_min:g}..{options.r_max:g} ohm"
        )


def check_buildable(circuit: Circuit, options: SynthesisOptions, roles: dict[str, str]) -> None:
    """Refuse a circuit with a resistor beyond ``HARD_RANGE`` times [r_min, r_max] or a DC
    source beyond ``BUILDABLE_VOLTS``.

    Parameters
    ----------
    roles : dict of str to str
        Part name (lower case) -> what it does (from the bill of materials), for the message.

    Raises
    ------
    SynthesisError
        Naming the part, its value, its role and what to change.
    """
    low, high = options.r_min / HARD_RANGE, options.r_max * HARD_RANGE
    for element in circuit.elements:
        if isinstance(element, Resistor):
            value = float(element.resistance)
            if not low <= value <= high:
                role = roles.get(element.name.lower(), "a resistor")
                raise SynthesisError(
                    f"{element.name} would be {value:.3g} ohm ({role}), outside "
                    f"{low:g}..{high:g} ohm: no part to build it with (the coefficient it "
                    "sets is too far from the others into the same integrator, or the time "
                    "scale too far from 1: give the states' ranges with --range STATE=PEAK, "
                    "or another --time-scale)"
                )  # fmt: skip
        elif isinstance(element, VoltageSource) and element.waveform is None:
            value = abs(float(element.dc))
            if element.name.upper() not in ("VCC", "VEE") and value > BUILDABLE_VOLTS:
                raise SynthesisError(
                    f"{element.name} would be a {value:.3g} V bias source, beyond the "
                    f"{BUILDABLE_VOLTS:g} V a circuit on +-15 V rails allows (give the ranges "
                    "of the states of its block with --range STATE=PEAK)"
                )


def integrator_gains(options: SynthesisOptions) -> tuple[float, float]:
    """(g_min, g_max): the integrator input gains (1/s of circuit time) parts can build, from
    the resistors ``check_buildable`` accepts and the capacitor decades."""
    r_low, r_high = options.r_min / HARD_RANGE, options.r_max * HARD_RANGE
    return 1.0 / (r_high * max(CAPACITOR_DECADES)), 1.0 / (r_low * min(CAPACITOR_DECADES))


def refuse_unrealizable(system: System, options: SynthesisOptions) -> None:
    """Refuse, before any integration, coefficients no scaling can make buildable.

    ``options.time_scale`` must be set (K). Checked: every coefficient finite; each state's
    own coefficient A_ii at most g_max / K (a coefficient too small for any resistor costs
    the scaling run nothing and is named by :func:`check_buildable`); the fastest mode (over
    every region of the |x| terms when there are at most 2^8 of them, else of the linear
    part) at most n (1 + T + P) g_max / K (see the module's docstring).

    Raises
    ------
    SynthesisError
        Naming the state equation's entry or the nonlinear term (``nonlinear.NAME``), the
        value, the bound and what sets it.
    """
    K = float(options.time_scale or 1.0)
    states = system.states
    A = np.asarray(system.A, dtype=float)
    _refuse_non_finite(system, A)
    _, g_max = integrator_gains(options)
    parts = (
        f"resistors of {options.r_min / HARD_RANGE:g}..{options.r_max * HARD_RANGE:g} ohm "
        f"and capacitors of {min(CAPACITOR_DECADES):g}..{max(CAPACITOR_DECADES):g} F"
    )
    for i, name in enumerate(states):
        gain = abs(A[i, i]) * K
        if gain <= g_max:  # a gain below g_min: its resistor is named by check_buildable
            continue
        raise SynthesisError(
            f"not buildable: the coefficient of {name} in d{name}/dt, {A[i, i]:.3g} 1/s "
            f"({_largest_coefficient(system)}), makes its integrator's gain {gain:.3g} 1/s at "
            f"time scale {K:g}; {parts} build at most {g_max:.3g} 1/s whatever the "
            "amplitude scales: change the coefficient or the time scale (--time-scale)"
        )
    terms = [t for t in system.nonlinear if t.t_on is None or math.isfinite(t.t_on)]
    pieces = sum(1 for t in terms for piece in t.abs_terms if piece.gain != 0)
    limit = system.n * (1 + len(terms) + pieces) * g_max
    if pieces <= math.log2(MAX_REGIONS):  # every region exactly
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                rate, source = fastest_mode(system)
        except (np.linalg.LinAlgError, ValueError):  # a region's sum past the float range
            rate, source = math.inf, "mode with " + ", ".join(t.name for t in terms) + " on"
    else:  # past that fastest_mode bounds the regions from above: the linear part only
        rate, source = float(np.max(np.abs(np.linalg.eigvals(A)))), "mode of the linear part"
    if rate * K <= limit:
        return
    if source == "mode of the linear part":
        i, j = np.unravel_index(int(np.argmax(np.abs(A))), A.shape)
        culprit = (
            f"the largest entry: the coefficient of {states[j]} in d{states[i]}/dt, "
            f"{A[i, j]:.3g}; {_largest_coefficient(system)}"
        )
    else:
        named = [t.name for t in terms if t.name in source] or [t.name for t in terms]
        culprit = "check " + ", ".join(f"nonlinear.{n}" for n in named)
    raise SynthesisError(
        f"not buildable: the model's fastest {source} is {rate:.3g} 1/s ({culprit}), "
        f"{rate * K:.3g} 1/s of circuit time at time scale {K:g}, beyond the {limit:.3g} 1/s "
        f"that {system.n} integrators of {parts} can reach whatever the amplitude scales: "
        "change the coefficient or the time scale (--time-scale)"
    )


def _refuse_non_finite(system: System, A: np.ndarray) -> None:
    """Refuse a coefficient that is inf or NaN (a value past the float range as computed)."""
    if not np.all(np.isfinite(A)):
        i, j = (int(k) for k in np.argwhere(~np.isfinite(A))[0])
        raise SynthesisError(
            f"not buildable: the coefficient of {system.states[j]} in d{system.states[i]}/dt "
            f"is {A[i, j]} ({_largest_coefficient(system)})"
        )
    for term in system.nonlinear:
        values = [term.direction, term.linear, term.constant]
        for piece in term.abs_terms:
            values += [piece.row, piece.gain, piece.offset]
        if not all(np.all(np.isfinite(np.asarray(v, dtype=float))) for v in values):
            raise SynthesisError(
                f"not buildable: nonlinear.{term.name} has a coefficient that is not finite "
                "as the model computes it (its enters, linear or abs entries, times the "
                "inverse mass matrix)"
            )
        with np.errstate(over="ignore", invalid="ignore"):
            slopes = [np.outer(term.direction, term.linear)] + [
                piece.gain * np.outer(term.direction, piece.row) for piece in term.abs_terms
            ]
        if not all(np.all(np.isfinite(slope)) for slope in slopes):
            raise SynthesisError(
                f"not buildable: nonlinear.{term.name}'s slope (linear or abs part) overflows "
                "the float range where it enters the state equations"
            )


def _largest_coefficient(system: System) -> str:
    """``largest coefficient: coefficients.paper.k_y = 4.81e6`` (or of the model's matrices)."""
    values = {k: v for k, v in system.coefficients.items() if isinstance(v, int | float)}
    if not values:
        return "from the model's matrices"
    name = max(values, key=lambda k: abs(values[k]) if math.isfinite(values[k]) else math.inf)
    where = f"coefficients.{system.coefficient_set}" if system.coefficient_set else "coefficients"
    return f"largest coefficient: {where}.{name} = {values[name]:.3g}"
