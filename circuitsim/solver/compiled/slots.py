"""Named slots of the compiled loops' plain arrays (numpy only, no numba).

The loops keep their scalars in small arrays so that a run can stop, return to Python (progress,
the wall-time limit, a new pivot order) and go on: ``plan.real`` / ``plan.ints`` (the run's
constants, built by plan.build_plan) and ``state.fs`` / ``state.ints`` (what the loop changes,
started by plan.start_counters). The device parameter matrices' columns are named in the
devices' kernel twins (devices/diode_kernel.py, switch_kernel.py, source_kernel.py).
"""

from __future__ import annotations

# plan.real: tolerances (reltol, abstol A, vntol V, chgtol C, trtol), the integration
# method's error constants at order 1 and 2, the fixed step (0: adaptive), TMAX, the smallest
# step and tstop (s); the MNA kernel's chord tolerance (plan.CHORD_TOLERANCE: a junction conductance
# within this fraction of the factored one keeps the factored one)
RELTOL, ABSTOL, VNTOL, CHGTOL, TRTOL, ERROR_ORDER1, ERROR_ORDER2 = range(7)
FIXED_STEP, MAX_STEP, MIN_STEP, TSTOP, CHORD = range(7, 12)
REAL_SLOTS = 12
# plan.ints: integration method (TRAP or GEAR), highest order, Newton iterations per time
# point (itl4), attempted steps allowed, whether the run starts from initial conditions (uic)
METHOD, MAXORD, ITL4, MAX_STEPS, UIC = range(5)
PLAN_INT_SLOTS = 5
TRAP, GEAR = 0, 1

# state.fs: time, next step, the step saved before landing on a breakpoint (s), the a0 of the
# last accepted step (1/s), and one slot per loop: the MNA loop's a0 at which a pivot order
# failed (REPIVOT_A0), the ports loop's a0 of its present configuration (CFG_A0)
T, H, SAVED_H, LAST_A0 = range(4)
REPIVOT_A0 = CFG_A0 = 4
FLOAT_SLOTS = 5

# state.ints, both loops: integration order, at a breakpoint, first step, index of the next
# breakpoint, steps attempted, accepted, rejected, Newton iterations, factorizations
ORDER, AT_BREAK, FIRST, BI, ATTEMPTS, ACCEPTED, REJECTED, NEWTON, FACTORIZATIONS = range(9)
# history points (1-4), output rows written, accepted steps in a row at one a0, the
# factorization's version, the version the junctions' responses were formed at
NHIST, COUNT, SAME_A0, VERSION, JUNCTION_VERSION = range(9, 14)
# slot 14, one per loop: the MNA loop's pivot orders made during the run (after the first);
# the ports loop's factorization version its configuration was made from (-1: none)
PIVOT_ORDERS = CFG_VERSION = 14
# the ports loop's: 1 when a switch toggled since the configuration, configurations made (H's
# columns are formed lazily for the present one), accepted steps in a row that ended with many
# active junctions
CFG_STALE, CFG_COUNT, ACTIVE_STREAK = 15, 16, 17
# both loops: the loop returns PAUSED once this many steps were attempted (the caller checks
# its wall-time limit and Ctrl-C); active junctions the run's last refactor left, and that
# refactor's VERSION (newton.rebase_wanted)
PAUSE_ATTEMPTS, AFTER_REFACTOR, MEASURED_VERSION = 18, 19, 20
# the ports loop's caches, kept across its returns so that a pause changes nothing: 1 when H
# ieq is to be recomputed in full (H changed), and the factorization version the recorded
# unknowns' junction part (PortState.y_junctions) was formed at (-1: none)
NEW_H_MATRIX, Y_VERSION = 21, 22
INT_SLOTS = 23
