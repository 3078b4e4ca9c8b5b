"""Piecewise-linear terms as circuit signals: s(x) built from |x| blocks or a dead zone.

A term ``s(x) = linear . x + constant + sum_m gain_m |row_m . x + offset_m|`` entering along
``direction`` becomes one voltage v_sig = sigma * beta * s(x), made by an inverting summer of
the state signals and the |x| block outputs (helper D's precision rectifiers, which take the
offset themselves), with sigma = the sign of the term's first direction entry so the path into
that integrator is a plain resistor. beta is the volts per unit of s: the largest that keeps
every summer weight at most 1 (for the wheelset in unity scaling, v_sig = y - (|y + eta| -
|y - eta|)/2 volts: the paper's nonlinear module). Where a direction entry has the other sign,
an inverter adds -v_sig.

With ``nonlinear="deadzone"`` a term of the shape c r.x - (c/2)(|r.x + eta| - |r.x - eta|) is
c * deadzone(r.x, eta), realized by one dead-zone block fed with +-alpha r.x so that its
output is v_sig itself (no summer).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from circuitsim.mechanics.system import PiecewiseLinearTerm
from circuitsim.netlist.circuit import VoltageSource
from circuitsim.synthesis.blocks import BomEntry, Builder
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.naming import node_name
from circuitsim.synthesis.nonlinear import add_dead_zone, add_precision_abs


@dataclass(frozen=True)
class TermSignal:
    """Where a piecewise-linear term's voltage is.

    Attributes
    ----------
    node : str
        Carries sigma * beta * s(x).
    negated : str or None
        Carries -sigma * beta * s(x) (only when some direction entry needs it).
    sigma : int
        +1 or -1.
    beta : float
        Volts per unit of s.
    """

    node: str
    negated: str | None
    sigma: int
    beta: float
    inner: tuple[InnerNode, ...] = ()


@dataclass(frozen=True)
class InnerNode:
    """A node inside a term's blocks: an |x| block's output or an argument summer's, carrying
    +-alpha (row . x + offset) or its absolute value (V); its peak is predicted like the
    states' (an offset can take it past the op-amps' swing though every state is within).

    Attributes
    ----------
    node : str
    what : str
        In words, for warnings (``"|x| block 1"``).
    alpha : float
        Volts per unit of ``row . x``.
    row : ndarray, shape (n,)
    offset : float
        In the units of ``row . x``.
    """

    node: str
    what: str
    alpha: float
    row: np.ndarray
    offset: float = 0.0

    def peak(self, x: np.ndarray) -> float:
        """max |v| (V) over states ``x`` of shape (n, m)."""
        return float(self.alpha * np.max(np.abs(self.row @ x + self.offset)))


def dead_zone_shape(term: PiecewiseLinearTerm) -> tuple[np.ndarray, float, float] | None:
    """(r, eta, c) when ``term`` is c r.x - (c/2)(|r.x + eta| - |r.x - eta|), else None."""
    if len(term.abs_terms) != 2 or term.constant != 0:
        return None
    first, second = sorted(term.abs_terms, key=lambda a: -a.offset)
    r = np.asarray(first.row, dtype=float)
    eta = first.offset
    if not (eta > 0 and np.allclose(second.row, r) and np.isclose(second.offset, -eta)):
        return None
    scale = np.max(np.abs(r))
    linear = np.asarray(term.linear, dtype=float)
    c = 2.0 * second.gain
    if not (np.isclose(first.gain, -second.gain) and np.allclose(linear, c * r, atol=0, rtol=1e-9)):
        return None
    if not scale:
        return None
    return r, float(eta), float(c)


class TermBuilder:
    """Builds one term's signal; ``states`` maps state name -> (+x node, -x node)."""

    def __init__(
        self,
        builder: Builder,
        states: list[str],
        nodes: dict[str, tuple[str, str]],
        volts_per_unit: np.ndarray,
        r_unit: float,
    ) -> None:
        self.b = builder
        self.states = states
        self.nodes = nodes
        self.G = volts_per_unit
        self.r_unit = r_unit
        self.inner: list[InnerNode] = []  # of the term being built

    def _node_for(self, j: int, sign: float) -> str:
        """The node carrying sign(sign) * G_j x_j."""
        plus, minus = self.nodes[self.states[j]]
        return plus if sign > 0 else minus

    def build(self, term: PiecewiseLinearTerm, mode: str) -> TermSignal:
        """Add the blocks of ``term`` (``mode`` ``"abs"`` or ``"deadzone"``)."""
        direction = np.asarray(term.direction, dtype=float)
        entries = np.flatnonzero(direction)
        if entries.size == 0:
            raise SynthesisError(f"nonlinear term {term.name!r} enters no state (zero direction)")
        sigma = 1 if direction[entries[0]] > 0 else -1
        prefix = node_name(term.name).upper()
        n = prefix.lower()
        self.inner = []
        if mode == "deadzone":
            shape = dead_zone_shape(term)
            if shape is None:
                raise SynthesisError(
                    f"nonlinear term {term.name!r} is not a dead zone "
                    "c*r.x - (c/2)(|r.x + eta| - |r.x - eta|); use nonlinear='abs'"
                )
            node, beta = self._dead_zone(term, prefix, n, sigma, *shape)
        else:
            node, beta = self._abs_sum(term, prefix, n, sigma)
        negated = None
        if np.any(np.sign(direction[entries]) != sigma):
            negated = f"{n}_sign"
            self.b.summer(
                f"{prefix}_NEG",
                f"{prefix}_NEG",
                negated,
                [("IN", node, 1.0, 1.0, f"inverter of {term.name} signal")],
                self.r_unit,
                self.b.chain_tolerance,
            )
        return TermSignal(node, negated, sigma, beta, tuple(self.inner))

    def _argument(
        self, row: np.ndarray, prefix: str, out: str, want_sign: int
    ) -> tuple[str, float, int]:
        """A node carrying s_in * alpha * row.x; returns (node, alpha, s_in).

        A single-state row uses the state's node itself (s_in = want_sign); several states
        need an inverting summer (s_in = want_sign as well: inputs are picked to match).
        """
        used = np.flatnonzero(row)
        if used.size == 0:
            raise SynthesisError("an absolute-value term has an all-zero row")
        alpha = float(min(self.G[j] / abs(row[j]) for j in used))
        if used.size == 1:
            j = int(used[0])
            return self._node_for(j, want_sign * row[j]), alpha, want_sign
        inputs = []
        for j in used:
            weight = alpha * abs(row[j]) / self.G[j]
            # the summer inverts: feed -s_in*sign(row_j) G_j x_j
            node = self._node_for(int(j), -want_sign * row[j])
            inputs.append((node_name(self.states[j]).upper(), node, weight, weight, "argument"))
        self.b.summer(prefix, prefix, out, inputs, self.r_unit, self.b.chain_tolerance)
        self.inner.append(InnerNode(out, f"argument summer {prefix}", alpha, row))
        return out, alpha, want_sign

    def _abs_sum(
        self, term: PiecewiseLinearTerm, prefix: str, n: str, sigma: int
    ) -> tuple[str, float]:
        linear = np.asarray(term.linear, dtype=float)
        plan = []
        # |x| blocks of one row share its argument summer (a fitted function has one row and
        # many breakpoints: one summer instead of one per breakpoint)
        arguments: dict[bytes, tuple[str, float, int]] = {}
        for m, piece in enumerate(term.abs_terms, start=1):
            row = np.asarray(piece.row, dtype=float)
            key = row.tobytes()
            if key not in arguments:
                arguments[key] = self._argument(row, f"{prefix}_ARG{m}", f"{n}_arg{m}", +1)
            node, alpha, s_in = arguments[key]
            # |s_in alpha row.x + v_off| = alpha |row.x + offset|  for v_off = s_in alpha offset
            plan.append((m, piece, node, alpha, s_in * alpha * piece.offset))
        used = np.flatnonzero(linear)
        # an abs term of gain 0 adds nothing (and gets no block below): it sets no scale
        abs_scales = [alpha / abs(p.gain) for _, p, _, alpha, _ in plan if p.gain]
        if used.size:
            beta = float(min(self.G[j] / abs(linear[j]) for j in used))
        elif abs_scales:
            beta = float(min(abs_scales))
        else:
            beta = 1.0 / abs(term.constant) if term.constant else 1.0
        inputs = []
        for j in used:
            c = sigma * beta * linear[j] / self.G[j]
            role = f"{term.name}: {self.states[j]} (linear part)"
            tag = node_name(self.states[j]).upper()
            inputs.append((tag, self._node_for(int(j), -c), abs(c), abs(c), role))
        for m, piece, node, alpha, v_off in plan:
            c = sigma * beta * piece.gain / alpha
            if c == 0:
                continue
            out = f"{n}_abs{m}"
            add_precision_abs(
                self.b.circuit,
                f"{prefix}_ABS{m}",
                node,
                out,
                self.r_unit,
                self.b.opamp_kind,
                offset_volts=v_off,
                sign=-1 if c > 0 else 1,
            )
            self._record_block(f"{prefix}_ABS{m}", f"{term.name}: |x| block {m}")
            self.inner.append(
                InnerNode(
                    out, f"|x| block {m}", alpha, np.asarray(piece.row, dtype=float), piece.offset
                )
            )
            inputs.append((f"ABS{m}", out, abs(c), abs(c), f"{term.name}: |x| block {m}"))
        if term.constant:
            source = f"{n}_const"
            volts = -sigma * beta * term.constant
            # at most 1 V from the source, the rest as the summer's weight: a constant of
            # 17.5 V would be a bias no +-15 V circuit has (synthesis/bounds.py)
            weight = max(1.0, abs(volts))
            self.b.circuit.add(VoltageSource(f"V{prefix}_CONST", source, "0", dc=volts / weight))
            inputs.append(("CONST", source, weight, weight, f"{term.name}: constant"))
        out = f"{n}_sig"
        self.b.summer(
            f"{prefix}_SUM", f"{prefix}_SUM", out, inputs, self.r_unit, self.b.chain_tolerance
        )
        return out, beta

    def _dead_zone(
        self,
        term: PiecewiseLinearTerm,
        prefix: str,
        n: str,
        sigma: int,
        row: np.ndarray,
        eta: float,
        c: float,
    ) -> tuple[str, float]:
        # v_sig = sigma beta c dz(z) with dz output = s_in alpha dz(z): s_in = sigma sign(c)
        s_in = int(sigma * np.sign(c))
        node, alpha, s_in = self._argument(row, f"{prefix}_ARG", f"{n}_arg", s_in)
        out = f"{n}_sig"
        add_dead_zone(
            self.b.circuit, f"{prefix}_DZ", node, out, alpha * eta, self.r_unit, self.b.opamp_kind
        )
        self._record_block(f"{prefix}_DZ", f"{term.name}: dead-zone block")
        return out, alpha / abs(c)

    def _record_block(self, prefix: str, role: str) -> None:
        """Bill-of-materials lines for a block's own (exact, unrounded) resistors."""
        tag = f"R{prefix}_".lower()
        for element in self.b.circuit.elements:
            if element.name.lower().startswith(tag) and element.letter == "R":
                self.b.bom.append(
                    BomEntry(element.name, float(element.resistance), "ohm", "exact", role)
                )
