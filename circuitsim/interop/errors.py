"""Errors raised when running other simulators."""


class NgspiceError(RuntimeError):
    """ngspice is missing, failed, or produced no usable output.

    Parameters
    ----------
    message : str
        What went wrong.
    log : str, optional
        The relevant lines of ngspice's output.
    """

    def __init__(self, message: str, log: str = ""):
        self.log = log
        super().__init__(f"{message}\n{log}" if log else message)


class NgspiceTimeout(NgspiceError):
    """ngspice ran past its time limit and was stopped.

    Parameters
    ----------
    seconds : float
        The limit that passed.
    log : str, optional
        The last lines ngspice printed.
    """

    def __init__(self, seconds: float, log: str = ""):
        self.seconds = seconds
        self._log = log
        super().__init__(
            f"ngspice did not finish within {seconds:g} s and was stopped; a longer .tran step "
            "or TMAX (fewer time points), a shorter TSTOP, or a longer limit (run_ngspice's "
            "timeout=..., --ngspice-timeout SECONDS of circuitsim simulate, compare, sweep, "
            "reproduce) may help",
            log,
        )

    def __reduce__(self):  # rebuilt from its own arguments in a parent process
        return (type(self), (self.seconds, self._log))
