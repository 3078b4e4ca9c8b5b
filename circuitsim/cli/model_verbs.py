"""Verbs of the ODE side: ``stability`` and ``ode``."""

from __future__ import annotations

import argparse
import math

from circuitsim.cli.common import (
    MAX_STEP_COUNT,
    UsageError,
    add_figure_options,
    add_max_step,
    plot_target,
    require_count,
    require_figure_options,
    require_figure_path,
    require_finite,
    require_fraction,
    require_positive,
    require_writable,
)
from circuitsim.cli.scenario_options import (
    add_model_options,
    add_scenario_options,
    check_scenario_options,
    parameter_assignment,
    scenario_system,
)

MAX_CSV_ROWS = 10_000_000
"""Most rows ``ode --csv`` writes (``--tstop`` / ``--dt`` + 1): about a gigabyte of text."""

DEFAULT_T_STOP = 5.0
"""End time of ``ode`` when neither ``--tstop`` nor the model's ``[circuit] t_stop`` is given."""


def _add_stability(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "stability",
        help="critical speed, hunting frequency and eigenvalues of the linear part",
        description=(
            "Linear stability of the model without its piecewise-linear terms (the flange): "
            "the critical speed is where the largest real part of the state matrix's "
            "eigenvalues crosses zero (brentq), the hunting frequency is |Im|/(2 pi) there. "
            "The wheelset's paper set gives 55.6455 m/s and 8.477 Hz."
        ),
    )
    add_model_options(parser)
    parser.add_argument(
        "--speed",
        type=float,
        metavar="V",
        help="speed (m/s) at which to list the eigenvalues (1/s); default: the model's "
        "default (wheelset: 55 m/s)",
    )
    parser.add_argument(
        "--bracket",
        type=float,
        nargs=2,
        metavar=("LO", "HI"),
        default=(1.0, 1000.0),
        help="speed interval (m/s) searched for the loss of stability, finite with LO < HI "
        "(default: 1 1000)",
    )
    parser.add_argument(
        "--parameter",
        metavar="NAME",
        help="parameter to sweep instead of the speed (for user models; --speed and --bracket "
        "are then in its unit); default: the model's [options] speed (wheelset: V)",
    )
    parser.add_argument(
        "--eigenvalues",
        action="store_true",
        help="only list the linear part's eigenvalues (1/s) with damping ratio and natural "
        "and damped frequencies (Hz) at the parameters given (--param, --speed); any model, "
        "no speed parameter or critical-value search needed",
    )
    parser.add_argument(
        "--param",
        type=parameter_assignment,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="set a model parameter in its unit (repeatable)",
    )
    parser.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object: critical_speed (m/s), hunting_frequency (Hz), speed "
        "(m/s), eigenvalues ([re, im] pairs, 1/s), coefficients (the set's name); with "
        "--eigenvalues: parameters and modes (eigenvalue [re, im], damping_ratio, "
        "natural_frequency and damped_frequency in Hz)",
    )
    parser.set_defaults(func=_run_stability)


def _check_stability(args: argparse.Namespace) -> None:
    """Refuse a non-finite --speed and a --bracket that is not finite and increasing."""
    require_finite("--speed", args.speed)
    lo, hi = args.bracket
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise UsageError(f"--bracket LO HI must be finite numbers with LO < HI, got {lo:g} {hi:g}")


def _run_stability(args: argparse.Namespace) -> int:
    import json

    from circuitsim.mechanics import critical_speed, eigenvalues, load_model

    _check_stability(args)
    model = load_model(args.model)
    if args.eigenvalues:
        return _print_modes(args, model)
    if args.parameter:
        speed_parameter = args.parameter
        if speed_parameter not in model.parameters:
            # eigenvalues() raises the ModelError naming the file and the known parameters
            eigenvalues(model, speed_parameter, [0.0])
    elif "speed" not in model.options:
        raise UsageError(
            f"model {model.name} has no parameter for --speed (no [options] speed): name the "
            "parameter to search with --parameter NAME, or list the modes at given "
            "parameters with --eigenvalues"
        )
    else:
        speed_parameter = model.options["speed"]
    speed = model.parameters[speed_parameter] if args.speed is None else args.speed
    coefficients = args.coeffs or model.default_coefficients
    fixed = dict(args.param) or None
    value, frequency = critical_speed(
        model, coefficients, parameter=speed_parameter, bracket=tuple(args.bracket),
        parameters=fixed,
    )  # fmt: skip
    lam = eigenvalues(model, speed_parameter, [speed], coefficients, fixed)[0]
    if args.json:
        report = {
            "model": model.name,
            "coefficients": coefficients,
            "critical_speed": value,
            "hunting_frequency": frequency,
            "speed": speed,
            "eigenvalues": [[float(v.real), float(v.imag)] for v in lam],
        }
        print(json.dumps(report))
        return 0
    print(f"model {model.name}, coefficient set {coefficients}")
    unit = model.parameter_info[speed_parameter].unit
    label = f"critical {speed_parameter}" if args.parameter else "critical speed"
    rate, hertz = _time_units(model)
    print(f"{label:18s} {value:.4f} {unit}")
    print(f"hunting frequency  {frequency:.4f} {hertz}")
    print(f"eigenvalues at {speed_parameter} = {speed:g} {unit} ({rate}):")
    for v in lam:
        print(f"  {v.real:+.6g} {v.imag:+.6g}j")
    return 0


def _time_units(model) -> tuple[str, str]:
    """The units of an eigenvalue and of a frequency in the model's time: ``("1/s", "Hz")``;
    a dimensionless time: ``("per unit time", "cycles per unit time")``."""
    time_unit = getattr(model, "time_unit", "s")
    if time_unit == "s":
        return "1/s", "Hz"
    if not time_unit:
        return "per unit time", "cycles per unit time"
    return f"1/{time_unit}", f"cycles per {time_unit}"


def _print_modes(args: argparse.Namespace, model) -> int:
    """``stability --eigenvalues``: the modes at the parameters given, as a table or JSON."""
    import json

    from circuitsim.mechanics.stability import modes

    parameters = dict(args.param)
    if args.speed is not None:
        parameters.update(model.option_parameters({"speed": args.speed}))
    coefficients = args.coeffs or model.default_coefficients
    found = modes(model, coefficients, parameters)
    values = model.environment(coefficients, parameters)[1]
    rate, hertz = _time_units(model)
    if args.json:
        report = {
            "model": model.name,
            "coefficients": coefficients,
            "parameters": values,
            "modes": [
                {
                    "eigenvalue": [m.eigenvalue.real, m.eigenvalue.imag],
                    "damping_ratio": None if math.isnan(m.damping_ratio) else m.damping_ratio,
                    "natural_frequency": m.natural_frequency,
                    "damped_frequency": m.damped_frequency,
                }
                for m in found
            ],
        }
        print(json.dumps(report))
        return 0
    given = ", ".join(f"{k}={v:g}" for k, v in parameters.items()) or "the model's defaults"
    print(f"model {model.name}, coefficient set {coefficients}, at {given}")
    print(f"{'eigenvalue (' + rate + ')':>32s}  {'damping':>9s}  {'natural':>11s}  "
          f"{'damped':>11s}  ({hertz})")  # fmt: skip
    for m in found:
        value = f"{m.eigenvalue.real:+.6g} {m.eigenvalue.imag:+.6g}j"
        print(
            f"{value:>32s}  {m.damping_ratio:9.4g}  {m.natural_frequency:11.5g}  "
            f"{m.damped_frequency:11.5g}{'' if m.stable else '  unstable'}"
        )
    return 0


def _add_ode(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "ode",
        help="solve the model's ODE directly (scipy DOP853, restarted at every kink)",
        description=(
            "Direct solution of the model (default: the wheelset, paper coefficients, V = 55 m/s, "
            "a = 0.040 m, f = 3 Hz, zero initial state, 0-5 s, flange on). Prints max |.| and "
            "the final value of every state (SI units); writes a CSV and a figure on request. "
            "For a user model, --speed/--freq/--amplitude/--y0 set the parameters its [options] "
            "table names (--y0 sets the first state if it names none); --param sets any."
        ),
    )
    add_model_options(parser)
    add_scenario_options(parser)
    parser.add_argument(
        "--tstop",
        type=float,
        metavar="T",
        help="end time in the model's time unit (> 0; default: the model file's [circuit] "
        "t_stop, else 5)",
    )
    # defaults: those of mechanics.limits (not imported here: it loads scipy; a test checks)
    parser.add_argument(
        "--max-steps",
        type=int,
        metavar="N",
        help="stop with an error after N integrator steps, at least 1 (default 500,000)",
    )
    parser.add_argument(
        "--max-wall-time",
        type=float,
        metavar="SECONDS",
        help="stop with an error after this much wall time, > 0 (default 300 s)",
    )
    add_max_step(parser)
    parser.add_argument(
        "--rtol",
        type=float,
        default=1e-10,
        help="relative tolerance of the integrator, between 0 and 1 (default 1e-10; absolute "
        "1e-12)",
    )
    parser.add_argument(
        "--dt",
        type=float,
        default=5e-4,
        help="sample step of the CSV in the model's time unit (> 0, at most 10 million rows; "
        "default 0.0005; dense output, exact to the tolerance)",
    )
    parser.add_argument("--csv", metavar="FILE", help=_csv_help())
    parser.add_argument(
        "--plot",
        metavar="FILE",
        help="write a figure in the format of its suffix (.png, .pdf, .svg ...): every state "
        "against time, one panel per unit, and the phase portrait of --state's coordinate "
        "(default: the model's [options] state, else the first) of a second-order model",
    )
    add_figure_options(parser, "the --plot figure")
    parser.set_defaults(func=_run_ode)


def _csv_help() -> str:
    """Help of ``ode --csv``: the header and units of the model asked about, or the wheelset's."""
    from circuitsim.cli import common

    model = common.HELP_MODEL
    if model is None:
        return (
            "write time and every state in the model's units (the wheelset: header "
            "time,y,psi,y_dot,psi_dot; s, m, rad, m/s, rad/s)"
        )
    units = ", ".join([model.time_unit or "1"] + [u or "1" for u in model.units])
    return f"write time and every state: header time,{','.join(model.states)}; units {units}"


def _check_ode(args: argparse.Namespace) -> None:
    """Refuse bad times, tolerance, limits and figure suffix."""
    check_scenario_options(args)
    require_positive("--tstop", args.tstop)
    require_positive("--dt", args.dt)
    require_fraction("--rtol", args.rtol)
    require_count("--max-steps", args.max_steps, MAX_STEP_COUNT)
    require_positive("--max-wall-time", args.max_wall_time)
    require_positive("--max-step", args.max_step)
    require_figure_path("--plot", args.plot)
    require_figure_options(args)
    args.plot = plot_target("--plot", args.plot, args)
    require_writable(args.csv, args.plot)


def _check_csv_rows(args: argparse.Namespace, t_stop: float) -> None:
    """Refuse a CSV of more than MAX_CSV_ROWS rows (``t_stop`` may come from the model)."""
    rows = t_stop / args.dt + 1
    if args.csv and rows > MAX_CSV_ROWS:
        raise UsageError(
            f"--dt {args.dt:g} with --tstop {t_stop:g} gives {rows:.3g} CSV rows, more than "
            f"{MAX_CSV_ROWS:,}: use a larger --dt"
        )


def _run_ode(args: argparse.Namespace) -> int:
    import numpy as np

    from circuitsim.atomic import write_text_atomic
    from circuitsim.mechanics import solve
    from circuitsim.mechanics.shapes import fit_summaries

    _check_ode(args)
    model, system = scenario_system(args, with_model=True)
    t_stop = args.tstop or float(model.circuit.get("t_stop", DEFAULT_T_STOP))
    _check_csv_rows(args, t_stop)
    limits = {
        "max_steps": args.max_steps,
        "max_wall_time": args.max_wall_time,
        "max_step": args.max_step,
    }
    limits = {name: value for name, value in limits.items() if value is not None}
    result = solve(system, t_span=(0.0, t_stop), rtol=args.rtol, atol=1e-12, **limits)
    if args.csv:
        samples = int(np.floor(t_stop / args.dt + 1e-9)) + 1
        grid = np.linspace(0.0, (samples - 1) * args.dt, samples)
        if grid[-1] < t_stop:
            grid = np.append(grid, t_stop)
        write_text_atomic(args.csv, result.csv_text(grid))
    if args.plot:
        from circuitsim.compare.figures import plot_states

        shown = {
            name: system.parameters[name]
            for option, name in model.options.items()
            if option != "state"  # the only option that names a state, not a parameter
        }
        shown.update(dict(args.param))
        settings = ", ".join([system.coefficient_set] + [f"{k}={v:g}" for k, v in shown.items()])
        title = f"{model.name} ({settings})"
        plot_states(
            args.plot, result, title=title, time_unit=model.time_unit,
            state=model.state_named(args.state), dpi=args.dpi,
        )  # fmt: skip
    terms = ", ".join(term.name for term in system.nonlinear) or "none"
    print(f"model {model.name}, coefficient set {system.coefficient_set}, nonlinear: {terms}")
    for line in fit_summaries(system):
        print(line)
    when = f"{t_stop:g} {model.time_unit}".rstrip()  # a dimensionless time has no unit
    print(f"0 to {when}, {len(result.t)} steps, {len(result.kinks)} kink crossings")
    final = result.sol(t_stop)
    for i, (name, unit) in enumerate(zip(result.states, result.units, strict=True)):
        peak = result.max_abs(name)
        print(f"  {name:10s} max |.| {peak:.6g} {unit:6s} at {when}: {final[i]:+.6g}")
    if args.csv:
        print(f"wrote {args.csv}")
    if args.plot:
        print(f"wrote {args.plot}")
    return 0


COMMANDS = [_add_stability, _add_ode]
