"""Stamps of nonlinear multi-terminal devices, linearized in a few controlling voltages.

A device family with T terminals whose terminal currents depend on C controlling voltages
v_c = x[a_c] - x[b_c] hands over, per Newton iteration and for all m elements at once,

- ``current`` (T, m): the current flowing from each terminal's node *into* the device, A;
- ``conductance`` (T, C, m): d current / d v_c, S;
- ``voltage`` (C, m): the controlling voltages at which both were evaluated, V.

:class:`TerminalStamp` turns that into matrix entries (row of terminal k, columns a_c and b_c:
+g and -g) and right-hand-side entries (-(I - sum_c g v_c)), the Newton companion model of
any such device (the diode's is the case T = 2, C = 1). JFETs, BJTs and the polynomial
controlled sources use it; the device code keeps only its equations.
"""

from __future__ import annotations

import numpy as np

from circuitsim.netlist.circuit import Circuit, Model
from circuitsim.solver.context import Stamps, StepContext
from circuitsim.solver.devices.base import DeviceFamily, find_model
from circuitsim.solver.errors import CircuitInputError
from circuitsim.solver.layout import MatrixPattern, VectorPattern


class TerminalStamp:
    """Fixed stamp positions of m devices with T terminals and C controlling voltages.

    Parameters
    ----------
    terminals : ndarray of int, shape (T, m)
        Node (or branch-row) index of each terminal; -1 is ground.
    controls : list of (ndarray, ndarray), length C
        For each controlling voltage, the + and - node indices, each shape (m,).
    """

    def __init__(self, terminals: np.ndarray, controls: list[tuple[np.ndarray, np.ndarray]]):
        terminals = np.asarray(terminals, dtype=np.intp)
        t, m = terminals.shape
        c = len(controls)
        plus = np.stack([np.asarray(p, dtype=np.intp) for p, _ in controls])  # (C, m)
        minus = np.stack([np.asarray(n, dtype=np.intp) for _, n in controls])
        rows = np.broadcast_to(terminals[:, None, :], (t, c, m))
        self.pattern = MatrixPattern(
            np.stack([rows, rows]),
            np.stack([np.broadcast_to(plus, (t, c, m)), np.broadcast_to(minus, (t, c, m))]),
        )
        self.rows = VectorPattern(terminals)
        self.rows_of = terminals  # (T, m)
        self.plus, self.minus = plus, minus

    def voltages(self, x_ext: np.ndarray) -> np.ndarray:
        """The controlling voltages at x (extended with ground), shape (C, m), volts."""
        return x_ext[self.plus] - x_ext[self.minus]

    def add(
        self,
        stamps: Stamps,
        rhs: np.ndarray,
        current: np.ndarray,
        conductance: np.ndarray,
        voltage: np.ndarray,
    ) -> None:
        """Stamp the companion model of currents linearized at ``voltage``."""
        stamps.add(self.pattern, np.stack([conductance, -conductance]))
        self.rows.add(rhs, np.einsum("tcm,cm->tm", conductance, voltage) - current)


def current_converged(
    current: np.ndarray,
    conductance: np.ndarray,
    voltage: np.ndarray,
    voltage_new: np.ndarray,
    reltol: float,
    abstol: float,
) -> bool:
    """SPICE's device current check: the linearized currents at the new controlling voltages
    differ from those at the linearization point by at most reltol * max + abstol."""
    delta = np.einsum("tcm,cm->tm", conductance, voltage_new - voltage)
    tol = reltol * np.maximum(np.abs(current + delta), np.abs(current)) + abstol
    return not np.count_nonzero(np.abs(delta) > tol)


class TransistorFamily(DeviceFamily):
    """What JFETs and BJTs share: an n- or p-type ``polarity`` (+1 / -1) per element, a
    :class:`TerminalStamp` ``terminal`` whose controls are the two junction voltages, and
    ``lin`` = (currents, slopes, voltages) of the last load in the circuit's frame."""

    nonlinear = True
    lin: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def converged(self, x_ext: np.ndarray, ctx: StepContext) -> bool:
        if self.lin is None:
            return True
        return current_converged(
            *self.lin, self.terminal.voltages(x_ext), self.options.reltol, self.options.abstol
        )

    def terminal_data(self, model: str, columns: list[np.ndarray]) -> dict:
        """The family's ``kernel_data`` for the compiled MNA kernel (compiled/terminal_plan.py
        describes the keys): its terminals and controls, parameter ``columns`` (each (m,),
        in its kernel twin's PARAMS order), charge slots and last evaluation."""
        m = len(self.elements)
        terminal = self.terminal
        return {
            "kind": "terminals",
            "model": model,
            "rows": terminal.rows_of.T,
            "controls": np.stack([terminal.plus.T, terminal.minus.T], axis=2),
            "params": np.stack(columns, axis=1),
            "slots": None if self.slots is None else self.slots.reshape(2, m).T,
            "tol": self.options.abstol,
            "v_last": self.v.T,
            "slope": None if self.lin is None else np.transpose(self.lin[1], (2, 0, 1)),
        }


def find_model_any(circuit: Circuit, name: str, kinds: tuple[str, ...], owner: str) -> Model:
    """:func:`~circuitsim.solver.devices.base.find_model` for a device with several model
    kinds (``("NJF", "PJF")``), or a clear error naming them."""
    for kind in kinds[:-1]:
        try:
            return find_model(circuit, name, kind, owner)
        except CircuitInputError:
            pass
    try:
        return find_model(circuit, name, kinds[-1], owner)
    except CircuitInputError as exc:
        if "no .model" in str(exc):
            raise
        raise CircuitInputError(f"{owner}: .model {name} is not {' or '.join(kinds)}") from None
