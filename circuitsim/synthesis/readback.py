"""Reading a generated circuit back: what voltage each node carries, as a function of the
states.

The mapping check (:mod:`circuitsim.synthesis.check`) walks the circuit from the scale map's
state nodes with a :class:`CircuitReader`: which op-amp drives a node and what is at its
inputs, resistors followed through series pairs, grounded sources, the switches' closing
times, and the voltage of a node of a piecewise-linear signal (:class:`Affine`), recomputed
from its summers and from the precision |x| and dead-zone blocks of
:mod:`circuitsim.synthesis.nonlinear` (taken as their ideal transfer, after checking that
their resistor ratios are the ideal ones). Nothing of the generator's memory is used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from circuitsim.netlist.circuit import (
    Circuit,
    Diode,
    Pwl,
    Resistor,
    SubcircuitCall,
    Switch,
    VoltageSource,
)
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.opamps import is_opamp_call


@dataclass
class Affine:
    """vec . x + const + sum coef |row . x + offset|, plus the parts it depends on."""

    vec: np.ndarray
    const: float = 0.0
    pieces: list[tuple[float, np.ndarray, float]] = field(default_factory=list)
    parts: tuple[str, ...] = ()

    def scaled(self, c: float, parts: tuple[str, ...] = ()) -> Affine:
        return Affine(
            c * self.vec,
            c * self.const,
            [(c * g, r, o) for g, r, o in self.pieces],
            self.parts + parts,
        )

    def plus(self, other: Affine) -> Affine:
        return Affine(
            self.vec + other.vec,
            self.const + other.const,
            self.pieces + other.pieces,
            self.parts + other.parts,
        )


class CircuitReader:
    """The elements of ``circuit`` indexed by node, and what its nodes carry.

    ``state_expr`` maps the state nodes (and the integrators' outputs) to their voltage; the
    caller fills it before asking for :meth:`signal`. ``problems`` collects what is wrong
    but does not stop the reading (a switch's control, a block's resistor ratios).
    """

    def __init__(self, circuit: Circuit, n: int) -> None:
        self.c = circuit
        self.n = n
        self.problems: list[str] = []
        self.by_node: dict[str, list] = {}
        for e in circuit.elements:
            for node in e.nodes:
                self.by_node.setdefault(node.lower(), []).append(e)
        self.opamp_by_out: dict[str, SubcircuitCall] = {}
        for e in circuit.elements:
            if is_opamp_call(circuit, e):
                self.opamp_by_out[e.connections[-1].lower()] = e
        self.names = {e.name.lower(): e for e in circuit.elements}
        self.state_expr: dict[str, Affine] = {}

    # --- the circuit's structure -----------------------------------------------------------

    def resistors_at(self, node: str) -> list[Resistor]:
        return [e for e in self.by_node.get(node, []) if isinstance(e, Resistor)]

    @staticmethod
    def far(element, node: str) -> str:
        a, b = (x.lower() for x in element.nodes[:2])
        return b if a == node else a

    def through(self, r: Resistor, node: str) -> tuple[str, float, tuple[str, ...]]:
        """Far node, total ohms and names of ``r`` seen from ``node``, continued through a
        node that joins it to exactly one other resistor and nothing else (a series pair)."""
        names, total, here, last = (r.name,), float(r.resistance), node, r
        for _ in range(8):
            far = self.far(last, here)
            joined = self.by_node.get(far, [])
            if far == "0" or len(joined) != 2 or not all(isinstance(e, Resistor) for e in joined):
                return far, total, tuple(sorted(names))
            last = joined[0] if joined[1] is last else joined[1]
            names, total, here = names + (last.name,), total + float(last.resistance), far
        raise SynthesisError(f"{r.name}: a chain of more than 8 resistors in series")

    def opamp_inputs(self, out: str) -> tuple[SubcircuitCall, str]:
        op = self.opamp_by_out.get(out)
        if op is None:
            raise SynthesisError(f"no op-amp drives node {out!r}")
        if op.connections[0] != "0":
            raise SynthesisError(f"op-amp {op.name}: non-inverting input is not grounded")
        return op, op.connections[1].lower()

    def source_at(self, node: str) -> VoltageSource | None:
        for e in self.by_node.get(node, []):
            if isinstance(e, VoltageSource) and e.negative == "0" and e.positive.lower() == node:
                return e
        return None

    def switch_time(self, sw: Switch, K: float) -> float | None:
        """Model time the switch closes (None: closed throughout)."""
        control = self.source_at(sw.control_positive.lower())
        model = self.c.models.get(sw.model.lower())
        vt = float(model.params.get("vt", 0.0)) if model else 0.0
        if control is None:
            self.problems.append(f"switch {sw.name}: control is not a grounded voltage source")
            return None
        if isinstance(control.waveform, Pwl):
            points = [(float(t), float(v)) for t, v in control.waveform.points]
            for (t0, v0), (t1, v1) in zip(points, points[1:], strict=False):
                if v0 <= vt < v1:
                    return (t0 + (vt - v0) / (v1 - v0) * (t1 - t0)) * K
            return math.inf
        return None if float(control.dc) > vt else math.inf

    # --- piecewise-linear signals -------------------------------------------------------

    def signal(self, node: str, depth: int = 0) -> Affine:
        """The voltage of ``node`` as a function of the states."""
        if depth > 20:
            raise SynthesisError(f"signal path through {node!r} is too deep (a loop?)")
        if node in self.state_expr:
            return self.state_expr[node]
        source = self.source_at(node)
        if source is not None and source.waveform is None:
            return Affine(np.zeros(self.n), float(source.dc))
        op = self.opamp_by_out.get(node)
        if op is None:
            raise SynthesisError(f"node {node!r} of a nonlinear signal is not driven by an op-amp")
        block = self.block_of(op)
        if block is not None:
            return block(depth)
        _, junction = self.opamp_inputs(node)
        rs = self.resistors_at(junction)
        fb = [r for r in rs if self.far(r, junction) == node]
        if len(fb) != 1:
            raise SynthesisError(f"summer {op.name}: no single feedback resistor")
        rf = float(fb[0].resistance)
        total = Affine(np.zeros(self.n), parts=(fb[0].name,))
        for r in rs:
            if r is fb[0]:
                continue
            node, ohms, names = self.through(r, junction)
            part = self.signal(node, depth + 1)
            total = total.plus(part.scaled(-rf / ohms, names))
        return total

    def block_of(self, op: SubcircuitCall):
        """A reader for helper D's |x| (``X<p>B``) or dead-zone (``X<p>C``) output op-amp."""
        name = op.name
        prefix, last = name[1:-1], name[-1].upper()
        get = self.names.get
        r = {k: get(f"r{prefix}_{k}".lower()) for k in range(1, 10)}
        if last == "B" and get(f"d{prefix}_1".lower()) and r[5] and r[4] and r[1]:
            return lambda depth: self.abs_block(prefix, r, depth)
        if last == "C" and get(f"d{prefix}_4".lower()) and r[9] and r[1]:
            return lambda depth: self.dead_zone_block(prefix, r, depth)
        return None

    def ratios_ok(self, prefix: str, values: dict[int, float], unit: list[int], half: list[int]):
        base = values[unit[0]]
        good = all(math.isclose(values[k], base, rel_tol=1e-12) for k in unit) and all(
            math.isclose(values[k], base / 2, rel_tol=1e-12) for k in half
        )
        if not good:
            self.problems.append(f"block {prefix}: resistor ratios are not the ideal ones")

    def abs_block(self, prefix, r, depth) -> Affine:
        node_in = self.far(r[1], f"{prefix.lower()}_s1")
        values = {k: float(v.resistance) for k, v in r.items() if v is not None}
        self.ratios_ok(prefix, values, [k for k in (1, 2, 3, 5, 6, 7) if k in values], [4])
        bias = self.names.get(f"v{prefix}_b".lower())
        offset = float(bias.dc) if bias is not None else 0.0
        catch: Diode = self.names[f"d{prefix}_1".lower()]
        first_out = self.opamp_by_out_name(f"x{prefix}a")
        sign = 1.0 if catch.anode.lower() == first_out else -1.0
        inner = self.signal(node_in, depth + 1)
        if inner.pieces:
            raise SynthesisError(f"block {prefix}: input is itself nonlinear")
        return Affine(np.zeros(self.n), 0.0, [(sign, inner.vec, inner.const + offset)], inner.parts)

    def dead_zone_block(self, prefix, r, depth) -> Affine:
        node_in = self.far(r[1], f"{prefix.lower()}_s1")
        values = {k: float(v.resistance) for k, v in r.items() if v is not None}
        self.ratios_ok(prefix, values, [1, 3, 4, 6, 7, 8, 9], [])
        plus = self.names.get(f"v{prefix}_p".lower())
        if plus is not None:
            eta = float(plus.dc) * values[1] / values[5]
        else:  # bias from the +15 V supply through R5
            eta = 15.0 * values[1] / values[5]
        w = self.signal(node_in, depth + 1)
        if w.pieces:
            raise SynthesisError(f"block {prefix}: input is itself nonlinear")
        # dz(w, eta) = w - |w + eta| / 2 + |w - eta| / 2
        return Affine(
            w.vec.copy(), w.const, [(-0.5, w.vec, w.const + eta), (0.5, w.vec, w.const - eta)],
            w.parts,
        )  # fmt: skip

    def opamp_by_out_name(self, name: str) -> str:
        element = self.names.get(name.lower())
        return element.connections[-1].lower() if element is not None else ""
