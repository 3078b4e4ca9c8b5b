"""The scenario options shared by the verbs that build a System from a model file: --model,
--coeffs, --speed, --freq, --amplitude, --y0, --state, --flange, --forcing, --param and
--input, their help texts (in the names and units of the model given with ``--help``), and
the System they describe."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING

from circuitsim.cli import common
from circuitsim.cli.common import require_finite

if TYPE_CHECKING:
    from circuitsim.mechanics.model import Model


def _coefficients_help() -> str:
    """Help of --coeffs: the sets of the model asked about, or the wheelset's."""
    model = common.HELP_MODEL
    if model is None:
        return (
            "coefficient set of the model; wheelset: paper (default, the paper's eq. 5), "
            "derived (Table 1 via eq. 4) or eq2 (eq. 2, with suspension damping)"
        )
    return (
        f"coefficient set of {model.name}: {', '.join(model.coefficient_sets)} (default "
        f"{model.default_coefficients})"
    )


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
        help=_coefficients_help(),
    )


def parameter_assignment(text: str) -> tuple[str, float]:
    """``--param NAME=VALUE``: the name and a finite number.

    Raises
    ------
    argparse.ArgumentTypeError
        No ``=``, no name, or a value that is not a finite number.
    """
    name, sep, value = text.partition("=")
    try:
        if not sep or not name.strip() or not math.isfinite(float(value)):
            raise ValueError
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected NAME=VALUE with a finite number, got {text!r}"
        ) from None


_SCENARIO_WHEELSET = {
    "speed": "forward speed V, m/s; default 55",
    "freq": "excitation frequency f, Hz; default 3",
    "amplitude": "lateral track displacement a, m; default 0.040; 0 gives the free response",
    "y0": "initial lateral displacement y0, m; default 0",
}


def scenario_help(option: str) -> str:
    """Help text of a scenario option (``speed``, ``freq``, ``amplitude``, ``y0``).

    With :data:`~circuitsim.cli.common.HELP_MODEL` set: the parameter the model's
    ``[options]`` table maps the option to, its description, unit and default. Without: what
    the option does for any model, the wheelset's meaning as the example.
    """
    model = common.HELP_MODEL
    if model is None:
        first = "else --state's (default the first state's), " if option == "y0" else ""
        return (
            f"sets the parameter the model's [options] table maps {option!r} to, in its unit "
            f"({first}the built-in wheelset: {_SCENARIO_WHEELSET[option]})"
        )
    if option in model.options:
        info = model.parameter_info[model.options[option]]
        about = ", ".join(part for part in (info.description, info.unit) if part)
        about = f"{about}; " if about else ""
        return f"sets {info.name} of {model.name} ({about}default {info.value:g})"
    if option == "y0":
        state = model.default_state
        unit = model.units[model.states.index(state)] or "1"
        return (
            f"initial value of --state (default {state}), {unit} (default: the model's [initial])"
        )
    mapped = ", ".join(model.options) or "none"
    return f"not used by {model.name} (its [options] maps: {mapped}); use --param NAME=VALUE"


def _switch_help() -> str:
    """Help of --flange/--no-flange: the model's piecewise-linear terms by name."""
    model = common.HELP_MODEL
    if model is None:
        return (
            "switch all the model's piecewise-linear terms on or off; default: as the model "
            "file says (the built-in wheelset: its flange force F_t, switch S1, on)"
        )
    terms = ", ".join(
        f"{name} ({'on' if on else 'off'})" for name, on in model.nonlinear_terms.items()
    )
    return (
        f"switch all the piecewise-linear terms of {model.name} on or off; default as the "
        f"file says: {terms or 'it has none'}"
    )


def _forcing_help() -> str:
    """Help of --forcing: the model's forcing groups by name, when there is a model."""
    model = common.HELP_MODEL
    if model is None:
        return (
            "switch on only this forcing group of the model (repeatable), the others off; "
            "default: as the model file says (the built-in wheelset: track on; --forcing "
            "irregularity runs its random track profile instead)"
        )
    groups = ", ".join(f"{name} ({'on' if on else 'off'})" for name, on in
                       model.forcing_terms.items())  # fmt: skip
    return (
        f"switch on only this forcing group of {model.name} (repeatable), the others off; "
        f"default as the file says: {groups or 'it has none'}"
    )


def _parameter_help() -> str:
    """Help of --param: the parameters of the model asked about, with units, when there is one."""
    model = common.HELP_MODEL
    if model is None:
        return "set any model parameter in its unit (repeatable), e.g. --param eta=0.01"
    known = ", ".join(
        f"{p.name} ({p.unit})" if p.unit else p.name for p in model.parameter_info.values()
    )
    return f"set a parameter of {model.name} in its unit (repeatable): {known or 'none'}"


def add_scenario_options(parser: argparse.ArgumentParser) -> None:
    """--speed, --freq, --amplitude, --y0, --flange/--no-flange, --forcing and --param: the
    run's scenario.

    Shared by the verbs that build a System from a model file (see ``scenario_system``):
    ode, generate, compare and sweep take the same scenario with the same names.
    """
    parser.add_argument("--speed", type=float, metavar="V", help=scenario_help("speed"))
    parser.add_argument("--freq", type=float, metavar="F", help=scenario_help("freq"))
    parser.add_argument("--amplitude", type=float, metavar="A", help=scenario_help("amplitude"))
    parser.add_argument("--y0", type=float, metavar="Y", help=scenario_help("y0"))
    parser.add_argument(
        "--state",
        metavar="NAME",
        help="the state --y0 starts away from rest (when the model's [options] table maps no "
        "y0) and that hunting, sweep, tolerance and ode's phase portrait measure and plot "
        "(default: the model's [options] state, else the first state)",
    )
    parser.add_argument(
        "--flange", action=argparse.BooleanOptionalAction, default=None, help=_switch_help()
    )
    parser.add_argument(
        "--forcing",
        action="append",
        metavar="NAME",
        help=_forcing_help(),
    )
    parser.add_argument(
        "--param",
        type=parameter_assignment,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help=_parameter_help(),
    )
    parser.add_argument(
        "--input",
        type=input_assignment,
        action="append",
        default=[],
        metavar="NAME=FILE.csv",
        help="replace forcing group NAME's input by the time series of a CSV file (two "
        "columns: time in s, value in the group's unit; one header line and # comments "
        "allowed; linear interpolation) and switch the group on (repeatable; docs/model.md)",
    )


def input_assignment(text: str) -> tuple[str, str]:
    """``--input NAME=FILE.csv``: the forcing group's name and the file name.

    Raises
    ------
    argparse.ArgumentTypeError
        No ``=``, no name or no file.
    """
    name, sep, path = text.partition("=")
    if not sep or not name.strip() or not path.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=FILE.csv, got {text!r}")
    return name.strip(), path.strip()


def with_inputs(args: argparse.Namespace, model: Model) -> Model:
    """``model`` with the ``--input NAME=FILE.csv`` time series of ``args`` in place.

    Raises
    ------
    ModelError
        An unknown group or a bad file (naming it and the line).
    """
    for name, path in getattr(args, "input", None) or ():
        model = model.with_input_file(name, path)
    return model


def check_scenario_options(args: argparse.Namespace) -> None:
    """Refuse non-finite ``--speed``, ``--freq``, ``--amplitude`` and ``--y0`` values.

    Raises
    ------
    UsageError
        Naming the option.
    """
    for option in ("speed", "freq", "amplitude", "y0"):
        require_finite(f"--{option}", getattr(args, option, None))


def scenario_system(args: argparse.Namespace, with_model: bool = False, model: Model | None = None):
    """The System of ``--model``/``--coeffs`` and the scenario options.

    ``--y0`` sets the parameter the model's ``[options]`` table names
    for it, or else the initial value of ``--state`` (default: the model's ``[options]
    state``, else the first state). With ``with_model`` the loaded Model is
    returned too, as ``(model, system)``, with its ``--input`` series. ``model``, when given,
    is used instead of loading ``--model`` again (a sweep builds many systems of one model;
    it applies ``--input`` with :func:`with_inputs` itself).

    Raises
    ------
    UsageError
        A non-finite scenario option (see :func:`check_scenario_options`).
    ModelError
        The model file, or a parameter it does not know.
    """
    from circuitsim.mechanics import load_model

    check_scenario_options(args)
    model = with_inputs(args, load_model(args.model)) if model is None else model
    parameters = model.option_parameters(
        {"speed": args.speed, "freq": args.freq, "amplitude": args.amplitude}
    )
    x0 = None
    y0 = getattr(args, "y0", None)
    if y0 is not None:
        if "y0" in model.options:
            parameters.update(model.option_parameters({"y0": y0}))
        else:
            x0 = {model.state_named(getattr(args, "state", None)): y0}
    parameters.update(dict(args.param))
    nonlinear = None
    if args.flange is not None:
        nonlinear = {name: args.flange for name in model.nonlinear_terms}
    forcing = None
    if getattr(args, "forcing", None):
        forcing = {name: False for name in model.forcing_terms}
        forcing.update({name: True for name in args.forcing})  # an unknown name: ModelError
    system = model.system(args.coeffs, parameters, nonlinear, x0, forcing=forcing)
    return (model, system) if with_model else system
