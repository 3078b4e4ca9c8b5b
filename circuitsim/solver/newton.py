"""Newton-Raphson on the MNA system: a plain function returning (converged, iterations, x)."""

from __future__ import annotations

import math

import numpy as np

from circuitsim.solver.context import StepContext
from circuitsim.solver.layout import with_ground
from circuitsim.solver.system import MnaSystem


def newton(
    system: MnaSystem,
    x0: np.ndarray,
    ctx: StepContext,
    rhs0: np.ndarray,
    max_iterations: int,
    clamp_ic: bool = False,
) -> tuple[bool, int, np.ndarray]:
    """Iterate x <- solve(linearization at x) until SPICE's convergence test passes.

    A converged iterate needs: no device limited its voltage or changed a discrete state while
    producing it (``ctx.noncon == 0``), every unknown within reltol/vntol/abstol of the
    previous iterate, and every nonlinear device's current check passed. As in SPICE, at least
    two iterations are taken unless the circuit has no nonlinear or discrete devices (then the
    first solve is exact).

    Parameters
    ----------
    system : MnaSystem
    x0 : ndarray, shape (n,)
        Starting iterate (volts, amperes).
    ctx : StepContext
        Analysis state; ``init_junction`` applies to the first iteration only.
    rhs0 : ndarray, shape (n,)
        The x-independent right-hand side (``system.source_vector``).
    max_iterations : int
    clamp_ic : bool
        Hold ``.ic`` nodes (the transient's operating point).

    Returns
    -------
    converged : bool
    iterations : int
    x : ndarray, shape (n,)
        The last iterate. The one before it is left in ``ctx.x_previous`` (to name the worst
        unknown when Newton fails).
    """
    if system.ports is not None:
        return _newton_at_ports(system, x0, ctx, rhs0, max_iterations, clamp_ic)
    x = x0
    init_junction = ctx.init_junction
    for iteration in range(1, max_iterations + 1):
        ctx.first_iteration = iteration == 1
        ctx.init_junction = init_junction and iteration == 1
        ctx.noncon = 0
        x_new = system.solve_linearized(x, ctx, rhs0, clamp_ic)
        if not np.all(np.isfinite(x_new)):
            ctx.init_junction = False
            ctx.x_previous = x
            return False, iteration, x_new
        if system.is_linear:
            done = ctx.noncon == 0
        else:
            done = ctx.noncon == 0 and iteration > 1 and system.converged(x_new, x, ctx)
        ctx.x_previous, x = x, x_new
        if done:
            ctx.init_junction = False
            return True, iteration, x
    ctx.init_junction = False
    return False, max_iterations, x


def finite(x: np.ndarray) -> bool:
    """Whether every entry of x is finite (one reduction: a NaN or inf makes the sum so)."""
    return math.isfinite(_SUM(x))


_SUM = np.add.reduce


def _newton_at_ports(
    system: MnaSystem,
    x0: np.ndarray,
    ctx: StepContext,
    rhs0: np.ndarray,
    max_iterations: int,
    clamp_ic: bool,
) -> tuple[bool, int, np.ndarray]:
    """:func:`newton` with every iteration an m x m solve at the junction ports.

    The same iterates and the same convergence test as the general path (see
    port_solver.py). A solution is refined and checked when it would be accepted and from the
    third iteration on (a slow Newton may be a sign of a poor update); a failed check refactors
    at the present linearization and the iteration's solution is recomputed exactly.
    """
    ports = system.ports
    discrete = system.discrete
    x = x0
    v = ports.voltages(x)
    init_junction = ctx.init_junction
    last = None  # (g, ieq, solver, rebuilds) of the previous iteration
    checked = False
    for iteration in range(1, max_iterations + 1):
        ctx.first_iteration = iteration == 1
        ctx.init_junction = init_junction and iteration == 1
        ctx.noncon = 0
        if discrete:
            x_ext = with_ground(x)
            for family in discrete:
                family.update_state(x_ext, ctx)
        key, base = system.base_matrix(ctx, clamp_ic)
        g, ieq = system.load_ports(v, ctx)
        solver = system.port_solver(key, base, g)
        if (
            last is not None
            and g is last[0]
            and ieq is last[1]
            and solver is last[2]
            and solver.rebuilds == last[3]
        ):
            # every junction bypassed and the matrix unchanged: the same linear system as the
            # last iteration, whose solution x is
            x_new, checked_new = x, checked
        else:
            x_new, exact = solver.solve(g, ieq, rhs0)
            checked_new = False
            if not exact and not finite(x_new):
                system.rebuild_port_solver(solver, g)
                x_new, _ = solver.solve(g, ieq, rhs0)
                checked_new = True
        last = (g, ieq, solver, solver.rebuilds)
        if not finite(x_new):
            ctx.init_junction = False
            ctx.x_previous = x
            return False, iteration, x_new
        v_new = ports.voltages(x_new)
        done = (
            ctx.noncon == 0
            and iteration > 1
            and system.close(x_new, x)
            and system.ports_converged(v_new, ctx)
        )
        if (done or iteration > 2) and not checked_new:
            # every solution that may be accepted is checked: one refinement step against the
            # full matrix, or a fresh factorization at this linearization if that fails
            tol = system.options.reltol * np.abs(x_new) + system.abs_tol
            refined = solver.refine(x_new, g, ieq, rhs0, tol)
            if refined is None:
                system.rebuild_port_solver(solver, g)
                refined, _ = solver.solve(g, ieq, rhs0)
                last = (g, ieq, solver, solver.rebuilds)
            x_new, checked_new = refined, True
            v_new = ports.voltages(x_new)
            done = done and system.close(x_new, x) and system.ports_converged(v_new, ctx)
        checked = checked_new
        ctx.x_previous, x, v = x, x_new, v_new
        if done:
            ctx.init_junction = False
            return True, iteration, x
    ctx.init_junction = False
    return False, max_iterations, x
