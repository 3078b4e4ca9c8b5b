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
