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
