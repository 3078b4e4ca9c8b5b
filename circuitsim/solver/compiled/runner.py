"""Running a transient on the compiled kernels: which kernel, its start, its loop in chunks.

:func:`run_compiled` and :func:`run_ports` have the signature and results of
:func:`circuitsim.solver.transient.run_transient`. The operating point is still solved by the
reference engine (dc.py); the time loop runs compiled (time_loop.py here). The
loop returns to Python every tenth of the run (progress) and after a bounded number of steps
(the wall-time limit, Ctrl-C), when its output arrays are full, and for a factorization it
cannot make in compiled code (a new pivot order, or the ports kernel's sparse factorization:
newton.FACTOR, then it goes on where it stopped).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from circuitsim.solver.compiled import startup_library
from circuitsim.solver.compiled.cache import (
    check_cache,
    compile_notice,
    is_cold,
    record_compile_seconds,
)
from circuitsim.solver.compiled.failures import failure, singular_row
from circuitsim.solver.compiled.fill import FILL_FUNCTIONS
from circuitsim.solver.compiled.mna_orders import (
    constant_parts,
    pivot_order,
    reorder,
    singular_message,
)
from circuitsim.solver.compiled.order_cache import EarlierOrders, compile_trial, python_called
from circuitsim.solver.compiled.pivot_search import SEARCH_FUNCTIONS
from circuitsim.solver.compiled.plan import (
    KernelPlan,
    build_plan,
    device_states,
    initial_state,
    unsupported,
)
from circuitsim.solver.compiled.slots import CFG_COUNT, MAX_STEP, PIVOT_ORDERS, TSTOP
from circuitsim.solver.compiled.sparse_factors import (
    SPARSE_FROM,
    SPARSE_FUNCTIONS,
    factor_sparse,
    factor_trial,
)
from circuitsim.solver.compiled.terminal_plan import terminal_state
from circuitsim.solver.devices.diode_kernel import CJO, TT
from circuitsim.solver.errors import (
    CircuitInputError,
    KernelCompileWarning,
    KernelFallbackWarning,
    RunLimitError,
    SingularMatrixError,
)
from circuitsim.solver.jit import numba_installed
from circuitsim.solver.recording import (
    budget_rows,
    first_non_finite,
    memory_error,
    non_finite_error,
    row_bytes,
    zero_table,
)
from circuitsim.solver.system import MnaSystem
from circuitsim.solver.transient import recorded, run_transient, start_transient, wall_deadline

# The loop returns to Python after FIRST_PAUSE attempted steps, then after about PAUSE_SECONDS
# of work, to check the wall-time limit. Such a return changes nothing: both loops keep
# their caches in the state (tests/solver/test_pause_transparency.py; the ports loop forms
# its in-place caches anew at each tenth of the run in model time, a fixed point). With
# ``fixed_pauses`` (sweep variants) every chunk is FIRST_PAUSE attempts.
FIRST_PAUSE = 20_000
PAUSE_SECONDS = 1.0

_ANNOUNCED: set[str] = set()


def kernel_unavailable(system: MnaSystem, kernel: str = "compiled") -> str | None:
    """Why the compiled ``kernel`` (``"compiled"``, the MNA kernel, or ``"ports"``) cannot
    run ``system`` (numba missing, unsupported device), or None."""
    if not numba_installed():
        return "numba is not installed"
    return unsupported(system, kernel)


# kernel="auto": the ports kernel while at most AUTO_PORTS_MAX_SWITCHING junctions carry
# charge (CJO or TT: a generated circuit's contact and precision-rectifier diodes, the junctions
# that switch during a run; an op-amp macromodel's clamp diodes have none and sit in reverse)
# and at most AUTO_PORTS_MAX_ELIMINATED ports are eliminated at each new step size (switches
# and linear charges: the ports kernel's Gauss-Jordan on them is cubic in their number; a
# TL074 macromodel brings two to three capacitors per op-amp), else the MNA kernel. Measured
# with ngspice's iteration floor (docs/solver.md, "Choosing the kernel";
# benchmarks/bench_kernels.py) at 2ab5b0e, the one time loop: the ports kernel is 1.3-2.2x
# faster on the wheelsets, the ideal chains of 1-2 masses, the TL074 chain of 1 and the
# ideal lattices of 1-4 (at most 12 charged junctions), and as fast on the TL074 chain and
# lattice of 2 (8 and 6; 24 and 27 eliminated ports); the MNA kernel 1.17x faster on the
# ideal chain of 4 (16 charged: the ports kernel's side until the MNA loop lost its
# reference counts), 2.4x on the chain of 8 (32) and 2.1x on the TL074 chain of 4 (48
# eliminated ports).
AUTO_PORTS_MAX_SWITCHING = 12
AUTO_PORTS_MAX_ELIMINATED = 32


def switching_junctions(system: MnaSystem) -> int:
    """Junctions with a charge (CJO or TT): those the ports kernel keeps active."""
    count = 0
    for family in system.families:
        part = family.kernel_data()
        if part is not None and part["kind"] == "junctions" and part["charge"] is not None:
            charge = np.asarray(part["charge"], dtype=float)
            count += int(np.count_nonzero((charge[:, CJO] != 0) | (charge[:, TT] != 0)))
    return count


def eliminated_ports(system: MnaSystem) -> int:
    """Switches and linear charges: the ports the ports kernel eliminates at a new step size."""
    count = len(system.linear_slots)
    for family in system.families:
        part = family.kernel_data()
        if part is not None and part["kind"] == "switches":
            count += len(part["nodes"])
    return count


def auto_kernel(system: MnaSystem) -> str:
    """The kernel ``kernel="auto"`` runs for a supported system: ``"ports"`` while few
    junctions switch (AUTO_PORTS_MAX_SWITCHING) and few ports are eliminated at each new step
    size (AUTO_PORTS_MAX_ELIMINATED), else ``"compiled"`` (the MNA kernel); and the MNA kernel
    for JFETs, BJTs and nonlinear POLY sources, which only it models."""
    if (
        unsupported(system, "ports") is None
        and switching_junctions(system) <= AUTO_PORTS_MAX_SWITCHING
        and eliminated_ports(system) <= AUTO_PORTS_MAX_ELIMINATED
    ):
        return "ports"
    return "compiled"


def transient_runner(system: MnaSystem, stats: dict) -> Callable:
    """The transient loop ``system.options.kernel`` asks for: :func:`run_ports`,
    :func:`run_compiled` or the reference ``run_transient``. ``kernel="auto"`` falling back to
    the reference loop warns (:class:`KernelFallbackWarning`) and says why in
    ``stats["kernel"]``.

    Raises
    ------
    CircuitInputError
        ``kernel`` is ``compiled`` or ``ports`` and that kernel cannot run the system.
    """
    choice = system.options.kernel
    if choice == "python":
        stats["kernel"] = "python"
        return run_transient
    reason = kernel_unavailable(system)
    if reason is None:
        if choice == "auto":
            choice = auto_kernel(system)
        if choice != "ports":
            return run_compiled
        reason = kernel_unavailable(system, "ports")
        if reason is None:
            return run_ports
    if choice in ("compiled", "ports"):
        raise CircuitInputError(f"option kernel={choice}: {reason}")
    stats["kernel"] = f"python ({reason})"
    if reason.startswith("no charges"):  # nothing to integrate: no loop is faster there
        return run_transient
    warnings.warn(
        KernelFallbackWarning(
            f"the compiled kernels cannot run this circuit ({reason}): the numpy reference "
            "loop runs it, slower"
        ),
        stacklevel=3,
    )
    return run_transient


def run_compiled(
    system: MnaSystem,
    tstep: float,
    tstop: float,
    tstart: float = 0.0,
    tmax: float | None = None,
    uic: bool = False,
    progress: Callable[[str], None] | None = None,
    stats: dict | None = None,
    rows: np.ndarray | None = None,
    fixed_pauses: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~circuitsim.solver.transient.run_transient`, compiled; only the unknowns
    ``rows`` (default: all) are recorded and returned; ``fixed_pauses`` as in
    :func:`run_ports`.

    Returns
    -------
    times : ndarray, shape (m,)
        Accepted time points >= tstart (with uic, after 0: see ``recorded``), seconds.
    solutions : ndarray, shape (m, len(rows))
    """
    return _run(
        "compiled", system, tstep, tstop, tstart, tmax, uic, progress, stats, rows, fixed_pauses
    )


def run_ports(
    system: MnaSystem,
    tstep: float,
    tstop: float,
    tstart: float = 0.0,
    tmax: float | None = None,
    uic: bool = False,
    progress: Callable[[str], None] | None = None,
    stats: dict | None = None,
    rows: np.ndarray | None = None,
    fixed_pauses: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`run_compiled` with Newton confined to the junction voltages (the ports kernel,
    port_steps.py), recording only the unknowns ``rows`` (default: all); ``fixed_pauses``:
    chunks of a fixed number of attempted steps (values independent of the machine's speed).

    Returns
    -------
    times : ndarray, shape (m,)
        Accepted time points >= tstart (with uic, after 0: see ``recorded``), seconds.
    solutions : ndarray, shape (m, len(rows))
    """
    return _run(
        "ports", system, tstep, tstop, tstart, tmax, uic, progress, stats, rows, fixed_pauses
    )


class PortsStart(NamedTuple):
    """A compiled run up to its first step (:func:`ports_start`; the same for both kernels):
    what runs that differ only in the constant matrix G can share."""

    system: MnaSystem
    plan: KernelPlan
    families: dict  # build_plan's device states at t = 0
    x: np.ndarray  # (n,) start solution
    q0: np.ndarray  # (nq,) its charges
    tstep: float  # s (the first step is a tenth of min(tstep, tstop / 100))
    tstart: float  # s
    min_step: float  # s
    uic: bool  # the start solution does not depend on G


def ports_start(
    system: MnaSystem,
    tstep: float,
    tstop: float,
    tstart: float = 0.0,
    tmax: float | None = None,
    uic: bool = False,
    stats: dict | None = None,
    dense: bool = True,
) -> PortsStart:
    """The checks, breakpoints, start solution and plan of a ports-kernel run (what
    :func:`run_ports` does before its first step), for :func:`run_ports_from`; ``dense``:
    False for an MNA-kernel run (its plan without dense G and M: plan.build_plan)."""
    stats = stats if stats is not None else {}
    max_step, min_step, breaks, x, ctx0 = start_transient(
        system, tstep, tstop, tstart, tmax, uic, stats
    )
    plan, families = build_plan(system, breaks, tstop, max_step, min_step, uic, dense)
    return PortsStart(system, plan, families, x, ctx0.q.copy(), tstep, tstart, min_step, bool(uic))


def run_ports_from(
    start: PortsStart,
    G: np.ndarray | None = None,
    rows: np.ndarray | None = None,
    stats: dict | None = None,
    progress: Callable[[str], None] | None = None,
    fixed_pauses: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`run_ports` from a shared start, with the constant matrix ``G`` in place of the
    system's (a sweep variant: ``MnaSystem.conductances_with``). The start is only read, so
    threads may share it. ``stats["factorizations"]`` counts this run's (``start.system`` is
    not updated). ``fixed_pauses`` as in :func:`run_ports`.

    Raises
    ------
    ValueError
        ``G`` given for a start that is an operating point (it depends on G; use uic).
    """
    if G is not None and not start.uic:
        raise ValueError("run_ports_from: G can change only for a uic start")
    plan = start.plan
    if G is not None:
        G = np.ascontiguousarray(G if isinstance(G, np.ndarray) else G.toarray(), dtype=float)
        plan = plan._replace(G=G)
    stats = stats if stats is not None else {}
    stats.update(accepted=0, rejected=0, newton_iterations=stats.get("newton_iterations", 0))
    counted: list[int] = []
    try:
        return _integrate("ports", start, plan, progress, stats, rows, counted, fixed_pauses)
    finally:
        stats["factorizations"] = sum(counted)


def _run(kind, system, tstep, tstop, tstart, tmax, uic, progress, stats, rows, fixed=False):
    stats = stats if stats is not None else {}
    # the same for both, but for the MNA kernel's plan without dense G and M
    start = ports_start(system, tstep, tstop, tstart, tmax, uic, stats, dense=kind == "ports")
    counted: list[int] = []
    try:
        return _integrate(kind, start, start.plan, progress, stats, rows, counted, fixed)
    finally:
        system.factorizations += sum(counted)


def _loop_state(kind, start: PortsStart, plan, rows, capacity, constant=None, earlier=None):
    """The kernel module and its state at t = 0 (with the rows it records, and the slots of
    a return to Python in the middle of a step: newton.RESUME_*); for the MNA kernel,
    ``constant``: its (G, M), sparse (:func:`constant_parts`), and ``earlier``: the
    EarlierOrders that gets the pivot orders not chosen."""
    loop = _loop_module(kind)
    if kind == "ports":
        from circuitsim.solver.compiled.port_state import initial_port_state

        rows = np.arange(start.system.size) if rows is None else np.asarray(rows, dtype=np.int64)
        state = initial_port_state(plan, start.families, start.x, start.q0.copy(), 1, rows)
    else:
        devices = device_states(start.families)
        terms = terminal_state(start.families["terminals"], plan.terms)
        a0 = _a0_start(start)
        lu, *others = pivot_order(plan, devices["gd"], devices["state"], a0, terms, constant,
                                  search=earlier.search)  # fmt: skip
        for other in others:  # the other column orders' (tried when a pivot gets small)
            earlier.keep(other)
        state = initial_state(plan, start.families, start.x, start.q0.copy(), 1, lu)
        if rows is not None:  # only these are recorded (the loop's MidStep.rows)
            rows = np.asarray(rows, dtype=np.int64)
            state = state._replace(out_x=start.x[rows][None, :])
    # the recorded table, lazily zero (recording.zero_table): it costs what the run writes
    out_x = zero_table((capacity, state.out_x.shape[1]))
    out_x[0] = state.out_x[0]
    state = state._replace(out_t=zero_table(capacity), out_x=out_x)
    from circuitsim.solver.compiled import newton as nw

    state = state._replace(
        fs=np.concatenate([state.fs, np.full(nw.RESUME_FLOATS, np.nan)]),
        ints=np.concatenate([state.ints, np.zeros(nw.RESUME_INTS, dtype=np.int64)]),
    )
    if kind == "ports" and factors_in_python(state):
        state.ints[nw.FACTOR_IN_PYTHON] = 1
    return loop, state, _mid_step(kind, state, rows)


def _loop_module(kind: str):
    """The time loop's module (time_loop.py: its status codes and slots)."""
    from circuitsim.solver.compiled import time_loop

    return time_loop


def _loop_entry(kind: str):
    """The kernel's entry into the time loop (a numba function): time_loop.run_ports (ports)
    or run_mna (MNA)."""
    loop = _loop_module(kind)
    return loop.run_ports if kind == "ports" else loop.run_mna


def _mid_step(kind, st, rows) -> tuple:
    """The MNA loop's extra argument: its arrays that outlive a return mid-step and the
    unknowns it records (MidStep; ``rows`` None: all); none for the ports loop."""
    from circuitsim.solver.compiled import newton as nw

    if kind == "ports":
        return ()
    n, nq = st.hx.shape[1], st.hq.shape[1]
    rows = np.arange(n, dtype=np.int64) if rows is None else np.asarray(rows, dtype=np.int64)
    kept = np.empty(n), np.zeros(nq), np.zeros(nq), st.fs.copy(), st.ints.copy()
    return (nw.MidStep(*kept, rows),)


def factors_in_python(state) -> bool:
    """Whether the ports kernel's factorizations are made in Python (sparse, for a state
    without room for the dense matrices: above sparse_factors.SPARSE_FROM unknowns)."""
    return state.fac.Binv.shape[0] != state.fac.yc.size


def _factor(plan, st, a0: float) -> None:
    """The ports kernel's factorization at the present port values and a0 (1/s), as the loop
    asks (newton.factor_now): compiled (dense), or sparse from Python (sparse_factors.py)."""
    from circuitsim.solver.compiled import newton as nw

    if st.fac.Binv.shape[0] == st.fac.yc.size:
        nw.dense_factor(plan, st, a0)
    else:
        factor_sparse(plan, st, a0)


def _helpers(kind: str, plan, n: int) -> tuple:
    """The compiled functions the runner calls from Python on ``kind``'s run of ``plan`` (n
    unknowns)."""
    if kind == "ports":
        return SPARSE_FUNCTIONS if n >= SPARSE_FROM else ()
    return (*FILL_FUNCTIONS, *SEARCH_FUNCTIONS, *python_called(plan))


def _a0_start(start: PortsStart) -> float:
    """The step coefficient the first factorization is made at (the nominal step's)."""
    options = start.system.options
    step = options.fixed_step or float(start.plan.real[MAX_STEP])
    return (2.0 if options.method == "trap" else 1.5) / step


def _integrate(kind, start: PortsStart, plan, progress, stats, rows, counted, fixed_pauses=False):
    """The compiled loop from t = 0 on ``plan`` (``start.plan``, or it with a variant's G):
    (times, recorded values); the run's factorizations are appended to ``counted``, also
    when it fails."""
    check_cache()
    from circuitsim.solver.compiled import newton as nw

    system, tstep = start.system, start.tstep
    options = system.options
    fixed = options.fixed_step
    tstop, max_step = float(plan.real[TSTOP]), float(plan.real[MAX_STEP])
    capacity = int(min(max(2 * (tstop / (fixed or max_step)) + 100, 1000), 5_000_000))
    columns = system.size if rows is None else len(rows)
    # the budget's points: the output arrays are made with np.zeros, whose pages cost memory
    # only once written, so a table sized to the budget costs what the run records
    most_points = budget_rows(options.max_memory, columns)
    if most_points is not None:
        capacity = max(1, min(capacity, most_points))
    constant = constant_parts(system) if kind != "ports" else None
    orders = EarlierOrders()  # the MNA kernel's earlier pivot orders
    # the compiled functions the runner calls from Python (pivot orders and their fill, the
    # MNA kernel's trials of earlier orders, the ports kernel's sparse factorizations):
    # compiled with the kernel, announced with it, not in the middle of the run
    cold_helpers = any(is_cold(f) for f in _helpers(kind, plan, system.size))
    entry = _loop_entry(kind)
    compiling = _announce_compile(kind, entry, cold_helpers)
    try:
        loop, st, mid = _loop_state(kind, start, plan, rows, capacity, constant, orders)
    except np.linalg.LinAlgError:  # the first pivot order: the start's matrix is singular
        devices = device_states(start.families)
        terms = terminal_state(start.families["terminals"], plan.terms)
        raise SingularMatrixError(
            singular_message(system, plan, devices["gd"], devices["state"], _a0_start(start), terms)
        ) from None
    st.fs[nw.H] = fixed if fixed else min(tstop / 100, tstep) / 10
    st.fs[nw.SAVED_H] = tstop / 50
    if cold_helpers and kind == "ports":
        factor_trial()
    elif cold_helpers:
        compile_trial(plan, st)
    deadline = wall_deadline(options, time.perf_counter)  # the clock the pauses read
    report_every = tstop / 10  # progress every tenth of the run
    t_until = report_every
    st.ints[nw.PAUSE_ATTEMPTS] = FIRST_PAUSE
    began = time.perf_counter()
    made, repivoted_at, same_step = 1, -1, 0  # pivot orders made (sparse_order.py)
    factored_in_python = 0  # FACTOR returns
    checked = 0  # recorded points found finite (_check_recorded)
    try:
        if kind == "ports":  # the first factorization: by the loop (newton.FIRST_FACTOR)
            st.fs[nw.FACTOR_A0] = _a0_start(start)
            st.ints[nw.RESUME_AT] = nw.FIRST_FACTOR
        # the rate of attempted steps since the last pause sizes the next chunk; a chunk
        # that compiled has no rate (its own would make every later chunk 100 steps)
        chunk_began, attempts, compiled = time.perf_counter(), int(st.ints[nw.ATTEMPTS]), False
        while True:
            status = entry(plan, st, t_until, *mid)
            if compiling:
                seconds = time.perf_counter() - began
                record_compile_seconds(kind, seconds)
                compiling, compiled = False, True
                if deadline is not None:  # the compile (minutes at a load) is not the run's
                    deadline += seconds  # time; its first chunk's steps are forgiven with it
            if status == nw.FACTOR and kind == "ports":
                _factor(plan, st, float(st.fs[nw.FACTOR_A0]))
                factored_in_python += 1
                continue
            if status == nw.FACTOR:  # MNA: a new pivot order at this matrix, then on
                a0 = float(st.fs[nw.FACTOR_A0])
                earlier = orders.suited(plan, st, a0)
                orders.keep(st.lu)
                if earlier is not None:
                    st = st._replace(lu=earlier)
                    continue
                if reorder(plan, st, a0, orders.search) == 0:
                    continue
                # no room for its fill, or singular: the step is undone, as the loop's REPIVOT
                st.fs[:] = mid[0].fs_start
                st.ints[:] = mid[0].ints_start
                st.fs[loop.REPIVOT_A0] = a0
                status = loop.REPIVOT
            if status == loop.FULL:
                checked = _check_recorded(system, st, rows, checked)
                st = _grown(st, most_points, options.max_memory, tstop)
            elif kind != "ports" and status == loop.REPIVOT:
                # the step is attempted again: each new order lets it go further (at most
                # one per Newton iteration), unless the matrix is singular
                same_step += repivoted_at == st.ints[nw.ATTEMPTS]
                if same_step > options.transient_iterations + 1:
                    raise np.linalg.LinAlgError("no pivot order suits the matrix")
                repivoted_at = int(st.ints[nw.ATTEMPTS])
                a0 = float(st.fs[loop.REPIVOT_A0])
                lu = pivot_order(plan, st.gd, st.state, a0, st.terms, constant, 2.0,
                                 orders.search)[0]  # fmt: skip
                st = st._replace(lu=lu)
                made += 1
            elif status == loop.PAUSED:
                checked = _check_recorded(system, st, rows, checked)
                if st.fs[nw.T] >= t_until:
                    if progress is not None:
                        progress(
                            f"transient: t = {st.fs[nw.T]:.4g} s of {tstop:.4g} s, "
                            f"{st.ints[nw.ACCEPTED]} steps"
                        )
                    t_until += report_every
                done = int(st.ints[nw.ATTEMPTS])
                if deadline is not None and time.perf_counter() > deadline:
                    raise RunLimitError(
                        "max_wall_time", options.max_wall_time, float(st.fs[nw.T]), tstop, done
                    )
                if fixed_pauses or compiled:
                    st.ints[nw.PAUSE_ATTEMPTS] = done + FIRST_PAUSE
                else:
                    rate = (done - attempts) / max(time.perf_counter() - chunk_began, 1e-6)
                    pause = int(min(max(rate * PAUSE_SECONDS, 100), 1e7))
                    st.ints[nw.PAUSE_ATTEMPTS] = done + pause
                chunk_began, attempts, compiled = time.perf_counter(), done, False
            else:
                break
    except np.linalg.LinAlgError:
        if kind == "ports":
            raise SingularMatrixError(system.describe_singular(singular_row(st.fac.B))) from None
        raise SingularMatrixError(
            singular_message(system, plan, st.gd, st.state, float(st.fs[loop.REPIVOT_A0]), st.terms)
        ) from None
    finally:
        stats["accepted"] = int(st.ints[nw.ACCEPTED])
        stats["rejected"] = int(st.ints[nw.REJECTED])
        stats["newton_iterations"] += int(st.ints[nw.NEWTON])
        stats["kernel"] = kind
        if kind == "ports":  # eliminations of the switch and charge ports (new a0 or switch)
            stats["configurations"] = int(st.ints[CFG_COUNT])
            stats["factor_returns"] = factored_in_python
        else:
            # orders made (sparse_order.py); "orders_reused": an earlier one taken again instead
            stats["pivot_orders"] = made + int(st.ints[PIVOT_ORDERS]) - orders.reused
            stats["orders_reused"] = orders.reused
            stats["pivot_search"] = orders.search.get("kind")  # "ours" or "superlu"
        counted.append(int(st.ints[nw.FACTORIZATIONS]))
    _check_recorded(system, st, rows, checked)  # a diverged run's first failure
    if status != loop.FINISHED:
        raise failure(system, st, status, tstop)
    if kind != "ports" and startup_library.wanted(kind):
        compile_trial(plan, st)  # its helpers in this process, for the start-up library's build
    count = int(st.ints[nw.COUNT])
    out_t, out_x = st.out_t[:count], st.out_x[:count]
    keep = recorded(out_t, start.tstart, start.min_step, start.uic)
    # times increase, so the points kept are a tail: returned as views of the output arrays
    # (the recorded table is the largest thing a run holds; a copy doubled a long run's peak)
    first = count - int(np.count_nonzero(keep))
    if keep[first:].all():
        return out_t[first:], out_x[first:]
    return out_t[keep], out_x[keep]


def _announce_compile(kind: str, dispatcher, helpers_cold: bool = False) -> bool:
    """Warn (once per process and kernel) when ``dispatcher`` must compile before it runs, or
    the kernel's functions called from Python must (``helpers_cold``); returns whether
    ``dispatcher`` must."""
    cold = is_cold(dispatcher)
    if (cold or helpers_cold) and kind not in _ANNOUNCED:
        _ANNOUNCED.add(kind)
        warnings.warn(KernelCompileWarning(compile_notice(kind)), stacklevel=4)
    return cold


def _check_recorded(system: MnaSystem, st, rows, checked: int) -> int:
    """Raise NonFiniteError when a point recorded since the first ``checked`` holds inf or
    NaN; returns the points checked."""
    from circuitsim.solver.compiled import newton as nw

    count = int(st.ints[nw.COUNT])
    row = first_non_finite(st.out_x, checked, count)
    if row is None:
        return count
    names = system.layout.unknowns
    names = names if rows is None else [names[int(i)] for i in rows]
    raise non_finite_error(names, st.out_t, st.out_x, row)


def _grown(st, most_points: int | None = None, max_memory=None, tstop: float = 0.0):
    """The state with twice the output capacity; a MemoryBudgetError when the old table and
    the new one would pass the budget of ``most_points`` points together (the copy holds
    both)."""
    size = st.out_t.size
    if most_points is not None and 2 * size > most_points:
        from circuitsim.solver.compiled import newton as nw

        held = size * row_bytes(st.out_x.shape[1])
        raise memory_error(max_memory, float(st.fs[nw.T]), tstop, size, held)
    out_t = zero_table(2 * size)
    out_t[:size] = st.out_t
    out_x = zero_table((2 * size, st.out_x.shape[1]))
    out_x[:size] = st.out_x
    return st._replace(out_t=out_t, out_x=out_x)
