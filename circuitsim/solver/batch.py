"""Many variants of one circuit (same topology, different element values) in one transient run.

The variants are joined into one flat *union* circuit whose nodes, elements and models carry a
variant suffix (``y|3`` is node ``y`` of variant 3). The solver's own code does everything that
is not linear algebra: :class:`~circuitsim.solver.system.MnaSystem` assembles the union (every
device family stamps the elements of all variants in one numpy call, and the nonlinear families
- diodes, switches - are evaluated for all variants at once), and
:func:`~circuitsim.solver.transient.run_transient` integrates it, so all variants share one
time grid whose step is the smallest any variant's truncation error, breakpoint or switch
transition asks for, and Newton iterates until every variant has converged.

Only the linear solves differ: the union's MNA matrix is block diagonal, so
:class:`BatchedMnaSystem` keeps it as a stack of ``(variants, n, n)`` dense blocks and solves
them together (``numpy.linalg.solve`` on the stack, LAPACK per block without Python in the
loop). Each variant's waveform equals its single run to within the solver's tolerances (its
grid is at least as fine; tests/solver/test_solver_batch.py checks this).
"""

from __future__ import annotations

import dataclasses
import re
import time as _time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from circuitsim.netlist.circuit import Circuit, Model
from circuitsim.solver.context import Stamps, StepContext
from circuitsim.solver.engine import flat_circuit
from circuitsim.solver.errors import CircuitInputError, SingularMatrixError
from circuitsim.solver.layout import GROUND_NAMES
from circuitsim.solver.options import SimulationOptions
from circuitsim.solver.system import CACHE_SIZE, IC_CONDUCTANCE, MnaSystem
from circuitsim.solver.transient import run_transient
from circuitsim.solver.waveforms import Waveforms

SEPARATOR = "|"
"""Joins a node, element or model name to its variant number in the union circuit."""

RESIDUAL_TOLERANCE = 1e-8
"""Relative residual above which a low-rank (Woodbury) solve is redone with LU."""

_NODE_FIELDS = ("positive", "negative", "control_positive", "control_negative", "anode", "cathode")
_SUFFIX = re.compile(re.escape(SEPARATOR) + r"(\d+)")


def _tag(name: str, k: int) -> str:
    return f"{name}{SEPARATOR}{k}"


def _node(name: str, k: int) -> str:
    return name if name.lower() in GROUND_NAMES else _tag(name, k)


def _signature(circuit: Circuit) -> list[tuple]:
    """What must agree between variants: each element's kind, name and connections."""
    rows = []
    for e in circuit.elements:
        control = str(getattr(e, "control", "")).lower()
        rows.append((type(e).__name__, e.name.lower(), tuple(n.lower() for n in e.nodes), control))
    return rows


def union_circuit(circuits: Sequence[Circuit]) -> Circuit:
    """One flat circuit holding every (flat) variant, names suffixed ``|k``.

    Parameters
    ----------
    circuits : sequence of Circuit
        Flat circuits (no subcircuit calls, float values) with identical topology: the same
        elements, in the same order, on the same nodes. Values and models may differ.

    Raises
    ------
    CircuitInputError
        The variants differ in topology (the first difference is named).
    """
    if not circuits:
        raise CircuitInputError("a batch needs at least one circuit")
    reference = _signature(circuits[0])
    union = Circuit(title=f"batch of {len(circuits)}: {circuits[0].title}")
    for k, circuit in enumerate(circuits):
        signature = _signature(circuit)
        if signature != reference:
            if len(signature) != len(reference):
                raise CircuitInputError(
                    f"variant {k} has {len(signature)} elements, variant 0 has {len(reference)}"
                )
            first = next(
                i for i, (a, b) in enumerate(zip(signature, reference, strict=True)) if a != b
            )
            raise CircuitInputError(
                f"variant {k} differs in topology from variant 0 at element "
                f"{circuit.elements[first].name}: {signature[first]} vs {reference[first]}"
            )
        for element in circuit.elements:
            changes = {"name": _tag(element.name, k)}
            for f in _NODE_FIELDS:
                if hasattr(element, f):
                    changes[f] = _node(getattr(element, f), k)
            if isinstance(getattr(element, "control", None), str):
                changes["control"] = _tag(element.control, k)  # F and H name a V source
            if isinstance(getattr(element, "model", None), str) and element.model:
                changes["model"] = _tag(element.model, k)
            union.elements.append(dataclasses.replace(element, **changes))
        for model in circuit.models.values():
            tagged = _tag(model.name, k)
            union.models[tagged.lower()] = Model(tagged, model.kind, dict(model.params))
        for node, value in circuit.initial_conditions.items():
            union.initial_conditions[_node(node, k)] = value
    union.analyses = list(circuits[0].analyses)
    union.options = dict(circuits[0].options)
    return union


class BatchedMnaSystem(MnaSystem):
    """The union circuit's MNA system, solved as a stack of per-variant dense blocks.

    Parameters
    ----------
    circuit : Circuit
        From :func:`union_circuit`.
    options : SimulationOptions
    variants : int
        Number of variants in the union.

    Attributes
    ----------
    order : ndarray of int, shape (variants, n)
        ``order[k, i]`` is the union index of variant k's local unknown i.
    local_unknowns : list of str
        The n local unknown labels (``v(y)``, ``i(vxfg1)`` ...), shared by every variant.
    """

    def __init__(self, circuit: Circuit, options: SimulationOptions, variants: int):
        super().__init__(circuit, options)
        labels = self.layout.unknowns
        variant_of = np.empty(len(labels), dtype=np.intp)
        local_labels: list[list[str]] = [[] for _ in range(variants)]
        for index, label in enumerate(labels):
            found = _SUFFIX.search(label)
            if found is None:
                raise CircuitInputError(f"unknown {label} belongs to no variant")
            variant_of[index] = int(found.group(1))
            local_labels[variant_of[index]].append(_SUFFIX.sub("", label))
        if any(lab != local_labels[0] for lab in local_labels[1:]):
            raise CircuitInputError("the variants' unknowns differ (not the same topology)")
        n = self.n_local = len(local_labels[0])
        self.n_variants = variants
        self.local_unknowns = local_labels[0]
        self.order = np.empty((variants, n), dtype=np.intp)
        local = np.empty(len(labels), dtype=np.intp)
        for k in range(variants):
            members = np.flatnonzero(variant_of == k)
            self.order[k] = members
            local[members] = np.arange(n)
        self.variant_of, self.local = variant_of, local
        self.G_blocks = self._blocks(self.G)
        self.M_blocks = self._blocks(self.M)
        touched = np.flatnonzero(
            np.any(self.M_blocks != 0, axis=(0, 1)) | np.any(self.M_blocks != 0, axis=(0, 2))
        )
        self.charge_ports = touched.astype(np.intp)
        self._batched_bases: OrderedDict = OrderedDict()
        self._batched_inverses: OrderedDict = OrderedDict()
        self._linearized: OrderedDict = OrderedDict()
        self._abs_bases: dict = {}

    # --- union index <-> blocks -------------------------------------------------------------

    def flat_positions(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Positions in the raveled ``(variants, n, n)`` stack of union entries (rows, cols)."""
        n = self.n_local
        return self.variant_of[rows] * (n * n) + self.local[rows] * n + self.local[cols]

    def _blocks(self, matrix) -> np.ndarray:
        coo = sp.coo_matrix(matrix)
        if np.any(self.variant_of[coo.row] != self.variant_of[coo.col]):
            raise CircuitInputError("variants are coupled (the union matrix is not block diagonal)")
        n, v = self.n_local, self.n_variants
        flat = np.bincount(
            self.flat_positions(coo.row, coo.col), weights=coo.data, minlength=v * n * n
        )
        return flat.reshape(v, n, n)

    def to_blocks(self, vector: np.ndarray) -> np.ndarray:
        """A union vector, shape (N,), as per-variant rows, shape (variants, n)."""
        return vector[self.order]

    def from_blocks(self, blocks: np.ndarray) -> np.ndarray:
        """Per-variant rows, shape (variants, n), as one union vector, shape (N,)."""
        out = np.empty(self.size)
        out[self.order] = blocks
        return out

    # --- matrices ------------------------------------------------------------------------------

    def batched_base(self, ctx: StepContext, clamp_ic: bool) -> tuple[tuple, np.ndarray]:
        """G + a0 M + gshunt + discrete stamps (+ .ic clamps) of every variant, cached."""
        key = (ctx.a0, ctx.gshunt, clamp_ic, tuple(f.state_key() for f in self.discrete))
        base = self._batched_bases.get(key)
        if base is not None:
            self._batched_bases.move_to_end(key)
            return key, base
        base = self.G_blocks + ctx.a0 * self.M_blocks if ctx.a0 else self.G_blocks.copy()
        extra = Stamps()
        for family in self.discrete:
            family.stamp_state(extra)
        r, c, v = extra.triplets()
        if ctx.gshunt:
            nodes = self.node_index
            r, c = np.concatenate([r, nodes]), np.concatenate([c, nodes])
            v = np.concatenate([v, np.full(nodes.size, ctx.gshunt)])
        if clamp_ic and self.ic_nodes.size:
            r, c = np.concatenate([r, self.ic_nodes]), np.concatenate([c, self.ic_nodes])
            v = np.concatenate([v, np.full(self.ic_nodes.size, IC_CONDUCTANCE)])
        if len(v):
            np.add.at(base.reshape(-1), self.flat_positions(r, c), v)
        self._batched_bases[key] = base
        if len(self._batched_bases) > CACHE_SIZE:
            self._batched_bases.popitem(last=False)
        return key, base

    def solve_linearized(
        self, x: np.ndarray, ctx: StepContext, rhs0: np.ndarray, clamp_ic: bool = False
    ) -> np.ndarray:
        """Linearize every device of every variant at x and solve all blocks, shape (N,)."""
        x_ext = np.append(x, 0.0)
        for family in self.discrete:
            family.update_state(x_ext, ctx)
        key, base = self.batched_base(ctx, clamp_ic)
        if not self.nonlinear:
            inverse = self._inverse(key, base)
            none = np.zeros(0, dtype=np.intp)
            if inverse is None:
                return self.from_blocks(self._direct(base, none, none, np.zeros(0), rhs0))
            blocks = np.einsum("kij,kj->ki", inverse, self.to_blocks(rhs0))
            bad = ~self._accurate(key, blocks, none, none, np.zeros(0), rhs0)
            if bad.any():
                blocks[bad] = self._direct(base, none, none, np.zeros(0), rhs0, bad)
            return self.from_blocks(blocks)
        rhs = rhs0.copy()
        stamps = Stamps()
        for family in self.nonlinear:
            family.load(x_ext, ctx, stamps, rhs)
        r, c, v = stamps.triplets()
        everyone = np.ones(self.n_variants, dtype=bool)
        # the reused inverse does not depend on the step: a0 M is part of the low-rank update
        shared = key[1:]
        blocks = self._low_rank(shared, ctx.a0, r, c, v, rhs)
        if blocks is None:
            blocks = self._rebase(shared, ctx.a0, base, r, c, v, rhs, everyone, None)
        bad = ~self._accurate(key, blocks, r, c, v, rhs)
        if bad.any():
            # the reused inverse lost too many digits for these variants (their devices moved
            # far from where it was taken): a fresh one at the present linearization, then LU
            cached = self._linearized.get(shared)
            blocks[bad] = self._rebase(shared, ctx.a0, base, r, c, v, rhs, bad, cached)
            bad &= ~self._accurate(key, blocks, r, c, v, rhs)
            if bad.any():
                blocks[bad] = self._direct(base, r, c, v, rhs, bad)
        return self.from_blocks(blocks)

    def _inverse(self, key, base: np.ndarray) -> np.ndarray | None:
        """Cached inverse of the linear (no nonlinear stamps) blocks, None if singular."""
        if key in self._batched_inverses:
            self._batched_inverses.move_to_end(key)
            return self._batched_inverses[key]
        inverse = self._invert(base)
        self._batched_inverses[key] = inverse
        if len(self._batched_inverses) > CACHE_SIZE:
            self._batched_inverses.popitem(last=False)
        return inverse

    def _invert(self, stack: np.ndarray) -> np.ndarray | None:
        self.factorizations += self.n_variants
        try:
            inverse = np.linalg.inv(stack)
        except np.linalg.LinAlgError:
            return None
        return inverse if np.all(np.isfinite(inverse)) else None

    def _stacked(self, base, r, c, v) -> np.ndarray:
        return base + np.bincount(
            self.flat_positions(r, c), weights=v, minlength=base.size
        ).reshape(base.shape)

    def _direct(self, base, r, c, v, rhs, which=None) -> np.ndarray:
        """Solve (base + nonlinear stamps) with LU for the variants ``which`` (default all).

        Returns shape (count, n).
        """
        which = np.ones(self.n_variants, dtype=bool) if which is None else which
        stack = self._stacked(base, r, c, v)[which]
        self.factorizations += int(which.sum())
        try:
            return np.linalg.solve(stack, self.to_blocks(rhs)[which][..., None])[..., 0]
        except np.linalg.LinAlgError:
            raise SingularMatrixError(self._singular_message(stack)) from None

    def _rebase(self, key, a0, base, r, c, v, rhs, which, cached) -> np.ndarray:
        """Invert G + a0 M + D of the variants ``which`` at the present linearization, keep it.

        Returns the solution of those variants, shape (count, n) (NaN where a block is
        singular, so that the residual check sends them to LU).
        """
        stack = self._stacked(base, r, c, v)[which]
        self.factorizations += int(which.sum())
        try:
            fresh = np.linalg.inv(stack)
        except np.linalg.LinAlgError:
            fresh = np.full_like(stack, np.nan)
        if cached is None:
            ports = np.unique(np.concatenate([self.local[r], self.local[c], self.charge_ports]))
            position = np.full(self.n_local, -1, dtype=np.intp)
            position[ports] = np.arange(ports.size)
            inverse = np.empty_like(base)
            cached = _Linearization(r.copy(), c.copy(), v.copy(), inverse, ports, position)
            cached.a0 = np.full(self.n_variants, a0)
            cached.m_ports = self.M_blocks[:, ports][:, :, ports]
            self._linearized[key] = cached
            if len(self._linearized) > CACHE_SIZE:
                self._linearized.popitem(last=False)
        cached.inverse[which] = fresh
        members = which[self.variant_of[r]]
        cached.v0[members] = v[members]
        cached.a0[which] = a0
        cached.refresh(which)
        return np.einsum("kij,kj->ki", fresh, self.to_blocks(rhs)[which])

    def _low_rank(self, key, a0, r, c, v, rhs) -> np.ndarray | None:
        """Solve (G + a0 M + D) x = rhs reusing the inverse of G + a0' M + D0 taken earlier.

        With P the local unknowns the nonlinear stamps and the charges touch (p of them),
        W = (G + a0' M + D0)^-1, Z = W[:, P], E = (a0 - a0') M + D - D0 (nonzero on P x P
        only) and y = W rhs: x = y - Z (I + E_PP Z_P)^-1 E_PP y_P (the Woodbury identity).
        Only a (variants, p, p) system is factored per Newton iteration, whatever the step.
        None when there is nothing to reuse.
        """
        cached = self._linearized.get(key)
        if cached is None:
            return None
        if cached.r.shape != r.shape or not (
            np.array_equal(cached.r, r) and np.array_equal(cached.c, c)
        ):
            del self._linearized[key]
            return None
        self._linearized.move_to_end(key)
        p, position = cached.ports.size, cached.position
        flat = self.variant_of[r] * (p * p) + position[self.local[r]] * p + position[self.local[c]]
        e = np.bincount(flat, weights=v - cached.v0, minlength=self.n_variants * p * p)
        e = e.reshape(self.n_variants, p, p) + (a0 - cached.a0)[:, None, None] * cached.m_ports
        y = np.einsum("kij,kj->ki", cached.inverse, self.to_blocks(rhs))
        core = np.eye(p) + e @ cached.z_ports
        try:
            w = np.linalg.solve(core, e @ y[:, cached.ports, None])
        except np.linalg.LinAlgError:
            return None
        return y - (cached.z @ w)[..., 0]

    def _accurate(self, key, blocks, r, c, v, rhs) -> np.ndarray:
        """Per variant, shape (variants,): does (B + D) x = rhs hold to RESIDUAL_TOLERANCE
        of rowsum|B| max|x| + |D| |x| + |rhs|?  (NaN solutions fail.)"""
        base = self._batched_bases[key]
        row_sums = self._abs_bases.get(key)
        if row_sums is None or row_sums.shape != base.shape[:2]:
            # |B| |x| <= (row sums of |B|) max|x|: a bound that needs no second product
            row_sums = self._abs_bases[key] = np.abs(base).sum(axis=2)
            if len(self._abs_bases) > CACHE_SIZE:
                self._abs_bases.pop(next(iter(self._abs_bases)))
        product = np.einsum("kij,kj->ki", base, blocks)
        scale = row_sums * np.max(np.abs(blocks), axis=1, keepdims=True)
        x_local = blocks.reshape(-1)
        rows = self.variant_of[r] * self.n_local + self.local[r]
        cols = self.variant_of[c] * self.n_local + self.local[c]
        size = blocks.size
        product = product.reshape(-1) + np.bincount(rows, v * x_local[cols], minlength=size)
        scale = scale.reshape(-1) + np.bincount(rows, np.abs(v * x_local[cols]), minlength=size)
        target = self.to_blocks(rhs).reshape(-1)
        residual = np.abs(target - product)
        good = residual <= RESIDUAL_TOLERANCE * (scale + np.abs(target))
        return good.reshape(blocks.shape).all(axis=1)

    def _singular_message(self, stack: np.ndarray) -> str:
        for k in range(self.n_variants):
            try:
                np.linalg.solve(stack[k], np.ones(self.n_local))
            except np.linalg.LinAlgError:
                return f"variant {k}: " + self.describe_singular(None)
        return self.describe_singular(None)


@dataclass
class _Linearization:
    """Inverse of B + D0 (D0: the nonlinear stamps where it was taken), per variant.

    ``r``, ``c``, ``v0``: the stamps' union positions and values, shape (s,); ``inverse``
    shape (variants, n, n); ``ports`` the p local unknowns the stamps touch and ``position``
    each local unknown's place among them (-1 if none); ``z`` = inverse[:, :, ports] and
    ``z_ports`` = z[:, ports, :].
    """

    r: np.ndarray
    c: np.ndarray
    v0: np.ndarray
    inverse: np.ndarray
    ports: np.ndarray
    position: np.ndarray
    z: np.ndarray = None  # type: ignore[assignment]
    z_ports: np.ndarray = None  # type: ignore[assignment]
    a0: np.ndarray = None  # type: ignore[assignment]
    m_ports: np.ndarray = None  # type: ignore[assignment]

    def refresh(self, which: np.ndarray) -> None:
        """Recompute z and z_ports of the variants ``which`` from the inverse."""
        if self.z is None:
            self.z = self.inverse[:, :, self.ports]
            self.z_ports = self.z[:, self.ports, :]
            return
        self.z[which] = self.inverse[which][:, :, self.ports]
        self.z_ports[which] = self.z[which][:, self.ports, :]


@dataclass
class BatchResult:
    """Waveforms of every variant on the shared time grid.

    Attributes
    ----------
    time : ndarray, shape (m,)
        The accepted time points (s), shared by all variants.
    signals : dict of str to ndarray, shape (variants, m)
        ``v(node)`` (V) and ``i(vname)`` (A) of every variant, local (unsuffixed) names.
    stats : dict
        accepted, rejected, newton_iterations, factorizations (block factorizations),
        variants, unknowns (per variant), wall_time_s.
    """

    time: np.ndarray
    signals: dict[str, np.ndarray] = field(default_factory=dict)
    stats: dict = field(default_factory=dict)

    @property
    def n_variants(self) -> int:
        """Number of variants."""
        return int(self.stats.get("variants", 0))

    def variant(self, k: int) -> Waveforms:
        """Variant ``k`` as a :class:`Waveforms` (engine ``"builtin-batch"``)."""
        return Waveforms(
            time=self.time,
            signals={name: values[k] for name, values in self.signals.items()},
            engine="builtin-batch",
            stats=dict(self.stats),
        )


def _signal_name(probe: str) -> str:
    key = probe.strip().lower()
    return key if key.startswith(("v(", "i(")) else f"v({key})"


def batch_transient(
    circuits: Sequence[Circuit],
    options: SimulationOptions | None = None,
    progress: Callable[[str], None] | None = None,
    probes: Sequence[str] | None = None,
) -> BatchResult:
    """Run the ``.tran`` of variant 0 on all variants together.

    Parameters
    ----------
    circuits : sequence of Circuit
        Variants of one circuit: the same elements on the same nodes after flattening; any
        element values and model parameters may differ. Subcircuits are flattened here.
    options : SimulationOptions, optional
        Default: ngspice's, overridden by variant 0's ``.options``.
    progress : callable, optional
        Receives the transient's progress lines (``"transient: t = ... s of ... s, ..."``).
    probes : sequence of str, optional
        Keep only these signals (``"v(y)"``, ``"i(v1)"``); all when None. A sweep of many
        long variants needs only one.

    Returns
    -------
    BatchResult

    Raises
    ------
    CircuitInputError
        Different topologies, or variant 0 has no ``.tran``.
    ConvergenceError, SingularMatrixError
        As a single run (a singular block names its variant).
    """
    started = _time.perf_counter()
    flats = [flat_circuit(c) for c in circuits]
    tran = circuits[0].transient if circuits else None
    if tran is None:
        raise CircuitInputError("batch_transient: variant 0 has no .tran analysis")
    union = union_circuit(flats)
    if options is None:
        options = SimulationOptions.from_circuit(flats[0])
    options = dataclasses.replace(options, dense_limit=0)  # the blocks are ours: keep G sparse
    system = BatchedMnaSystem(union, options, len(flats))
    stats: dict = {"analysis": "tran", "newton_iterations": 0}
    times, solutions = run_transient(
        system, tran.tstep, tran.tstop, tran.tstart, tran.tmax, tran.uic, progress, stats
    )
    signals: dict[str, np.ndarray] = {}
    variants = len(flats)
    columns: dict[str, list] = {}
    wanted = None if probes is None else {_signal_name(p) for p in probes}
    for name, index in system.signals.items():
        found = _SUFFIX.search(name)
        if found is None:
            continue
        local = _SUFFIX.sub("", name)
        if wanted is not None and local not in wanted:
            continue
        columns.setdefault(local, [None] * variants)[int(found.group(1))] = index
    if wanted is not None and wanted - set(columns):
        missing = ", ".join(sorted(wanted - set(columns)))
        raise CircuitInputError(f"batch_transient: no signal {missing}")
    for local, indices in columns.items():
        signals[local] = np.stack(
            [solutions[:, i] if i >= 0 else np.zeros(len(times)) for i in indices]
        )
    stats.update(
        factorizations=system.factorizations,
        variants=variants,
        unknowns=system.n_local,
        method=options.method,
        wall_time_s=_time.perf_counter() - started,
    )
    return BatchResult(time=times, signals=signals, stats=stats)
