"""Errors raised by the ODE side."""


class ModelError(ValueError):
    """A model file or model description is invalid.

    Parameters
    ----------
    message : str
        What is wrong.
    file : str, optional
        The model file, when the model came from one.
    key : str, optional
        Dotted path of the offending key, e.g. ``"coefficients.paper.c_y"``.
    """

    def __init__(self, message: str, file: str | None = None, key: str | None = None):
        self.message = message
        self.file = file
        self.key = key
        where = ": ".join(part for part in (file, key) if part)
        super().__init__(f"{where}: {message}" if where else message)


class IntegrationError(ModelError):
    """The direct ODE solution failed (the integrator gave up, or kinks would not advance).

    A ModelError so that callers (and the CLI) handling model problems handle this too; the
    message says at what time and why.
    """


class IntegrationLimitError(IntegrationError):
    """The direct solution reached its step-count or wall-time limit before the end.

    Parameters
    ----------
    message : str
        Where it stopped and what to try.
    time : float
        Model time reached, s.
    steps : int
        Step attempts taken.
    limit : str
        ``"steps"`` or ``"time"``.
    """

    def __init__(self, message: str, time: float, steps: int, limit: str):
        super().__init__(message)
        self.time = time
        self.steps = steps
        self.limit = limit
