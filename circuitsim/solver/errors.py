"""Errors raised by the MNA engine."""


class SolverError(RuntimeError):
    """Base class of the engine's failures."""


class ConvergenceError(SolverError):
    """Newton did not converge.

    Parameters
    ----------
    message : str
        What failed.
    time : float, optional
        Simulation time of the failed step, seconds (None for the operating point).
    step : float, optional
        Step size at the failure, seconds.
    node : str, optional
        The node (or branch) with the largest Newton residual or update.
    """

    def __init__(
        self,
        message: str,
        time: float | None = None,
        step: float | None = None,
        node: str | None = None,
    ):
        self.time = time
        self.step = step
        self.node = node
        parts = [message]
        if time is not None:
            parts.append(f"at t = {time:.6g} s")
        if step is not None:
            parts.append(f"step {step:.3g} s")
        if node is not None:
            parts.append(f"worst node {node}")
        super().__init__(", ".join(parts))


class SingularMatrixError(SolverError):
    """The MNA matrix is singular: a floating node, a source loop or similar."""


class CircuitInputError(SolverError, ValueError):
    """The circuit cannot be simulated as given: a bad value, a missing model, a bad option.

    The message names the element, model or option and what is wrong with it.
    """


class RunLimitError(SolverError):
    """A transient run stopped at one of its limits (``SimulationOptions.max_steps`` or
    ``max_wall_time``) before ``tstop``.

    Parameters
    ----------
    limit : str
        ``"max_steps"`` or ``"max_wall_time"``: the option that stopped the run.
    value : float
        The limit's value (steps, or seconds).
    time : float
        Simulation time reached, seconds.
    tstop : float
        The run's end time, seconds.
    steps : int
        Time steps attempted (accepted + rejected) until then.
    """

    def __init__(self, limit: str, value: float, time: float, tstop: float, steps: int):
        self.limit, self.value, self.time, self.tstop, self.steps = limit, value, time, tstop, steps
        what = (
            f"more than {int(value)} time steps attempted"
            if limit == "max_steps"
            else f"the run took longer than {value:g} s of wall time"
        )
        super().__init__(
            f"{what}: stopped at t = {time:.6g} s of {tstop:.6g} s after {steps} steps. "
            f"Try a higher limit (option {limit}, CLI --{limit.replace('_', '-')}), a shorter "
            "tstop, or a larger tmax/reltol if the steps are far shorter than the run needs"
        )


class SolverWarning(UserWarning):
    """Something the user of the engine should know that does not stop the run."""


class KernelCompileWarning(SolverWarning):
    """A compiled kernel is being compiled (its machine code is not cached yet): the run
    starts after a delay, said with an estimate."""


class StartupLibraryWarning(SolverWarning):
    """The start-up library (compiled/startup_library.py) could not be built: processes load
    numba's machine code instead; the message says why."""


class KernelFallbackWarning(SolverWarning):
    """``kernel="auto"`` runs the slower numpy reference loop: the compiled kernels cannot run
    this circuit (or numba is missing); the message says why."""


class RunSizeError(RunLimitError):
    """A transient run refused before it starts: it needs more steps than
    ``SimulationOptions.max_steps`` or records more than ``max_memory`` at least
    (:class:`circuitsim.netlist.run_size.RunSize`).

    Parameters
    ----------
    limit : str
        ``"max_steps"`` or ``"max_memory"``.
    value : float
        The limit's value (steps, or bytes).
    tstop : float
        The run's end time, seconds.
    message : str
        The figures and the remedies (``RunSize.refusal``).
    """

    def __init__(self, limit: str, value: float, tstop: float, message: str):
        self.limit, self.value, self.time, self.tstop, self.steps = limit, value, 0.0, tstop, 0
        SolverError.__init__(self, f"refused before the start: {message}")
        self._message = message

    def __reduce__(self):  # rebuilt from its own arguments in a parent process
        return (type(self), (self.limit, self.value, self.tstop, self._message))


class MemoryBudgetError(RunLimitError):
    """A run's recorded results reached the memory budget (``SimulationOptions.max_memory``)
    before ``tstop``: the run stops there rather than let the machine run out of memory.

    Parameters
    ----------
    value : float
        The budget, bytes.
    time : float or None
        Simulation time reached, seconds (None: not known, an ngspice run).
    tstop : float
        The run's end time, seconds.
    steps : int or None
        Time points recorded until then (None: not known).
    held : float
        Bytes held then.
    remedies : str
        What to try.
    what : str
        What held them (default: the recorded results).
    """

    def __init__(
        self,
        value: float,
        time: float | None,
        tstop: float,
        steps: int | None,
        held: float,
        remedies: str,
        what: str = "the recorded results",
    ):
        from circuitsim.netlist.run_size import size_text

        self.limit, self.value, self.time, self.tstop, self.steps = (
            "max_memory", value, time, tstop, steps
        )  # fmt: skip
        self.held = held
        self._arguments = (value, time, tstop, steps, held, remedies, what)
        where = ""
        if time is not None:
            where = f": stopped at t = {time:.6g} s of {tstop:.6g} s"
            where += f" after {steps} time points" if steps is not None else ""
        SolverError.__init__(
            self,
            f"{what} reached {size_text(held)}, and the memory budget is {size_text(value)}"
            f"{where}. {remedies[0].upper()}{remedies[1:]}",
        )

    def __reduce__(self):  # rebuilt from its own arguments in a parent process
        return (type(self), self._arguments)


class NonFiniteError(SolverError):
    """A recorded signal became infinite or NaN: the circuit's solution diverged (a loop
    with positive feedback and no limit) or overflowed.

    Parameters
    ----------
    signal : str
        The first such signal (``v(node)``, ``i(vname)``).
    time : float
        The first time point where it is not finite, seconds.
    value : float
        Its value there (inf, -inf or nan).
    last : float or None
        The signal's last finite value before, if any.
    """

    def __init__(self, signal: str, time: float, value: float, last: float | None = None):
        self.signal, self.time, self.value, self.last = signal, time, value, last
        before = f" (last finite value {last:.6g})" if last is not None else ""
        super().__init__(
            f"the solution diverged: {signal} = {value} at t = {time:.6g} s{before}; "
            "the circuit has no bounded solution from there (a loop with positive feedback "
            "and no limit), or its values overflow"
        )

    def __reduce__(self):  # rebuilt from its own arguments in a parent process
        return (type(self), (self.signal, self.time, self.value, self.last))
