"""Numbering of the MNA unknowns and index patterns for vectorized stamps.

Unknowns are node voltages (ground removed) and branch currents, numbered in the order devices
ask for them. Ground has index ``-1`` everywhere: a solution vector is always extended with a
trailing zero (``x_ext = append(x, 0)``) so that ``x_ext[-1]`` reads ground as 0 V without a
branch in the hot path, and stamp patterns drop every entry that touches row or column -1.
"""

from __future__ import annotations

import numpy as np

from circuitsim.netlist.names import fold
from circuitsim.solver.errors import CircuitInputError

GROUND = -1
GROUND_NAMES = ("0", "gnd")
_GROUND_VALUE = np.zeros(1)


def with_ground(x: np.ndarray) -> np.ndarray:
    """``x`` extended by a trailing 0 V, so index -1 (ground) reads 0, shape (n + 1,)."""
    return np.concatenate((x, _GROUND_VALUE))


class Layout:
    """Unknown numbering shared by all device families of one circuit.

    Parameters
    ----------
    node_names : list of str
        The circuit's node names (ground excluded); they come first, in this order.
    """

    def __init__(self, node_names: list[str]):
        self.unknowns: list[str] = []
        self.is_voltage: list[bool] = []
        self._nodes: dict[str, int] = {}
        self.external_nodes: list[str] = []
        self.branches: dict[str, int] = {}
        self.n_charges = 0
        for name in node_names:
            if fold(name) not in GROUND_NAMES and name not in self._nodes:
                self._nodes[name] = self._new(f"v({fold(name)})", True)
                self.external_nodes.append(name)

    def _new(self, label: str, voltage: bool) -> int:
        self.unknowns.append(label)
        self.is_voltage.append(voltage)
        return len(self.unknowns) - 1

    @property
    def size(self) -> int:
        """Number of unknowns."""
        return len(self.unknowns)

    def node(self, name: str) -> int:
        """Index of node ``name`` (``-1`` for ground)."""
        if fold(name) in GROUND_NAMES:
            return GROUND
        try:
            return self._nodes[name]
        except KeyError:
            raise CircuitInputError(f"unknown node {name!r}") from None

    def nodes(self, names) -> np.ndarray:
        """Indices of several nodes, shape (len(names),), int."""
        return np.array([self.node(n) for n in names], dtype=np.intp)

    def add_internal_node(self, label: str) -> int:
        """A node private to a device (a diode's series-resistance node); not an output."""
        return self._new(f"v({fold(label)})", True)

    def add_branch(self, element_name: str) -> int:
        """A branch-current unknown owned by ``element_name`` (V, L, E, H)."""
        key = fold(element_name)
        if key in self.branches:
            raise CircuitInputError(f"element {element_name} defined twice")
        self.branches[key] = self._new(f"i({key})", False)
        return self.branches[key]

    def branch(self, element_name: str, wanted_by: str) -> int:
        """Index of the branch current of ``element_name`` (for F and H controls)."""
        try:
            return self.branches[fold(element_name)]
        except KeyError:
            raise CircuitInputError(
                f"{wanted_by}: controlling source {element_name!r} is not a voltage source "
                "(or other element with a branch current) of this circuit"
            ) from None

    def add_charges(self, count: int) -> np.ndarray:
        """Slots of ``count`` charges/fluxes in the engine's state vector, shape (count,)."""
        slots = np.arange(self.n_charges, self.n_charges + count, dtype=np.intp)
        self.n_charges += count
        return slots


class MatrixPattern:
    """Fixed (row, column) positions of a family's stamps, ground entries dropped.

    Parameters
    ----------
    rows, cols : array_like of int, same shape (k, m)
        Matrix positions for k stamp entries of m devices; ``-1`` is ground.
    """

    def __init__(self, rows, cols):
        rows = np.asarray(rows, dtype=np.intp)
        cols = np.asarray(cols, dtype=np.intp)
        self.shape = rows.shape
        r, c = rows.ravel(), cols.ravel()
        self.keep = (r >= 0) & (c >= 0)
        self.all_kept = bool(self.keep.all())
        self.rows = r[self.keep]
        self.cols = c[self.keep]
        self.flat: np.ndarray | None = None
        self._flat_size = -1

    def flat_indices(self, size: int) -> np.ndarray:
        """Flat indices into a C-ordered (size, size) matrix (computed once per size)."""
        if self.flat is None or self._flat_size != size:
            self.flat = self.rows * size + self.cols
            self._flat_size = size
        return self.flat

    def select(self, values) -> np.ndarray:
        """The kept entries of ``values`` (broadcast to the pattern's shape), shape (n_kept,)."""
        if getattr(values, "shape", None) != self.shape:
            values = np.broadcast_to(values, self.shape)
        v = values.ravel()
        return v if self.all_kept else v[self.keep]


class VectorPattern:
    """Fixed right-hand-side rows of a family's stamps, ground entries dropped."""

    def __init__(self, rows):
        rows = np.asarray(rows, dtype=np.intp)
        self.shape = rows.shape
        r = rows.ravel()
        self.keep = r >= 0
        self.all_kept = bool(self.keep.all())
        self.rows = r[self.keep]

    def add(self, rhs: np.ndarray, values) -> None:
        """``rhs[rows] += values`` with repeated rows summed."""
        if getattr(values, "shape", None) != self.shape:
            values = np.broadcast_to(values, self.shape)
        v = values.ravel()
        np.add.at(rhs, self.rows, v if self.all_kept else v[self.keep])


def two_terminal_pattern(p: np.ndarray, n: np.ndarray) -> MatrixPattern:
    """Pattern of a conductance between nodes p and n: (p,p) (p,n) (n,p) (n,n), shape (4, m)."""
    return MatrixPattern(np.stack([p, p, n, n]), np.stack([p, n, p, n]))


def conductance_values(g: np.ndarray) -> np.ndarray:
    """Values matching :func:`two_terminal_pattern`, shape (4, m)."""
    return np.stack([g, -g, -g, g])


def branch_stamp(p: np.ndarray, n: np.ndarray, branch: np.ndarray) -> tuple:
    """Pattern and values of branch currents ``branch`` from node p to node n through the
    element: +1 in p's KCL row and -1 in n's, and v(p) - v(n) in the branch row, shape (4, m)
    each (a voltage source's, an inductor's, a voltage-output POLY source's)."""
    one = np.ones(len(branch))
    pattern = MatrixPattern(np.stack([p, n, branch, branch]), np.stack([branch, branch, p, n]))
    return pattern, np.stack([one, -one, one, -one])
