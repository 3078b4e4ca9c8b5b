"""Polynomial controlled sources: E, G, F and H with ``POLY(n)``.

The output is P(x_1 ... x_n) = p0 + p1 x_1 + ... + pn x_n + p(n+1) x_1^2 + p(n+2) x_1 x_2 + ...,
the term order of SPICE 2G6 (ngspice's XSPICE ``spice2poly``): after the constant and the
linear terms, the products of each degree in lexicographic order of their factors' indices
(x_1^2, x_1 x_2, ..., x_1 x_n, x_2^2, ...). As in ngspice, one coefficient alone is p0.
The controlling quantities are voltages between node pairs (E, G) or branch currents of
voltage sources (F, H).

A family whose polynomials are all of degree <= 1 with p0 = 0 (the usual vendor macromodel
summer) is linear: its stamps are constant and the compiled kernels run it. Otherwise it is
a nonlinear family linearized at every Newton iteration (:mod:`terminals`).

Kernel twin: :mod:`circuitsim.solver.devices.poly_kernel` (the same evaluation for one
element, for the compiled MNA kernel; ``kernel_data`` hands over the term table).
"""

from __future__ import annotations

import itertools

import numpy as np

from circuitsim.netlist.circuit import PolyCccs, PolyCcvs, PolyVccs, PolyVcvs
from circuitsim.solver.context import Stamps, StepContext
from circuitsim.solver.devices.base import DeviceFamily, number
from circuitsim.solver.devices.terminals import TerminalStamp, current_converged
from circuitsim.solver.errors import CircuitInputError
from circuitsim.solver.layout import GROUND, branch_stamp

MAX_TERMS = 10_000  # coefficients per source: far above any macromodel, bounds the tables


def exponents(dimension: int, count: int) -> np.ndarray:
    """Exponents of the first ``count`` terms of a ``dimension``-variable SPICE polynomial,
    shape (count, dimension), int."""
    rows = []
    degree = 0
    while len(rows) < count:
        for factors in itertools.combinations_with_replacement(range(dimension), degree):
            row = [0] * dimension
            for index in factors:
                row[index] += 1
            rows.append(row)
            if len(rows) == count:
                break
        degree += 1
    return np.array(rows, dtype=np.int64).reshape(count, dimension)


class _Polynomials:
    """The polynomials of m sources as one table of terms, evaluated together.

    Controls are padded to the largest dimension C with zero exponents.
    """

    def __init__(self, elements, owner_names: list[str]):
        self.dimension = max(len(e.controls) for e in elements)
        owners, coefficients, powers = [], [], []
        for i, (element, name) in enumerate(zip(elements, owner_names, strict=True)):
            values = [
                number(c, name, f"POLY coefficient {k}") for k, c in enumerate(element.coefficients)
            ]
            if len(values) > MAX_TERMS:
                raise CircuitInputError(f"{name}: more than {MAX_TERMS} POLY coefficients")
            table = exponents(len(element.controls), len(values))
            padded = np.zeros((len(values), self.dimension), dtype=np.int64)
            padded[:, : table.shape[1]] = table
            owners += [i] * len(values)
            coefficients += values
            powers.append(padded)
        self.owner = np.array(owners, dtype=np.intp)
        self.coefficient = np.array(coefficients)
        self.power = np.concatenate(powers)  # (terms, C)
        self.count = len(elements)
        used = self.coefficient != 0
        degree = self.power.sum(axis=1)
        self.linear = bool(np.all(degree[used] == 1))  # no constant, nothing above degree 1
        # for the linear case: the gain of each control, shape (C, m)
        self.gains = np.zeros((self.dimension, self.count))
        for t in np.flatnonzero(used & (degree == 1)):
            self.gains[int(np.argmax(self.power[t])), self.owner[t]] += self.coefficient[t]

    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """P and dP/dx_c at controls x (shape (C, m)): shapes (m,) and (C, m)."""
        xt = x[:, self.owner].T  # (terms, C)
        factors = np.power(xt, self.power)
        product = np.prod(factors, axis=1)
        value = np.bincount(self.owner, self.coefficient * product, minlength=self.count)
        slopes = np.empty((self.dimension, self.count))
        for c in range(self.dimension):
            others = np.prod(np.delete(factors, c, axis=1), axis=1)
            e = self.power[:, c]
            term = self.coefficient * e * np.power(xt[:, c], np.maximum(e - 1, 0)) * others
            slopes[c] = np.bincount(self.owner, term, minlength=self.count)
        return value, slopes


class _PolyFamily(DeviceFamily):
    """Shared set-up: output terminals, controls, the polynomial table, linear or not."""

    nonlinear = True
    voltage_output = False  # E, H: an output branch whose equation is v(n+) - v(n-) = P
    current_controlled = False

    def __init__(self, elements, circuit, layout, options):
        super().__init__(elements, circuit, layout, options)
        self.p = layout.nodes([e.positive for e in elements])
        self.n = layout.nodes([e.negative for e in elements])
        self.poly = _Polynomials(elements, self.names)
        self.nonlinear = not self.poly.linear  # instance flag: the engine reads it per family
        if self.voltage_output:
            self.branch = np.array([layout.add_branch(e.name) for e in elements], dtype=np.intp)
        if not self.current_controlled:
            self._set_controls(
                [[layout.node(a) for a, _ in e.controls] for e in elements],
                [[layout.node(b) for _, b in e.controls] for e in elements],
            )

    def bind(self, layout) -> None:
        if self.current_controlled:
            branches = [[layout.branch(c, e.name) for c in e.controls] for e in self.elements]
            self._set_controls(branches, [[GROUND] * len(b) for b in branches])

    def _set_controls(self, plus: list[list[int]], minus: list[list[int]]) -> None:
        size = self.poly.dimension
        pad = [row + [GROUND] * (size - len(row)) for row in plus]
        pad_minus = [row + [GROUND] * (size - len(row)) for row in minus]
        controls = list(
            zip(np.array(pad, dtype=np.intp).T, np.array(pad_minus, dtype=np.intp).T, strict=True)
        )
        if self.voltage_output:
            # the branch row reads x[p] - x[n] + I = 0 with I = -P
            self.terminal = TerminalStamp(self.branch[None, :], controls)
        else:
            self.terminal = TerminalStamp(np.stack([self.p, self.n]), controls)
        self.lin_i = self.lin_g = self.lin_v = None

    def stamp_linear(self, stamps: Stamps) -> None:
        if self.voltage_output:
            stamps.add(*branch_stamp(self.p, self.n, self.branch))
        if not self.nonlinear:
            g = self._terminal_slopes(self.poly.gains)
            stamps.add(self.terminal.pattern, np.stack([g, -g]))

    def _terminal_slopes(self, slopes: np.ndarray) -> np.ndarray:
        """dI/dx per terminal, shape (T, C, m), from dP/dx (C, m)."""
        if self.voltage_output:
            return -slopes[None]
        return np.stack([slopes, -slopes])

    def _terminal_currents(self, value: np.ndarray) -> np.ndarray:
        return -value[None] if self.voltage_output else np.stack([value, -value])

    def load(self, x_ext: np.ndarray, ctx: StepContext, stamps: Stamps, rhs: np.ndarray) -> None:
        v = self.terminal.voltages(x_ext)
        value, slopes = self.poly.evaluate(v)
        self.lin_i = self._terminal_currents(value)
        self.lin_g = self._terminal_slopes(slopes)
        self.lin_v = v
        self.terminal.add(stamps, rhs, self.lin_i, self.lin_g, v)

    def converged(self, x_ext: np.ndarray, ctx: StepContext) -> bool:
        if self.lin_i is None:
            return True
        return current_converged(
            self.lin_i,
            self.lin_g,
            self.lin_v,
            self.terminal.voltages(x_ext),
            self.options.reltol,
            self.options.vntol if self.voltage_output else self.options.abstol,
        )

    def kernel_data(self) -> dict:
        if not self.nonlinear:
            return {"kind": "linear"}
        m = len(self.elements)
        terminal = self.terminal
        return {
            "kind": "terminals",
            "model": "poly_voltage" if self.voltage_output else "poly_current",
            "rows": terminal.rows_of.T,
            "controls": np.stack([terminal.plus.T, terminal.minus.T], axis=2),
            "params": np.zeros((m, 0)),
            "slots": None,
            "tol": self.options.vntol if self.voltage_output else self.options.abstol,
            "v_last": np.zeros((m, self.poly.dimension)),
            "slope": None if self.lin_g is None else np.transpose(self.lin_g, (2, 0, 1)),
            "terms": (self.poly.owner, self.poly.coefficient, self.poly.power),
        }


class PolyVcvsFamily(_PolyFamily):
    """E POLY(n): v(n+) - v(n-) = P(v(nc1+, nc1-), ...), with a branch current."""

    element_types = (PolyVcvs,)
    voltage_output = True


class PolyVccsFamily(_PolyFamily):
    """G POLY(n): current P(v(nc1+, nc1-), ...) from n+ through the source to n-."""

    element_types = (PolyVccs,)


class PolyCccsFamily(_PolyFamily):
    """F POLY(n): current P(i(v1), ...) from n+ through the source to n-."""

    element_types = (PolyCccs,)
    current_controlled = True


class PolyCcvsFamily(_PolyFamily):
    """H POLY(n): v(n+) - v(n-) = P(i(v1), ...), with a branch current."""

    element_types = (PolyCcvs,)
    voltage_output = True
    current_controlled = True
