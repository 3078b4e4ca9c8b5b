"""The assembled MNA system of one flat circuit: matrices, right-hand side, linear solves.

The constant conductance matrix G and the linear charge matrices are assembled once. For each
Newton iteration the engine needs ``base + nonlinear stamps``, where ``base = G + a0 E Q +
gshunt + discrete stamps`` depends only on (a0, gshunt, discrete states): bases and, for
circuits without nonlinear devices, their LU factors are cached under that key, so a linear
circuit at a fixed step costs one triangular solve per time point.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from circuitsim.netlist.circuit import Circuit
from circuitsim.netlist.names import fold
from circuitsim.solver.compressed import Compressed, product, unique
from circuitsim.solver.context import Stamps, StepContext
from circuitsim.solver.devices import FAMILIES, DeviceFamily
from circuitsim.solver.errors import CircuitInputError, SingularMatrixError
from circuitsim.solver.layout import Layout, with_ground
from circuitsim.solver.linalg import SingularPivot, factor
from circuitsim.solver.options import SimulationOptions
from circuitsim.solver.port_solver import Ports, PortSolver
from circuitsim.solver.sparse_assembly import SparseAssembler

IC_CONDUCTANCE = 1e10  # siemens: holds .ic nodes at their value during the transient's .op
CACHE_SIZE = 8


def build_families(
    circuit: Circuit, layout: Layout, options: SimulationOptions
) -> list[DeviceFamily]:
    """One family per element kind present, in ``FAMILIES`` order."""
    by_type = {t: family for family in FAMILIES for t in family.element_types}
    groups: dict[type, list] = {}
    for element in circuit.elements:
        family = by_type.get(type(element))
        if family is None:
            raise CircuitInputError(
                f"{element.name}: the engine has no model for {type(element).__name__}"
            )
        groups.setdefault(family, []).append(element)
    return [
        family(groups[family], circuit, layout, options) for family in FAMILIES if family in groups
    ]


class MnaSystem:
    """Matrices and unknowns of a flat circuit.

    Parameters
    ----------
    circuit : Circuit
        Flat: no subcircuit calls, every value a float.
    options : SimulationOptions
    """

    def __init__(self, circuit: Circuit, options: SimulationOptions):
        self.circuit = circuit
        self.options = options
        layout = Layout(circuit.node_names())
        self.families = build_families(circuit, layout, options)
        for family in self.families:
            family.bind(layout)
        self.layout = layout
        n = self.size = layout.size
        if n == 0:
            raise CircuitInputError("the circuit has no nodes besides ground")
        self.dense = n <= options.dense_limit
        self.nonlinear = [f for f in self.families if f.nonlinear]
        self.discrete = [f for f in self.families if f.discrete]
        self.is_linear = not self.nonlinear and not self.discrete
        self.voltage = np.array(layout.is_voltage)
        self.abs_tol = np.where(self.voltage, options.vntol, options.abstol)

        stamps = Stamps()
        for family in self.families:
            family.stamp_linear(stamps)
        charges, incidence = Stamps(), Stamps()
        for family in self.families:
            family.stamp_charges(charges, incidence)
        nq = self.n_charges = layout.n_charges
        q_rows = charges.triplets()[0]
        self.linear_slots = unique(q_rows)
        if self.dense:
            self.G = self._matrix(stamps)
            self.Q = _summed(*charges.triplets(), (nq, n), True)
            self.E = _summed(*incidence.triplets(), (n, nq), True)
            self.M = self.E @ self.Q
            self.Q_linear = self.Q[self.linear_slots]
            # dense when the matrices are small (a sparse matvec costs several microseconds
            # of overhead, a 50 x 10 dense one under one)
            self._E_step = self.E
            self._Q_step = self.Q_linear
            self._assembler = None
        else:
            # numpy's compressed form; scipy's (G, Q, E, M, ...) at their first use
            # (__getattr__): the MNA kernel's run takes these and does not load scipy
            E = Compressed.from_triplets(*incidence.triplets(), (n, nq))
            Q = Compressed.from_triplets(*charges.triplets(), (nq, n))
            self._parts = {
                "G": Compressed.from_triplets(*stamps.triplets(), (n, n)),
                "Q": Q,
                "E": E,
                "M": product(E, Q),
            }
            self._E_step = E
            self._Q_step = Q.take_rows(self.linear_slots)
        self.node_index = np.flatnonzero(self.voltage)
        self.ic_nodes, self.ic_values = self._initial_conditions()
        # (unknowns, charges or None) of a uic start when set (solver/continuation.py: a run
        # that carries on from where another ended); None: the .ic and IC= values
        self.start: tuple[np.ndarray, np.ndarray | None] | None = None
        self._bases: OrderedDict = OrderedDict()
        self._factors: OrderedDict = OrderedDict()
        # Newton confined to the junction ports (port_solver.py) when every nonlinear family
        # is a set of two-terminal junctions; subclasses that solve differently opt out.
        self._port_solvers: OrderedDict = OrderedDict()
        self.ports: Ports | None = None
        if (
            self.nonlinear
            and all(f.port_nodes is not None for f in self.nonlinear)
            and type(self).solve_linearized is MnaSystem.solve_linearized
        ):
            p = np.concatenate([f.port_nodes[0] for f in self.nonlinear])
            q = np.concatenate([f.port_nodes[1] for f in self.nonlinear])
            self.ports = Ports(n, p, q)
            bounds = np.cumsum([0] + [f.port_nodes[0].size for f in self.nonlinear])
            self._port_slices = [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        self.port_rebuilds = 0
        self.factorizations = 0
        self.signals = {f"v({fold(name)})": layout.node(name) for name in layout.external_nodes}
        for family in self.families:
            self.signals.update(family.output_signals())

    def __getattr__(self, name: str):
        """scipy's sparse forms of a sparse system, built at their first use."""
        parts = self.__dict__.get("_parts")
        if name not in _SCIPY_FORMS or parts is None:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        Q, E, M = (parts[key].scipy("csr") for key in "QEM")
        self.G = parts["G"].scipy("csc")
        self.Q, self.E, self.M = Q, E, M
        self.Q_linear = Q[self.linear_slots]
        self._assembler = SparseAssembler(self.size, CACHE_SIZE)
        return getattr(self, name)

    def compressed(self, name: str) -> Compressed:
        """Matrix ``name`` ("G", "Q", "E" or "M") in numpy's compressed form (no stored
        zeros), without loading scipy."""
        parts = self.__dict__.get("_parts")
        if parts is not None:
            return parts[name]
        return Compressed.from_dense(getattr(self, name))

    # --- assembly -------------------------------------------------------------------------

    def conductances_with(self, values: dict[str, float]):
        """The constant matrix G with the named elements' values replaced.

        Each family stamps as at assembly, in the same order, so the result equals bit for
        bit the G of the circuit with those values (a sweep's variants share one assembly).

        Parameters
        ----------
        values : dict of str to float
            Element name to new value (resistors: ohm).

        Raises
        ------
        CircuitInputError
            An unknown element, one whose value cannot change so, or a bad value.
        """
        left = dict(values)
        stamps = Stamps()
        for family in self.families:
            mine = {name: left.pop(name) for name in family.names if name in left}
            (family.with_values(mine) if mine else family).stamp_linear(stamps)
        if left:
            raise CircuitInputError(f"{', '.join(left)}: no such element")
        return self._matrix(stamps)

    def _matrix(self, stamps: Stamps):
        r, c, v = stamps.triplets()
        return _summed(r, c, v, (self.size, self.size), self.dense, "csc")

    def _initial_conditions(self) -> tuple[np.ndarray, np.ndarray]:
        nodes, values = [], []
        for name, value in self.circuit.initial_conditions.items():
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise CircuitInputError(f".ic v({name}): value {value!r} is not a number") from None
            index = self.layout.node(name)
            if index >= 0:
                nodes.append(index)
                values.append(value)
        return np.array(nodes, dtype=np.intp), np.array(values)

    def base_matrix(self, ctx: StepContext, clamp_ic: bool):
        """G + a0 M + gshunt + discrete stamps (+ .ic clamps), cached by its key."""
        key = (ctx.a0, ctx.gshunt, clamp_ic, tuple(f.state_key() for f in self.discrete))
        base = self._bases.get(key)
        if base is not None:
            self._bases.move_to_end(key)
            return key, base
        base = self.G + ctx.a0 * self.M if ctx.a0 else self.G.copy()
        extra = Stamps()
        for family in self.discrete:
            family.stamp_state(extra)
        r, c, v = extra.triplets()
        diag_nodes = self.node_index
        if ctx.gshunt:
            r = np.concatenate([r, diag_nodes])
            c = np.concatenate([c, diag_nodes])
            v = np.concatenate([v, np.full(diag_nodes.size, ctx.gshunt)])
        if clamp_ic and self.ic_nodes.size:
            r = np.concatenate([r, self.ic_nodes])
            c = np.concatenate([c, self.ic_nodes])
            v = np.concatenate([v, np.full(self.ic_nodes.size, IC_CONDUCTANCE)])
        base = self._add(base, r, c, v)
        self._bases[key] = base
        if len(self._bases) > CACHE_SIZE:
            self._bases.popitem(last=False)
        return key, base

    def _add(self, matrix, r, c, v):
        if not len(v):
            return matrix
        if self.dense:
            out = matrix.copy()
            np.add.at(out.ravel(), r * self.size + c, v)
            return out
        import scipy.sparse as sp

        return (matrix + sp.csc_matrix((v, (r, c)), shape=matrix.shape)).tocsc()

    def source_vector(self, ctx: StepContext, dc_op: bool, clamp_ic: bool) -> np.ndarray:
        """Right-hand side independent of x: sources, charge history, .ic clamps."""
        rhs = np.zeros(self.size)
        for family in self.families:
            family.source_rhs(ctx.time, ctx.source_scale, rhs, dc_op)
        if not ctx.dc and self.linear_slots.size:
            rhs -= self._E_step @ ctx.hist
        if clamp_ic and self.ic_nodes.size:
            rhs[self.ic_nodes] += IC_CONDUCTANCE * self.ic_values * ctx.source_scale
        return rhs

    # --- one Newton iteration ---------------------------------------------------------------

    def solve_linearized(
        self, x: np.ndarray, ctx: StepContext, rhs0: np.ndarray, clamp_ic: bool = False
    ) -> np.ndarray:
        """Linearize every device at x, solve, and return the next iterate, shape (n,)."""
        x_ext = with_ground(x)
        for family in self.discrete:
            family.update_state(x_ext, ctx)
        key, base = self.base_matrix(ctx, clamp_ic)
        if self.nonlinear:
            rhs = rhs0.copy()
            stamps = Stamps()
            for family in self.nonlinear:
                family.load(x_ext, ctx, stamps, rhs)
            if self._assembler is not None:
                r, c, v = stamps.triplets()
                lu = self._factor(self._assembler.add(key, base, r, c, v))
            else:
                flat, v = stamps.flat(self.size)
                matrix = base.copy()
                np.add.at(matrix.ravel(), flat, v)
                lu = self._factor(matrix)
        else:
            rhs = rhs0
            lu = self._factors.get(key)
            if lu is None:
                lu = self._factor(base)
                self._factors[key] = lu
                if len(self._factors) > CACHE_SIZE:
                    self._factors.popitem(last=False)
        return lu.solve(rhs)

    # --- Newton at the junction ports (see port_solver.py) -----------------------------------

    def load_ports(self, v: np.ndarray, ctx: StepContext) -> tuple[np.ndarray, np.ndarray]:
        """Junction conductances g (S) and companion currents ieq (A) at port voltages v."""
        if len(self.nonlinear) == 1:
            return self.nonlinear[0].port_load(v, ctx)
        pairs = zip(self.nonlinear, self._port_slices, strict=True)
        parts = [f.port_load(v[s], ctx) for f, s in pairs]
        return np.concatenate([g for g, _ in parts]), np.concatenate([i for _, i in parts])

    def ports_converged(self, v: np.ndarray, ctx: StepContext) -> bool:
        """Every junction family's current check at port voltages v."""
        if len(self.nonlinear) == 1:
            return self.nonlinear[0].port_converged(v, ctx)
        pairs = zip(self.nonlinear, self._port_slices, strict=True)
        return all(f.port_converged(v[s], ctx) for f, s in pairs)

    def port_solver(self, key, base, g: np.ndarray) -> PortSolver:
        """The cached solver of this base, or a new one factored at conductances g."""
        solver = self._port_solvers.get(key)
        if solver is not None:
            self._port_solvers.move_to_end(key)
            return solver
        self.factorizations += 1
        try:
            solver = PortSolver(base, self.ports, g)
        except SingularPivot as exc:
            raise SingularMatrixError(self.describe_singular(exc.index)) from None
        self._port_solvers[key] = solver
        if len(self._port_solvers) > CACHE_SIZE:
            self._port_solvers.popitem(last=False)
        return solver

    def rebuild_port_solver(self, solver: PortSolver, g: np.ndarray) -> None:
        """Refactor ``solver`` at conductances g (after a failed residual check)."""
        self.factorizations += 1
        self.port_rebuilds += 1
        try:
            solver.rebuild(g)
        except SingularPivot as exc:
            raise SingularMatrixError(self.describe_singular(exc.index)) from None

    def _factor(self, matrix):
        self.factorizations += 1
        try:
            return factor(matrix)
        except SingularPivot as exc:
            raise SingularMatrixError(self.describe_singular(exc.index)) from None

    def describe_singular(self, index: int | None) -> str:
        """A message naming the unknown whose pivot vanished and the topology findings."""
        parts = ["singular MNA matrix"]
        if index is not None and 0 <= index < self.size:
            label = self.layout.unknowns[index]
            what = "node" if self.voltage[index] else "branch"
            parts.append(
                f"at {what} {label} (a floating node, or a loop of voltage sources "
                "/ inductors, or a cut set of current sources / capacitors)"
            )
        findings = _topology_findings(self.circuit)
        if findings:
            parts.append("topology check: " + "; ".join(findings))
        return ", ".join(parts)

    # --- convergence ------------------------------------------------------------------------

    def tolerance(self, x_new: np.ndarray, x_old: np.ndarray) -> np.ndarray:
        """SPICE's per-unknown tolerance: reltol * max(|new|, |old|) + vntol or abstol."""
        return self.options.reltol * np.maximum(np.abs(x_new), np.abs(x_old)) + self.abs_tol

    def close(self, x_new: np.ndarray, x_old: np.ndarray) -> bool:
        """Every unknown within reltol * max(|new|, |old|) + vntol (abstol for currents)."""
        tol = self.options.reltol * np.maximum(np.abs(x_new), np.abs(x_old)) + self.abs_tol
        return not np.count_nonzero(np.abs(x_new - x_old) > tol)

    def converged(self, x_new: np.ndarray, x_old: np.ndarray, ctx: StepContext) -> bool:
        """Every unknown within tolerance and every nonlinear device's current check passed."""
        if not self.close(x_new, x_old):
            return False
        if not self.nonlinear:
            return True
        x_ext = with_ground(x_new)
        return all(family.converged(x_ext, ctx) for family in self.nonlinear)

    def worst_unknown(self, x_new: np.ndarray, x_old: np.ndarray) -> str:
        """Name of the unknown with the largest update relative to its tolerance."""
        ratio = np.abs(x_new - x_old) / self.tolerance(x_new, x_old)
        ratio = np.where(np.isfinite(ratio), ratio, np.inf)
        label = self.layout.unknowns[int(np.argmax(ratio))]
        return label[2:-1] if label.startswith("v(") else label

    # --- charges ------------------------------------------------------------------------------

    def linear_charges(self, x: np.ndarray, ctx: StepContext) -> None:
        """Write q and dq/dt of the linear charges for solution x into ctx."""
        if self.linear_slots.size:
            q = self._Q_step @ x
            ctx.q[self.linear_slots] = q
            ctx.qdot[self.linear_slots] = ctx.a0 * q + ctx.hist[self.linear_slots]


# the attributes of a sparse system built with scipy at their first use
_SCIPY_FORMS = frozenset({"G", "Q", "E", "M", "Q_linear", "_assembler"})


def _summed(rows, cols, values, shape: tuple[int, int], dense: bool, form: str = "csr"):
    """The matrix of ``shape`` whose entries are the sums of the triplets' values: a float
    ndarray when ``dense`` (float even without a triplet: an int64 G once made numba compile
    the kernels anew, silently), else scipy's ``form`` ("csr" or "csc"). scipy is imported
    only for the sparse form: a process whose circuit is small (below
    SimulationOptions.dense_limit) and runs on the ports kernel does not load it (0.14 of
    0.37 s of CPU of a simulate of the ideal wheelset, docs/performance.md section 6)."""
    if dense:
        out = np.zeros(shape)
        np.add.at(out, (rows, cols), values)
        return out
    import scipy.sparse as sp

    return getattr(sp, f"{form}_matrix")((values, (rows, cols)), shape=shape)


def _topology_findings(circuit: Circuit) -> list[str]:
    """Messages of the netlist room's topology checks, when that module is available."""
    try:
        from circuitsim.netlist.topology import check_circuit
    except ImportError:
        return []
    try:
        return [str(getattr(f, "message", f)) for f in check_circuit(circuit)]
    except Exception:  # noqa: BLE001 - a failing check must not hide the singular matrix
        return []
