"""A transient that carries on from where another ended (the live bench's chunks).

SPICE starts a transient from its operating point or from ``.ic``/``IC=`` values (``uic``);
neither holds a whole state: a diode's internal node, an op-amp macromodel's inner nodes or
a source's branch current are not node voltages a netlist can name. :func:`transient_from`
returns every unknown at the end of a run as a :class:`SavedState`, and starts a run from
one: the capacitors keep their charge, every other unknown its value, and the run begins
at time 0 with the step control's usual first steps (order 1, a short step). The state of a
circuit's own ``uic`` start (:func:`initial_state`) holds the charges its ``IC=`` values set
beside node voltages that may be 0, as SPICE starts. The circuit
may differ from the one that ended in its values (a resistor, a source's setting: the matrix
is assembled anew) but not in its wiring: the unknowns must mean the same.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field

import numpy as np

from circuitsim.netlist.circuit import Circuit
from circuitsim.netlist.names import fold
from circuitsim.solver.engine import _transient_runner, _waveforms, build_system
from circuitsim.solver.errors import CircuitInputError
from circuitsim.solver.options import SimulationOptions
from circuitsim.solver.threads import single_threaded_blas
from circuitsim.solver.waveforms import Waveforms


@dataclass
class SavedState:
    """Every unknown of a circuit at the end of a run.

    Attributes
    ----------
    x : ndarray, shape (n,)
        The unknowns, in the order of the circuit's MNA system (node voltages V, branch
        currents A, device-internal nodes).
    signals : dict of str to int
        ``v(node)`` and ``i(vname)`` to their index in ``x`` (-1: ground).
    charges : ndarray, shape (k,), optional
        The charges (C) and fluxes (Wb) of the reactive elements, where they are not those
        ``x`` gives (a ``uic`` start's ``IC=``); None: from ``x``.
    """

    x: np.ndarray
    signals: dict[str, int] = field(default_factory=dict)
    charges: np.ndarray | None = None

    def voltage(self, node: str) -> float:
        """The voltage of ``node`` (V).

        Raises
        ------
        KeyError
            No such node.
        """
        index = self.signals[f"v({fold(node)})"]
        return 0.0 if index < 0 else float(self.x[index])

    def with_voltages(self, volts: dict[str, float]) -> SavedState:
        """A copy with these node voltages (V) set, e.g. an integrator's output charged to
        a new value: every capacitor starts with the charge its voltages give.

        Raises
        ------
        KeyError
            No such node, or ground.
        """
        x = self.x.copy()
        for node, value in volts.items():
            index = self.signals[f"v({fold(node)})"]
            if index < 0:
                raise KeyError(f"{node} is ground")
            x[index] = float(value)
        return SavedState(x, dict(self.signals))


class Continuation:
    """One assembly of a circuit, run again and again from saved states: a chain of runs
    pays the assembly once. Between runs a SIN source's amplitude and phase may change
    (:meth:`set_sine`); any other value needs a new Continuation (the same wiring takes the
    same states).

    Parameters
    ----------
    circuit : Circuit
        Any circuit (flattened here if needed).
    options : SimulationOptions, optional
        Default: the circuit's ``.options`` over ngspice's defaults.
    """

    def __init__(self, circuit: Circuit, options: SimulationOptions | None = None):
        self.system = build_system(circuit, options)

    def set_sine(self, name: str, amplitude: float, phase: float) -> None:
        """Amplitude (V or A) and phase (degrees) of the SIN source ``name`` from the next
        run on.

        Raises
        ------
        CircuitInputError
            No SIN voltage source of that name.
        """
        for family in self.system.families:
            names = [n for n in family.names if fold(n) == fold(name)]
            if names and hasattr(family, "set_sine"):
                family.set_sine(names[0], amplitude, phase)
                return
        raise CircuitInputError(f"{name}: no SIN voltage source of that name")

    def run(
        self, tstep: float, tstop: float, tmax: float | None = None, state=None
    ) -> tuple[Waveforms, SavedState]:
        """A ``uic`` transient from 0 to ``tstop`` (s) that starts from ``state`` (None: the
        circuit's own ``uic`` start); see :func:`transient_from`."""
        started = _time.perf_counter()
        system = self.system
        if state is not None:
            if state.x.shape != (system.size,) or state.signals != system.signals:
                raise CircuitInputError(
                    f"the saved state has {state.x.size} unknowns of another wiring; this "
                    f"circuit has {system.size}"
                )
            system.start = (state.x, state.charges)
        else:
            system.start = None
        stats: dict = {"analysis": "tran", "newton_iterations": 0}
        runner = _transient_runner(system, stats)
        with single_threaded_blas():
            times, solutions = runner(system, tstep, tstop, 0.0, tmax, True, stats=stats)
        stats["wall_time_s"] = _time.perf_counter() - started
        end = SavedState(np.array(solutions[-1], dtype=float), dict(system.signals))
        return _waveforms(system, times, solutions, stats), end


def transient_from(
    circuit: Circuit,
    tstep: float,
    tstop: float,
    tmax: float | None = None,
    state: SavedState | None = None,
    options: SimulationOptions | None = None,
) -> tuple[Waveforms, SavedState]:
    """A ``uic`` transient from 0 to ``tstop`` (s) that starts from ``state``.

    Parameters
    ----------
    circuit : Circuit
        Any circuit (flattened here if needed).
    tstep, tstop, tmax : float
        As ``.tran tstep tstop 0 tmax uic``, seconds.
    state : SavedState, optional
        Where a run of a circuit of the same wiring ended. None: the circuit's own ``uic``
        start (its ``.ic`` and ``IC=`` values).
    options : SimulationOptions, optional
        Default: the circuit's ``.options`` over ngspice's defaults.

    Returns
    -------
    waveforms : Waveforms
        Every signal at the accepted points after 0 (as :func:`~circuitsim.solver.engine.
        transient` with ``uic``).
    end : SavedState
        Every unknown at ``tstop``: the start of the next run.

    Raises
    ------
    CircuitInputError
        ``state`` is of another wiring (other unknowns).
    ConvergenceError, SingularMatrixError, RunLimitError
        As :func:`~circuitsim.solver.engine.transient`.
    """
    return Continuation(circuit, options).run(tstep, tstop, tmax, state)


def initial_state(circuit: Circuit, options: SimulationOptions | None = None) -> SavedState:
    """The circuit's own ``uic`` start (its ``.ic`` and ``IC=`` values, every other unknown
    0) as a SavedState, to change before a first :func:`transient_from`."""
    from circuitsim.solver.dc import initial_condition_solution

    system = build_system(circuit, options)
    x, ctx = initial_condition_solution(system)
    return SavedState(np.array(x, dtype=float), dict(system.signals), ctx.q.copy())
