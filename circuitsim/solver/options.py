"""Simulation tolerances and limits, with ngspice's defaults, read from ``.options``."""

from __future__ import annotations

import dataclasses
import numbers
from dataclasses import dataclass, field

from circuitsim.netlist.circuit import Circuit, Expression
from circuitsim.netlist.run_size import default_memory_budget
from circuitsim.solver.errors import CircuitInputError

METHODS = ("trap", "gear")
KERNELS = ("auto", "compiled", "ports", "python")
# fields that are ours, not ngspice's: a netlist's .options cannot set them
NOT_NGSPICE = (
    "fixed_step",
    "dense_limit",
    "max_steps",
    "max_wall_time",
    "max_memory",
    "kernel",
    "itl_floor",
)
# ngspice's NIiter raises every Newton iteration limit below this to it (niiter.c)
NGSPICE_ITERATION_FLOOR = 100


@dataclass
class SimulationOptions:
    """Tolerances, iteration limits and integration settings of one run.

    The defaults are ngspice's. ``.options`` keys of the same (lower-case) name override them
    through :meth:`from_circuit`; unknown ``.options`` keys are ignored, as ngspice ignores
    options it does not use for a given analysis.

    Attributes
    ----------
    reltol : float
        Relative tolerance of node voltages, branch currents, charges (dimensionless).
    abstol : float
        Absolute current tolerance, amperes.
    vntol : float
        Absolute voltage tolerance, volts.
    chgtol : float
        Absolute charge tolerance, coulombs (LTE control).
    trtol : float
        Factor by which the local truncation error may exceed the tolerances (ngspice: 7).
    gmin : float
        Conductance in parallel with every junction, siemens.
    method : str
        ``"trap"`` (trapezoidal) or ``"gear"`` (BDF).
    maxord : int
        Highest integration order (1 or 2; 1 makes both methods backward Euler).
    itl1 : int
        Newton iteration limit of the operating point, as given; the limit the Newton loops
        apply is :attr:`op_iterations`.
    itl4 : int
        Newton iteration limit of one transient time point, as given; the limit the Newton
        loops apply is :attr:`transient_iterations`.
    gminsteps : int
        Number of gmin stepping decades tried (0 skips gmin stepping).
    srcsteps : int
        Source-stepping effort (0 skips source stepping).
    fixed_step : float or None
        If set, seconds: the transient takes exactly this step (breakpoints still hit, no LTE
        control). For order studies; not an ngspice option.
    dense_limit : int
        Up to this many unknowns the engine uses dense LU (LAPACK); above it sparse LU.
    max_steps : int
        Bound on attempted time steps (accepted + rejected); past it the run stops with a
        :class:`~circuitsim.solver.errors.RunLimitError` saying where it stopped.
    max_wall_time : float or None
        Bound on a transient run's wall time, seconds (None: none); past it the run stops with
        a :class:`~circuitsim.solver.errors.RunLimitError`. Checked between steps (the
        compiled loops return to Python for that after 20,000 steps, then about every
        second of work). A compile of the kernel in the run (its first use on a machine)
        does not count: the deadline moves by the time of the compiling first call.
    max_memory : float or None
        Budget of a transient run's recorded results, bytes (default: half the machine's
        physical memory, netlist/run_size.py; None: none). A run whose recorded table needs
        more at least (its time points at TMAX, times the recorded signals and the time, 8
        bytes each: netlist.run_size.RunSize) is refused before it starts, and a run whose
        table grows past it (steps shorter than TMAX) stops with a
        :class:`~circuitsim.solver.errors.MemoryBudgetError` at the time it reached. The
        compiled loops grow their table by doubling and hold the old one during the copy,
        so they stop when the next doubling would pass the budget (between half of it and
        all of it recorded); the reference loop counts its table twice (the list of points
        and the array made of it at the end).
    bypass : int
        1: after the first Newton iteration of a time point, a junction whose voltage and
        linearized current are within tolerance of its last evaluation keeps that evaluation
        (SPICE's device bypass; then an iteration in which every junction is bypassed costs no
        solve). 0 (default, as ngspice 39 behaves: its step sequences on the golden netlists
        are those without bypass) evaluates every junction at every iteration.
    itl_floor : int
        Newton iteration limits (``itl1``, ``itl4``) below this are raised to it, as ngspice's
        NIiter does (it raises any limit below 100 to 100, so that ngspice's default
        itl4 = 10, and even itl4 = 3, give 100 iterations per time point). 0 or 1: no floor
        (the limits apply as given; for tests that force a Newton failure). Not an ngspice
        option.
    kernel : str
        Which transient loop runs: ``"compiled"`` (numba, solver/compiled/: Newton on the
        whole MNA matrix, refactored sparse at every iteration; an error if the circuit or
        the machine does not allow it), ``"ports"`` (compiled, Newton on the junction
        voltages alone: solver/compiled/ports.py; same conditions), ``"python"`` (the
        reference engine, solver/transient.py) or ``"auto"`` (default: when numba is
        installed and the circuit is supported, ports while at most 16 junctions carry
        charge, else compiled (solver/compiled/runner.py, auto_kernel, from measurements in
        docs/solver.md), else python;
        ``Waveforms.stats["kernel"]`` says which ran).
    """

    reltol: float = 1e-3
    abstol: float = 1e-12
    vntol: float = 1e-6
    chgtol: float = 1e-14
    trtol: float = 7.0
    gmin: float = 1e-12
    method: str = "trap"
    maxord: int = 2
    itl1: int = 100
    itl4: int = 10
    gminsteps: int = 10
    srcsteps: int = 10
    fixed_step: float | None = None
    dense_limit: int = 150
    max_steps: int = 2_000_000
    max_wall_time: float | None = 600.0
    max_memory: float | None = field(default_factory=default_memory_budget)
    bypass: int = 0
    itl_floor: int = NGSPICE_ITERATION_FLOOR
    kernel: str = "auto"

    def __post_init__(self) -> None:
        self.method = str(self.method).lower()
        if self.method in ("trapezoidal",):
            self.method = "trap"
        if self.method not in METHODS:
            raise CircuitInputError(
                f"option method={self.method!r}: expected one of {', '.join(METHODS)}"
            )
        for name in ("reltol", "abstol", "vntol", "chgtol", "trtol"):
            if not getattr(self, name) > 0:
                raise CircuitInputError(f"option {name}={getattr(self, name)!r} must be > 0")
        if self.gmin < 0:
            raise CircuitInputError(f"option gmin={self.gmin!r} must be >= 0")
        if self.maxord not in (1, 2):
            # Gear orders above 2 are not implemented; ngspice accepts up to 6.
            self.maxord = max(1, min(int(self.maxord), 2))
        if self.kernel not in KERNELS:
            raise CircuitInputError(
                f"option kernel={self.kernel!r}: expected one of {', '.join(KERNELS)}"
            )
        if not self.max_steps > 0:
            raise CircuitInputError(f"option max_steps={self.max_steps!r} must be > 0")
        if self.max_wall_time is not None and not self.max_wall_time > 0:
            raise CircuitInputError(f"option max_wall_time={self.max_wall_time!r} must be > 0")
        if self.max_memory is not None and not self.max_memory > 0:
            raise CircuitInputError(f"option max_memory={self.max_memory!r} must be > 0")
        if self.fixed_step is not None and not self.fixed_step > 0:
            raise CircuitInputError(f"fixed_step={self.fixed_step!r} must be > 0")
        for name in ("itl1", "itl4", "itl_floor"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Integral):
                raise CircuitInputError(f"option {name}={value!r}: expected an integer")
            if value < 0:
                raise CircuitInputError(f"option {name}={value!r} must be >= 0")

    @property
    def op_iterations(self) -> int:
        """Newton iteration limit of an operating-point solve: ``max(itl1, itl_floor, 1)``."""
        return max(int(self.itl1), int(self.itl_floor), 1)

    @property
    def transient_iterations(self) -> int:
        """Newton iteration limit of one transient time point: ``max(itl4, itl_floor, 1)``."""
        return max(int(self.itl4), int(self.itl_floor), 1)

    @classmethod
    def from_circuit(cls, circuit: Circuit, **overrides) -> SimulationOptions:
        """Defaults, then the circuit's ``.options``, then ``overrides`` (keyword arguments)."""
        known = {f.name: f for f in dataclasses.fields(cls)}
        values: dict = {}
        for key, raw in circuit.options.items():
            key = key.lower()
            if key not in known or key in NOT_NGSPICE:
                continue
            values[key] = _option_value(key, raw, known[key].type)
        values.update(overrides)
        return cls(**values)


def _option_value(key: str, raw, annotation) -> object:
    """Convert one ``.options`` value to the field's type, or raise naming the option."""
    if key == "method":
        text = raw.text if isinstance(raw, Expression) else str(raw)
        return text.strip().lower()
    if isinstance(raw, bool) or isinstance(raw, Expression):
        raise CircuitInputError(f".options {key}: expected a number, got {raw!s}")
    try:
        number = float(raw)
    except (TypeError, ValueError):
        raise CircuitInputError(f".options {key}: expected a number, got {raw!r}") from None
    return int(number) if str(annotation) == "int" else number
