"""Options of the translator shared by generate, compare, tolerance, hunting and bench: the
state ranges and time scale, the op-amp model, E-series and pair tolerance, and the speed knob
(a fixed part plus a potentiometer over a parameter range)."""

from __future__ import annotations

import argparse
import functools
import math

from circuitsim.cli.common import UsageError, require_positive
from circuitsim.cli.scenario_options import scenario_system


def state_range(text: str) -> tuple[str, float]:
    """``--range STATE=PEAK``: the state's name and a positive finite peak.

    Raises
    ------
    argparse.ArgumentTypeError
        No ``=``, no name, or a peak that is not a positive finite number.
    """
    name, sep, value = text.partition("=")
    try:
        if not sep or not name.strip() or not (math.isfinite(float(value)) and float(value) > 0):
            raise ValueError
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected STATE=PEAK with a positive finite number, got {text!r}"
        ) from None


def add_time_scale(parser: argparse.ArgumentParser) -> None:
    """``--time-scale K``: how fast the circuit runs against the model."""
    parser.add_argument(
        "--time-scale",
        type=float,
        metavar="K",
        help="one model second takes 1/K circuit seconds (K > 0; default: the model file's "
        "[circuit] time_scale, else 1, real time)",
    )


def add_opamp_options(parser: argparse.ArgumentParser) -> None:
    """--opamp, --opamp-lib FILE and --opamp-subckt NAME (read with :func:`opamp_fields`)."""
    parser.add_argument(
        "--opamp", choices=("ideal", "tl074"), default=None, help="op-amp model (default ideal)"
    )
    parser.add_argument(
        "--opamp-lib",
        metavar="FILE",
        help="use an op-amp subcircuit from this SPICE library file instead of the built-in "
        "models (with --opamp-subckt; pins in+ in- V+ V- out, checked on loading; "
        "docs/parts.md)",
    )
    parser.add_argument(
        "--opamp-subckt", metavar="NAME", help="the op-amp subcircuit of --opamp-lib"
    )


def opamp_fields(args: argparse.Namespace) -> dict:
    """``SynthesisOptions`` fields of :func:`add_opamp_options`' options; ``args.opamp`` is
    set to the kind (``"lib"`` for a library op-amp).

    Raises
    ------
    UsageError
        Only one of --opamp-lib and --opamp-subckt, or --opamp with --opamp-lib.
    """
    if (args.opamp_lib is None) != (args.opamp_subckt is None):
        raise UsageError("--opamp-lib FILE and --opamp-subckt NAME go together")
    if args.opamp_lib is None:
        args.opamp = args.opamp or "ideal"
        return {"opamp": args.opamp}
    if args.opamp is not None:
        raise UsageError(f"--opamp {args.opamp} and --opamp-lib: choose one op-amp model")
    args.opamp = "lib"
    return {"opamp": "lib", "opamp_lib": args.opamp_lib, "opamp_subckt": args.opamp_subckt}


def add_translator_options(parser: argparse.ArgumentParser, series: str = "E96") -> None:
    """The translator's options (generate, bench): --opamp (and --opamp-lib, --opamp-subckt),
    --nonlinear, --scaling, --swing, --range, --time-scale, --series (default ``series``) and
    --pair-tolerance."""
    add_opamp_options(parser)
    parser.add_argument(
        "--nonlinear",
        choices=("abs", "deadzone"),
        default="abs",
        help="piecewise-linear terms from |x| blocks (the paper's form, default) or one "
        "dead-zone block",
    )
    parser.add_argument(
        "--scaling",
        choices=("auto", "unity"),
        default="auto",
        help="auto: volts per unit from the direct solution's peaks to --swing (default); "
        "unity: 1 V per SI unit (the paper's mapping)",
    )
    parser.add_argument(
        "--swing", type=float, default=5.0, metavar="VOLTS", help="target peak, V (> 0; default 5)"
    )
    parser.add_argument(
        "--range",
        type=state_range,
        action="append",
        default=[],
        metavar="STATE=PEAK",
        help="expected peak of a state in SI units, instead of the direct solution's (repeatable)",
    )
    add_time_scale(parser)
    parser.add_argument(
        "--series",
        choices=("E96", "E24", "exact"),
        default=series,
        help=f"resistor values (default {series})",
    )
    parser.add_argument(
        "--pair-tolerance",
        type=float,
        default=1e-3,
        metavar="REL",
        help="a coefficient resistor that one standard value misses by more than REL becomes "
        "two in series, R33 -> R33A + R33B (default 0.001; inf: never a pair)",
    )


def check_translator_options(args: argparse.Namespace) -> None:
    """Refuse a non-positive or non-finite --swing or --time-scale.

    Raises
    ------
    UsageError
        Naming the option.
    """
    require_positive("--swing", args.swing)
    require_positive("--time-scale", args.time_scale)


def translator_options(args: argparse.Namespace):
    """The SynthesisOptions of :func:`add_translator_options`' options (and ``--tstop``,
    when the verb has it)."""
    from circuitsim.synthesis.options import SynthesisOptions

    return SynthesisOptions(
        **opamp_fields(args),
        nonlinear=args.nonlinear,
        scaling=args.scaling,
        swing=args.swing,
        time_scale=args.time_scale,
        series=args.series,
        pair_tolerance=args.pair_tolerance,
        t_stop=getattr(args, "tstop", None),
        ranges=dict(args.range),
    )


def add_knob_options(parser: argparse.ArgumentParser) -> None:
    """``--speed-range LO:HI``, ``--knob PARAM``, ``--pot-series``: the speed knob as fixed
    resistors plus potentiometers (generate, bench)."""
    knob = parser.add_argument_group(
        "speed knob",
        "the resistors that follow a parameter (the wheelset's speed V: R33, R44) as a fixed "
        "resistor plus a potentiometer (generate: with a dial table in FILE.knob.csv)",
    )
    knob.add_argument(
        "--speed-range",
        type=value_range,
        nargs="?",
        const=(40.0, 70.0),
        metavar="LO:HI",
        help="turn the knob on over LO:HI (parameter units; alone: 40:70)",
    )
    knob.add_argument(
        "--knob",
        metavar="PARAM",
        help="the parameter the knob turns (default: the model's speed option, V)",
    )
    knob.add_argument(
        "--pot-series",
        choices=("E3", "E6"),
        default="E6",
        help="potentiometer values (default E6)",
    )


def value_range(text: str) -> tuple[float, float]:
    """``LO:HI``: two positive finite numbers, LO below HI."""
    low, sep, high = text.partition(":")
    try:
        pair = (float(low), float(high))
        if not sep or not all(math.isfinite(v) and v > 0 for v in pair) or pair[0] >= pair[1]:
            raise ValueError
        return pair
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected LO:HI with positive numbers, LO below HI, got {text!r}"
        ) from None


def knob_request(args: argparse.Namespace, model):
    """The KnobRequest of ``--speed-range``/``--knob``/``--pot-series``, None without them.

    Raises
    ------
    UsageError
        ``--knob`` without a range, or a parameter the model does not have.
    """
    from circuitsim.synthesis.knob import KnobRequest

    if args.speed_range is None:
        if args.knob is not None:
            raise UsageError("--knob needs --speed-range LO:HI (the range the dial covers)")
        return None
    name = args.knob or model.options.get("speed")
    if name is None:
        raise UsageError(
            f"--speed-range: model {model.name} has no speed option; name the parameter with "
            f"--knob (one of {', '.join(model.parameters)})"
        )
    if name in model.options:
        name = model.options[name]
    if name not in model.parameters:
        raise UsageError(
            f"--knob {name}: model {model.name} has no such parameter; known: "
            f"{', '.join(model.parameters)}"
        )

    @functools.cache
    def linear_part(value: float):
        variant = argparse.Namespace(**vars(args))
        variant.param = [*args.param, (name, float(value))]  # overrides --speed
        return scenario_system(variant, model=model).A

    low, high = args.speed_range
    unit = model.parameter_info[name].unit
    return KnobRequest(name, low, high, linear_part, unit, args.pot_series)
