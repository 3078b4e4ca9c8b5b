"""Option helpers shared by several verbs, and the progress printer."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable


def progress(message: str) -> None:
    """Progress callback handed to long-running library calls: one line on stderr."""
    print(message, file=sys.stderr, flush=True)


def progress_after(delay: float = 1.0) -> Callable[[str], None]:
    """:func:`progress`, silent until ``delay`` seconds after this call: a run that ends
    sooner prints no progress lines, a long one reports as usual."""
    started = time.monotonic()

    def report(message: str) -> None:
        if time.monotonic() - started >= delay:
            progress(message)

    return report


def add_model_options(parser: argparse.ArgumentParser) -> None:
    """--model and --coeffs, shared by the ODE-side verbs."""
    parser.add_argument(
        "--model",
        metavar="FILE",
        help="model file (TOML, see docs/model.md); default: the built-in wheelset",
    )
    parser.add_argument(
        "--coeffs",
        metavar="SET",
        help="coefficient set of the model; wheelset: paper (default, the paper's eq. 5), "
        "derived (Table 1 via eq. 4) or eq2 (eq. 2, with suspension damping)",
    )


def parameter_assignment(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    try:
        if not sep or not name.strip():
            raise ValueError
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected NAME=VALUE with a number, got {text!r}"
        ) from None


def add_scenario_options(parser: argparse.ArgumentParser) -> None:
    """--speed, --freq, --amplitude, --flange/--no-flange and --param: the run's scenario.

    Shared by the verbs that build a System from a model file (see ``scenario_system``).
    """
    parser.add_argument("--speed", type=float, metavar="V", help="forward speed, m/s (default 55)")
    parser.add_argument(
        "--freq", type=float, metavar="F", help="excitation frequency, Hz (default 3)"
    )
    parser.add_argument(
        "--amplitude",
        type=float,
        metavar="A",
        help="excitation amplitude as a lateral track displacement, m (force k_y*A; default "
        "0.040; 0 gives the free response)",
    )
    parser.add_argument(
        "--flange",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="switch the piecewise-linear terms (the wheelset: flange force F_t, switch S1) on "
        "or off; default: as the model file says, which for the wheelset is ON (the paper's "
        "Fig. 4/6 are about the flange)",
    )
    parser.add_argument(
        "--param",
        type=parameter_assignment,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="set any model parameter in its SI unit (repeatable), e.g. --param eta=0.01",
    )


def scenario_system(args: argparse.Namespace, with_model: bool = False):
    """The System of ``--model``/``--coeffs`` and the scenario options.

    ``--y0`` (where the verb has it) sets the parameter the model's ``[options]`` table names
    for it, or else the first state's initial value. With ``with_model`` the loaded Model is
    returned too, as ``(model, system)``.
    """
    from circuitsim.mechanics import load_model

    model = load_model(args.model)
    parameters = model.option_parameters(
        {"speed": args.speed, "freq": args.freq, "amplitude": args.amplitude}
    )
    x0 = None
    y0 = getattr(args, "y0", None)
    if y0 is not None:
        if "y0" in model.options:
            parameters.update(model.option_parameters({"y0": y0}))
        else:
            x0 = {model.states[0]: y0}
    parameters.update(dict(args.param))
    nonlinear = None
    if args.flange is not None:
        nonlinear = {name: args.flange for name in model.nonlinear_terms}
    system = model.system(args.coeffs, parameters, nonlinear, x0)
    return (model, system) if with_model else system


def state_range(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    try:
        if not sep or not name.strip() or float(value) <= 0:
            raise ValueError
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected STATE=PEAK with a positive number, got {text!r}"
        ) from None


def read_netlist_reporting_warnings(path: str):
    """``read_netlist(path)``, its NetlistWarnings printed as ``warning:`` lines on stderr."""
    import warnings

    from circuitsim.netlist.reader import read_netlist

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        circuit = read_netlist(path)
    for warning in caught:
        print(f"warning: {warning.message}", file=sys.stderr)
    return circuit
