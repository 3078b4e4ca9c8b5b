"""Operating point: Newton, then gmin stepping, then source stepping (ngspice's order).

Every loop here is bounded: Newton by ``itl1`` iterations (raised to ``itl_floor``, as ngspice's
NIiter raises it: ``SimulationOptions.op_iterations``), gmin stepping by a number of
attempts that shrinks its factor until it gives up, source stepping by a minimum increment.
"""

from __future__ import annotations

import numpy as np

from circuitsim.solver.context import Stamps, StepContext
from circuitsim.solver.errors import ConvergenceError
from circuitsim.solver.layout import with_ground
from circuitsim.solver.newton import newton
from circuitsim.solver.system import MnaSystem

GMIN_START = 1e-2  # siemens, ngspice's dynamic gmin stepping start
MIN_FACTOR = 1.00005
MIN_SOURCE_RAISE = 1e-7
MAX_ATTEMPTS = 400


class _Solver:
    """One operating-point solve with its counters."""

    def __init__(self, system: MnaSystem, dc_op: bool, clamp_ic: bool, stats: dict):
        self.system = system
        self.options = system.options
        self.dc_op = dc_op
        self.clamp_ic = clamp_ic
        self.stats = stats
        self.ctx = StepContext(system.n_charges)

    def newton(self, x0: np.ndarray, gshunt: float = 0.0, scale: float = 1.0, junction=False):
        ctx = self.ctx
        ctx.gshunt, ctx.source_scale, ctx.init_junction = gshunt, scale, junction
        rhs = self.system.source_vector(ctx, self.dc_op, self.clamp_ic)
        limit = self.options.op_iterations
        ok, iterations, x = newton(self.system, x0, ctx, rhs, limit, self.clamp_ic)
        self.stats["newton_iterations"] = self.stats.get("newton_iterations", 0) + iterations
        return ok, iterations, x

    def gmin_stepping(self, x_start: np.ndarray):
        """ngspice's dynamic gmin stepping: shunt every node, relax the shunt decade by decade."""
        target = max(self.options.gmin, 1e-300)
        factor, good_gmin, gshunt = 10.0, None, GMIN_START
        x_good = x_start
        junction = True
        for _ in range(MAX_ATTEMPTS):
            ok, iterations, x = self.newton(x_good, gshunt, junction=junction)
            junction = False
            if ok:
                x_good, good_gmin = x, gshunt
                if gshunt <= target:
                    ok, _, x = self.newton(x_good)
                    return ok, x
                # quarters of the limit the Newton had (op_iterations, not the nominal itl1:
                # below the floor a quarter of itl1 would make every step count as slow)
                if iterations <= self.options.op_iterations / 4:
                    factor = min(factor * np.sqrt(factor), 10.0)
                elif iterations > 3 * self.options.op_iterations / 4:
                    factor = np.sqrt(factor)
                gshunt = max(gshunt / factor, target)
            else:
                if good_gmin is None:
                    return False, x
                factor = np.sqrt(np.sqrt(factor))
                if factor < MIN_FACTOR:
                    return False, x
                gshunt = good_gmin / factor
        return False, x_good

    def source_stepping(self, x_start: np.ndarray):
        """Raise all sources from 0 to their values in adaptive increments."""
        ok, _, x_good = self.newton(np.zeros_like(x_start), scale=0.0, junction=True)
        if not ok:
            return False, x_good
        scale, increment = 0.0, 1e-3
        for _ in range(MAX_ATTEMPTS * 10):
            trial = min(1.0, scale + increment)
            ok, iterations, x = self.newton(x_good, scale=trial)
            if ok:
                scale, x_good = trial, x
                if scale >= 1.0:
                    return True, x_good
                if iterations <= self.options.op_iterations / 4:
                    increment *= 1.5
                elif iterations > 3 * self.options.op_iterations / 4:
                    increment *= 0.5
            else:
                increment /= 10
                if increment < MIN_SOURCE_RAISE:
                    return False, x
        return False, x_good


def operating_point_solution(
    system: MnaSystem, dc_op: bool, clamp_ic: bool, stats: dict
) -> tuple[np.ndarray, StepContext]:
    """Solve the DC operating point and accept it into every device.

    Parameters
    ----------
    system : MnaSystem
    dc_op : bool
        True for a stand-alone ``.op`` (sources at their DC values), False before ``.tran``
        (waveforms at t = 0).
    clamp_ic : bool
        Hold ``.ic`` nodes at their values (transient operating point without ``uic``).
    stats : dict
        ``newton_iterations`` is incremented.

    Returns
    -------
    x : ndarray, shape (n,)
    ctx : StepContext
        With the charges of the solution in ``ctx.q``.

    Raises
    ------
    ConvergenceError
        Newton, gmin stepping and source stepping all failed; names the worst node.
    """
    solver = _Solver(system, dc_op, clamp_ic, stats)
    x0 = np.zeros(system.size)
    ok, _, x = solver.newton(x0, junction=True)
    if not ok and system.options.gminsteps > 0:
        ok, x = solver.gmin_stepping(x0)
    if not ok and system.options.srcsteps > 0:
        ok, x = solver.source_stepping(x0)
    ctx = solver.ctx
    if not ok:
        previous = ctx.x_previous if ctx.x_previous is not None else x0
        worst = system.worst_unknown(x, previous) if np.all(np.isfinite(x)) else None
        raise ConvergenceError(
            "operating point did not converge (Newton, gmin stepping and source stepping failed)",
            node=worst,
        )
    ctx.gshunt, ctx.source_scale = 0.0, 1.0
    finish(system, x, ctx)
    return x, ctx


def initial_condition_solution(system: MnaSystem) -> tuple[np.ndarray, StepContext]:
    """The ``uic`` start: .ic node voltages, IC= currents, IC= charges; no solve.

    With ``system.start = (x, q)`` set, that vector of every unknown instead, and the charges
    ``q`` (None: the charges x gives); .ic and IC= are not applied: it is a whole state, e.g.
    where a run ended.
    """
    if system.start is not None:
        x, q = system.start
        x = np.array(x, dtype=float)
        ctx = StepContext(system.n_charges)
        finish(system, x, ctx)
        if q is not None:
            ctx.q[:] = q
        return x, ctx
    x = np.zeros(system.size)
    x[system.ic_nodes] = system.ic_values
    ctx = StepContext(system.n_charges)
    for family in system.families:  # IC= branch currents into x first
        family.initial_conditions(x, ctx.q)
    finish(system, x, ctx)
    for family in system.families:  # then IC= voltages override the charges of x
        family.initial_conditions(x, ctx.q)
    return x, ctx


def evaluate_charges(system: MnaSystem, x: np.ndarray, ctx: StepContext) -> None:
    """Load the nonlinear devices at x only for their charges (no solve)."""
    x_ext = with_ground(x)
    ctx.first_iteration = True
    for family in system.nonlinear:
        family.load(x_ext, ctx, Stamps(), np.zeros(system.size))


def finish(system: MnaSystem, x: np.ndarray, ctx: StepContext) -> None:
    """Let every device accept the solution, then store its charges (currents zero: DC)."""
    x_ext = with_ground(x)
    for family in system.families:
        family.accept(x_ext, ctx)
    ctx.a0 = 0.0
    ctx.hist[:] = 0.0
    system.linear_charges(x, ctx)
    evaluate_charges(system, x, ctx)
    ctx.qdot[:] = 0.0
