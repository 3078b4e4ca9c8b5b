"""The ODE side: models as data, direct solution with kink events, linear stability.

Typical use::

    from circuitsim.mechanics import load_model, solve
    model = load_model()                      # the built-in wheelset
    system = model.system(parameters={"V": 55, "f": 3}, nonlinear={"flange": True})
    result = solve(system, t_span=(0, 5))
    result.max_abs("y")                       # metres
"""

from circuitsim.mechanics.errors import IntegrationError, ModelError
from circuitsim.mechanics.model import Model, load_model
from circuitsim.mechanics.solve import OdeResult, solve
from circuitsim.mechanics.stability import critical_speed, eigenvalues, growth_rate, state_matrix
from circuitsim.mechanics.system import AbsTerm, PiecewiseLinearTerm, Sinusoid, System

__all__ = [
    "AbsTerm",
    "IntegrationError",
    "Model",
    "ModelError",
    "OdeResult",
    "PiecewiseLinearTerm",
    "Sinusoid",
    "System",
    "critical_speed",
    "eigenvalues",
    "growth_rate",
    "load_model",
    "solve",
    "state_matrix",
]
