"""The interface every device family implements; the engine calls only these hooks.

A family holds *all* elements of one kind in a circuit and evaluates them together with numpy
arrays. The engine never asks which kind a family is: it calls the hooks below on every family
(default: do nothing) and reads two flags, ``nonlinear`` and ``discrete``, to know whether a
family's matrix stamps change with x. Adding a device means adding a file in this package and
listing its family in ``devices/__init__.py``.

Equations: the engine solves, at each Newton iteration, the linearized MNA system

    (G + a0 * E Q + S + J(x_k)) x = b(t) - E hist + c(x_k)

where G holds constant stamps (``stamp_linear``), Q and E are the linear charges and where
their derivatives enter (``stamp_charges``), S the piecewise-constant stamps of discrete
devices (``stamp_state``), and J, c the nonlinear stamps (``load``).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from circuitsim.netlist.circuit import Circuit, Element, Expression, Model
from circuitsim.solver.context import Stamps, StepContext
from circuitsim.solver.errors import CircuitInputError
from circuitsim.solver.layout import Layout
from circuitsim.solver.options import SimulationOptions


class DeviceFamily:
    """All elements of one kind, evaluated together.

    Parameters
    ----------
    elements : list of Element
        The family's elements (at least one), in netlist order.
    circuit : Circuit
        The flat circuit (for models and ``.ic``).
    layout : Layout
        Where to allocate branches, internal nodes and charge slots.
    options : SimulationOptions
        Tolerances (gmin for junctions, ...).
    """

    element_types: ClassVar[tuple[type, ...]] = ()
    nonlinear: ClassVar[bool] = False
    discrete: ClassVar[bool] = False
    # (p, n) node indices of two-terminal junctions, set by nonlinear families whose whole
    # stamp is a conductance plus a current at these ports (then ``port_load`` and
    # ``port_converged`` are implemented and the engine may run Newton at the ports only).
    port_nodes: tuple[np.ndarray, np.ndarray] | None = None

    def __init__(
        self,
        elements: list[Element],
        circuit: Circuit,
        layout: Layout,
        options: SimulationOptions,
    ):
        self.elements = elements
        self.names = [e.name for e in elements]
        self.options = options

    # --- set-up -------------------------------------------------------------------------

    def bind(self, layout: Layout) -> None:
        """Resolve references to other devices' unknowns (all branches now exist)."""

    def with_values(self, values: dict[str, float]) -> DeviceFamily:
        """This family with the named elements' main values replaced (for a sweep's variants
        of one assembled circuit); families whose values cannot change so raise.

        Parameters
        ----------
        values : dict of str to float
            Element name (as in :attr:`names`) to its new value, in the element's unit.

        Raises
        ------
        CircuitInputError
            The family does not support it, or a value is not allowed.
        """
        raise CircuitInputError(
            f"{', '.join(values)}: a {type(self).__name__} value cannot change without "
            "assembling the circuit again"
        )

    def stamp_linear(self, stamps: Stamps) -> None:
        """Constant matrix entries."""

    def stamp_charges(self, charges: Stamps, incidence: Stamps) -> None:
        """Linear charges: q[slot] = sum Q[slot, j] x[j]; row i receives E[i, slot] dq/dt.

        ``charges`` collects Q with rows = charge slots, ``incidence`` collects E with
        columns = charge slots.
        """

    def output_signals(self) -> dict[str, int]:
        """Branch currents this family reports, SPICE name -> unknown index."""
        return {}

    # --- time-dependent sources -----------------------------------------------------------

    def source_rhs(self, time: float, scale: float, rhs: np.ndarray, dc: bool) -> None:
        """Add independent-source values at ``time`` (times ``scale``) to ``rhs``."""

    def ac_source(self, rhs: np.ndarray) -> None:
        """Add the small-signal excitation (``AC mag phase``) as phasors to the complex
        ``rhs`` (solver/ac.py)."""

    def breakpoints(self, tstop: float) -> np.ndarray:
        """Times (s) in [0, tstop] where a waveform has a corner."""
        return np.zeros(0)

    def set_timing(self, tstep: float, tstop: float) -> None:
        """Analysis times that SPICE source defaults depend on (PULSE rise = tstep ...)."""

    # --- discrete state (switches) --------------------------------------------------------

    def update_state(self, x_ext: np.ndarray, ctx: StepContext) -> None:
        """Decide piecewise-constant states from x; raise ctx.noncon if one changed."""

    def state_key(self) -> object:
        """A hashable value that changes whenever ``stamp_state`` would stamp differently."""
        return None

    def stamp_state(self, stamps: Stamps) -> None:
        """Matrix entries that depend only on the discrete state."""

    # --- nonlinear ------------------------------------------------------------------------

    def load(self, x_ext: np.ndarray, ctx: StepContext, stamps: Stamps, rhs: np.ndarray) -> None:
        """Linearize at x (extended with ground) and add matrix and rhs stamps."""

    def converged(self, x_ext: np.ndarray, ctx: StepContext) -> bool:
        """Device-level convergence test at the new iterate (SPICE's current check)."""
        return True

    def port_load(self, v: np.ndarray, ctx: StepContext) -> tuple[np.ndarray, np.ndarray]:
        """Linearize at port voltages v (shape (m,), volts): conductance g (S) and current
        ieq (A) such that the current from p to n through each port is g v + ieq."""
        raise NotImplementedError

    def port_converged(self, v: np.ndarray, ctx: StepContext) -> bool:
        """:meth:`converged` at port voltages v."""
        raise NotImplementedError

    # --- transient ------------------------------------------------------------------------

    def initial_conditions(self, x0: np.ndarray, q0: np.ndarray) -> None:
        """For ``uic``: put IC= values into the start vector and the charges."""

    def truncate(self, x_ext: np.ndarray, x_prev_ext: np.ndarray, h_prev: float) -> float:
        """Largest next step (s) this family allows, from the last two accepted points."""
        return np.inf

    def transition_fraction(self, x_ext: np.ndarray, x_prev_ext: np.ndarray) -> float:
        """Where in the last step (0..1, linear in the control) a discrete state changed."""
        return 1.0

    def accept(self, x_ext: np.ndarray, ctx: StepContext) -> bool:
        """The time point is accepted; True if a discontinuity happened (switch toggled)."""
        return False

    # --- compiled transient kernel (solver/compiled/) ----------------------------------------

    def kernel_data(self) -> dict | None:
        """What the compiled transient kernel needs of this family, as arrays.

        A family whose every stamp is constant or a linear charge needs nothing beyond what
        the assembled system holds: ``{"kind": "linear"}`` (the default for such families).
        Families with time-dependent sources, junctions or switches describe their elements
        under ``"kind"`` ``"sources"``, ``"junctions"`` or ``"switches"`` (see
        solver/compiled/plan.py for the keys). None: the kernel cannot simulate this family
        and the reference engine runs instead.
        """
        cls = type(self)
        if self.nonlinear or self.discrete or cls.source_rhs is not DeviceFamily.source_rhs:
            return None
        return {"kind": "linear"}


def number(value, owner: str, what: str) -> float:
    """``value`` as a float, or a clear error naming the element and quantity."""
    if isinstance(value, Expression):
        raise CircuitInputError(
            f"{owner}: {what} is the unevaluated expression {value}; flatten the circuit first"
        )
    try:
        return float(value)
    except (TypeError, ValueError):
        raise CircuitInputError(f"{owner}: {what} {value!r} is not a number") from None


def find_model(circuit: Circuit, name: str, kind: str, owner: str) -> Model:
    """The ``.model`` called ``name`` of ``kind`` (``"D"``, ``"SW"``), or a clear error."""
    model = circuit.models.get(name.lower())
    if model is None:
        model = next((m for m in circuit.models.values() if m.name.lower() == name.lower()), None)
    if model is None:
        raise CircuitInputError(f"{owner}: no .model {name!r}")
    if model.kind.upper() != kind:
        raise CircuitInputError(f"{owner}: .model {name} is {model.kind}, expected {kind}")
    return model


def model_params(
    models: list[Model], defaults: dict[str, float], owner_names: list[str]
) -> dict[str, np.ndarray]:
    """Per-element arrays of model parameters (lower-case keys), defaults filled in."""
    out = {key: np.empty(len(models)) for key in defaults}
    for i, (model, owner) in enumerate(zip(models, owner_names, strict=True)):
        given = {k.lower(): v for k, v in model.params.items()}
        for key, default in defaults.items():
            raw = given.get(key, default)
            out[key][i] = number(raw, f"{owner} (.model {model.name})", key)
    return out
