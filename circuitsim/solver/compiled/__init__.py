"""The compiled transient kernel: the reference engine's algorithm, run by numba.

:func:`run_compiled` has the signature and results of
:func:`circuitsim.solver.transient.run_transient`. The operating point is still solved by the
reference engine (dc.py); the time loop, Newton and device evaluations run compiled
(transient.py, newton.py, devices.py here), on one factorization of the base matrix updated at
low rank (lowrank.py). The reference engine stays the specification: tests run both on the same
circuits (tests/solver/test_compiled_kernel.py). Which circuits the kernel takes: see
:func:`plan.unsupported`; ``SimulationOptions.kernel`` chooses (``auto``, ``compiled``,
``python``).

numba compiles the kernel on first use and caches the machine code next to these files
(``__pycache__``), so later processes load it in a fraction of a second.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np

from circuitsim.atomic import write_text_atomic
from circuitsim.solver.compiled.plan import KernelPlan, build_plan, initial_state, unsupported
from circuitsim.solver.errors import ConvergenceError, SingularMatrixError
from circuitsim.solver.linalg import SingularPivot, factor
from circuitsim.solver.system import MnaSystem
from circuitsim.solver.transient import recorded, start_transient

__all__ = [
    "PortsStart",
    "auto_kernel",
    "check_cache",
    "kernel_unavailable",
    "ports_start",
    "run_compiled",
    "run_ports",
    "run_ports_from",
    "warm_up",
]


def kernel_unavailable(system: MnaSystem) -> str | None:
    """Why the compiled kernel cannot run ``system`` (numba missing, unsupported device,
    too large), or None."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return "numba is not installed"
    return unsupported(system)


# ``kernel="auto"`` runs the ports kernel up to this many junctions, the compiled kernel above.
# A ports iteration solves for the active junctions only, and H is formed column by column as
# needed (ports.py); but the kernel keeps md x md matrices. Measured (docs/performance.md):
# both wheelset circuits, 4 junctions / 54 unknowns and 56 junctions / 266 unknowns, run
# faster on ports than on compiled; larger circuits were not measured.
PORTS_MAX_JUNCTIONS = 64


def auto_kernel(system: MnaSystem) -> str:
    """``"ports"`` or ``"compiled"``: the one ``kernel="auto"`` runs for a supported system."""
    junctions = sum(f.port_nodes[0].size for f in system.nonlinear if f.port_nodes is not None)
    return "ports" if junctions <= PORTS_MAX_JUNCTIONS else "compiled"


KERNEL_MODULES = ("devices", "lowrank", "newton", "transient", "ports", "port_loop")
_CACHE_CHECKED: list = []
# reference-engine files whose constants the kernel compiles in (numba freezes globals)
CONSTANT_SOURCES = ("port_solver.py", "transient.py")


def clear_stale_cache(folder: Path | None = None) -> bool:
    """Delete numba's cached machine code of the kernel when any kernel file changed.

    numba's cache checks only the file a function is defined in, so a cached ``run``
    (transient.py) would keep the old code of a changed ``newton`` (newton.py) compiled into
    it, and the constants it takes from the reference engine's files. A stamp of all those
    sources, kept beside the cache, catches that. Returns True when
    cache files were deleted. Read-only package folders are left alone (numba then caches in
    its user folder, which a reinstall invalidates by the new files' modification times).
    """
    folder = folder or Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for name in KERNEL_MODULES:
        digest.update((folder / f"{name}.py").read_bytes())
    for name in CONSTANT_SOURCES:
        source = folder.parent / name
        if source.exists():
            digest.update(source.read_bytes())
    cache = folder / "__pycache__"
    stamp = cache / "kernel-sources.sha256"
    try:
        if stamp.read_text() == digest.hexdigest():
            return False
    except OSError:
        pass
    removed = False
    try:
        cache.mkdir(exist_ok=True)
        for name in KERNEL_MODULES:
            for path in [*cache.glob(f"{name}.*.nbi"), *cache.glob(f"{name}.*.nbc")]:
                path.unlink(missing_ok=True)
                removed = True
        write_text_atomic(stamp, digest.hexdigest())
    except OSError:
        return False
    return removed


def run_compiled(
    system: MnaSystem,
    tstep: float,
    tstop: float,
    tstart: float = 0.0,
    tmax: float | None = None,
    uic: bool = False,
    progress: Callable[[str], None] | None = None,
    stats: dict | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~circuitsim.solver.transient.run_transient`, compiled.

    Returns
    -------
    times : ndarray, shape (m,)
        Accepted time points >= tstart (with uic, after 0: see ``recorded``), seconds.
    solutions : ndarray, shape (m, n)
    """
    return _run("compiled", system, tstep, tstop, tstart, tmax, uic, progress, stats, None)


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
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`run_compiled` with Newton confined to the junction voltages (the ports kernel,
    port_loop.py), recording only the unknowns ``rows`` (default: all).

    Returns
    -------
    times : ndarray, shape (m,)
        Accepted time points >= tstart (with uic, after 0: see ``recorded``), seconds.
    solutions : ndarray, shape (m, len(rows))
    """
    return _run("ports", system, tstep, tstop, tstart, tmax, uic, progress, stats, rows)


# A circuit with every device kind the kernels compile for: a junction with charge, a
# switch, a capacitor and a sine source (numba compiles one machine code for all circuits).
_WARM_UP_NETLIST = """* kernel warm-up
V1 in 0 SIN(0 1 1k)
R1 in a 1k
D1 a b DW
C1 b 0 1u
S1 b 0 in 0 SW1
.model DW D(is=1e-14 cjo=1p tt=1n)
.model SW1 SW(vt=0.5 ron=1 roff=1g)
.tran 10u 200u
.end
"""


def warm_up(kernels: tuple[str, ...] = ("ports",)) -> float | None:
    """Make the compiled ``kernels`` ready in this process: built on their first use after
    an install (tens of seconds, then kept in numba's disk cache), loaded from the cache
    after that (about half a second). Call it before timing runs, so that their times do
    not include it. Returns the seconds it took; None without numba (nothing to make
    ready: ``kernel="auto"`` then runs the numpy loop).

    Raises
    ------
    CircuitInputError
        An unknown kernel.
    """
    import time

    try:
        import numba  # noqa: F401
    except ImportError:
        return None

    from circuitsim.netlist.reader import parse_netlist
    from circuitsim.solver.engine import simulate
    from circuitsim.solver.options import SimulationOptions

    started = time.perf_counter()
    circuit = parse_netlist(_WARM_UP_NETLIST)
    for kernel in kernels:
        simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=kernel))
    return time.perf_counter() - started


def check_cache() -> None:
    """:func:`clear_stale_cache`, once per process (the sources do not change under it)."""
    if not _CACHE_CHECKED:
        clear_stale_cache()
        _CACHE_CHECKED.append(True)


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
) -> PortsStart:
    """The checks, breakpoints, start solution and plan of a ports-kernel run (what
    :func:`run_ports` does before its first step), for :func:`run_ports_from`."""
    stats = stats if stats is not None else {}
    max_step, min_step, breaks, x, ctx0 = start_transient(
        system, tstep, tstop, tstart, tmax, uic, stats
    )
    plan, families = build_plan(system, breaks, tstop, max_step, min_step, uic)
    return PortsStart(system, plan, families, x, ctx0.q.copy(), tstep, tstart, min_step, bool(uic))


def run_ports_from(
    start: PortsStart,
    G: np.ndarray | None = None,
    rows: np.ndarray | None = None,
    stats: dict | None = None,
    progress: Callable[[str], None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`run_ports` from a shared start, with the constant matrix ``G`` in place of the
    system's (a sweep variant: ``MnaSystem.conductances_with``). The start is only read, so
    threads may share it. ``stats["factorizations"]`` counts this run's (``start.system`` is
    not updated).

    Raises
    ------
    ValueError
        ``G`` given for a start that is an operating point (it depends on G; use uic).
    """
    if G is not None and not start.uic:
        raise ValueError("run_ports_from: G can change only for a uic start")
    plan = start.plan
    if G is not None:
        G = np.ascontiguousarray(G if isinstance(G, np.ndarray) else G.toarray())
        plan = plan._replace(G=G)
    stats = stats if stats is not None else {}
    stats.update(accepted=0, rejected=0, newton_iterations=stats.get("newton_iterations", 0))
    counted: list[int] = []
    try:
        return _integrate("ports", start, plan, progress, stats, rows, counted)
    finally:
        stats["factorizations"] = sum(counted)


def _run(kind, system, tstep, tstop, tstart, tmax, uic, progress, stats, rows):
    stats = stats if stats is not None else {}
    start = ports_start(system, tstep, tstop, tstart, tmax, uic, stats)  # the same for both
    counted: list[int] = []
    try:
        return _integrate(kind, start, start.plan, progress, stats, rows, counted)
    finally:
        system.factorizations += sum(counted)


def _integrate(kind, start: PortsStart, plan, progress, stats, rows, counted):
    """The compiled loop from t = 0 on ``plan`` (``start.plan``, or it with a variant's G):
    (times, recorded values); the run's factorizations are appended to ``counted``, also
    when it fails."""
    check_cache()
    system, families, x, q0, tstep = start.system, start.families, start.x, start.q0, start.tstep
    from circuitsim.solver.compiled import newton as nw

    if kind == "ports":
        from circuitsim.solver.compiled import port_loop as tr
        from circuitsim.solver.compiled.port_state import initial_port_state
    else:
        from circuitsim.solver.compiled import transient as tr

    options = system.options
    fixed = options.fixed_step
    tstop, max_step = float(plan.real[10]), float(plan.real[8])
    capacity = int(min(max(2 * (tstop / (fixed or max_step)) + 100, 1000), 5_000_000))
    if kind == "ports":
        rows = np.arange(system.size) if rows is None else np.asarray(rows, dtype=np.int64)
        st = initial_port_state(plan, families, x, q0.copy(), capacity, rows)
    else:
        st = initial_state(plan, families, x, q0.copy(), capacity)
    st.fs[nw.H] = fixed if fixed else min(tstop / 100, tstep) / 10
    st.fs[nw.SAVED_H] = tstop / 50
    step = fixed or max_step
    a0_start = (2.0 if options.method == "trap" else 1.5) / step
    # the compiled loop returns every tenth of the run (Ctrl-C is seen between chunks, and
    # progress is reported there)
    report_every = tstop / 10
    t_until = report_every
    try:
        nw.factor_now(plan, st, a0_start)
        while True:
            status = tr.run(plan, st, t_until)
            if status == tr.FULL:
                st = _grown(st)
            elif status == tr.PAUSED:
                if progress is not None:
                    progress(
                        f"transient: t = {st.fs[nw.T]:.4g} s of {tstop:.4g} s, "
                        f"{st.ints[nw.ACCEPTED]} steps"
                    )
                t_until += report_every
            else:
                break
    except np.linalg.LinAlgError:
        raise SingularMatrixError(system.describe_singular(_singular_row(st.fac.B))) from None
    finally:
        stats["accepted"] = int(st.ints[nw.ACCEPTED])
        stats["rejected"] = int(st.ints[nw.REJECTED])
        stats["newton_iterations"] += int(st.ints[nw.NEWTON])
        stats["kernel"] = kind
        counted.append(int(st.ints[nw.FACTORIZATIONS]))
    if status != tr.FINISHED:
        raise _failure(system, st, status, options.max_steps)
    count = int(st.ints[nw.COUNT])
    out_t, out_x = st.out_t[:count], st.out_x[:count]
    keep = recorded(out_t, start.tstart, start.min_step, start.uic)
    return out_t[keep].copy(), out_x[keep].copy()


def _worst_junction(system: MnaSystem, fail_v: np.ndarray) -> str:
    """The junction whose voltage moved most (relative to its tolerance) in the last Newton
    iteration, as ``"a-k"`` node names (``fail_v``: that iterate and the one before, (2, md))."""
    options = system.options
    new, old = fail_v
    tol = options.reltol * np.maximum(np.abs(new), np.abs(old)) + options.vntol
    k = int(np.argmax(np.abs(new - old) / tol))
    p = np.concatenate([f.port_nodes[0] for f in system.nonlinear if f.port_nodes is not None])
    n = np.concatenate([f.port_nodes[1] for f in system.nonlinear if f.port_nodes is not None])
    names = system.layout.unknowns

    def name(i: int) -> str:
        return "0" if i < 0 else names[i][2:-1] if names[i].startswith("v(") else names[i]

    return f"{name(int(p[k]))}-{name(int(n[k]))}"


def _singular_row(matrix: np.ndarray) -> int | None:
    """The unknown whose pivot vanishes in the matrix the kernel failed to invert."""
    try:
        factor(matrix.copy())
    except SingularPivot as exc:
        return exc.index
    return None


def _grown(st):
    """The state with twice the output capacity."""
    size = st.out_t.size
    out_t = np.zeros(2 * size)
    out_t[:size] = st.out_t
    out_x = np.zeros((2 * size, st.out_x.shape[1]))
    out_x[:size] = st.out_x
    return st._replace(out_t=out_t, out_x=out_x)


def _failure(system: MnaSystem, st, status: int, max_steps: int) -> ConvergenceError:
    from circuitsim.solver.compiled import newton as nw
    from circuitsim.solver.compiled import transient as tr

    messages = {
        tr.NEWTON_FAILED_FIXED: "Newton failed at the fixed step",
        tr.STEP_TOO_SMALL: "time step too small",
        tr.STEP_TOO_SMALL_LTE: "time step too small (truncation error)",
        tr.TOO_MANY_STEPS: f"more than {max_steps} time steps attempted",
    }
    t, h = float(st.fs[nw.T]), float(st.fs[nw.H])
    node = None
    fail_x = getattr(st, "fail_x", None)  # the ports kernel keeps junction voltages only
    if status == tr.TOO_MANY_STEPS:
        pass
    elif fail_x is not None and np.all(np.isfinite(fail_x)):
        node = system.worst_unknown(st.fail_x, st.fail_prev)
    elif fail_x is None and st.fail_v.size and np.all(np.isfinite(st.fail_v)):
        node = _worst_junction(system, st.fail_v)
    time = t if status == tr.TOO_MANY_STEPS else t + h
    return ConvergenceError(messages[status], time=time, step=h, node=node)
