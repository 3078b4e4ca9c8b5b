"""circuitsim: mechanical ODE models, their op-amp analog-computer circuits, and both solved.

Rooms (see docs and ARCHITECTURE): ``mechanics`` (ODE side), ``synthesis`` (ODE -> circuit),
``netlist`` (circuit as data, SPICE text), ``solver`` (MNA engine), ``compare`` (metrics,
plots), ``interop`` (ngspice).
"""

__version__ = "0.1.0"
