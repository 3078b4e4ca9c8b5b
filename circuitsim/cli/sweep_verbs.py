"""The sweep verb: one model parameter over many values, each variant's circuit simulated."""

from __future__ import annotations

import argparse
import os
import sys
from typing import TYPE_CHECKING, TextIO

from circuitsim.cli.circuit_verbs import TSTOP_HELP
from circuitsim.cli.common import (
    UsageError,
    add_jobs_option,
    add_model_options,
    add_ngspice_timeout,
    add_scenario_options,
    check_scenario_options,
    parameter_assignment,
    prepare_output_folder,
    print_warning,
    require_jobs,
    require_positive,
    scenario_system,
    with_inputs,
)

if TYPE_CHECKING:
    from circuitsim.mechanics.model import Model


def _sweep_param_item(text: str) -> tuple[str, float] | str:
    """``--param`` of the sweep verb: NAME=VALUE (a fixed parameter) or NAME (the swept one)."""
    if "=" in text:
        return parameter_assignment(text)
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a parameter name or NAME=VALUE")
    return text.strip()


def _add_sweep(sub: argparse._SubParsersAction) -> None:
    from circuitsim.compare.values import MAX_VALUES

    parser = sub.add_parser(
        "sweep",
        help="peak |y| against a parameter: many circuit variants, one run each",
        description=(
            "Sweep one model parameter (e.g. --param speed --values 40:70:0.5): the circuit is "
            "translated once (exact resistors, one amplitude scaling for all values) and only "
            "the parts the parameter sets change between variants (for the speed: R33 and "
            "R44). Each variant is its own run (builtin: the steps and values of simulating that "
            "variant's circuit alone, in threads; ngspice: one process per variant), --jobs at "
            "a time. Writes "
            "sweep.csv and sweep.png (peak |y| over the last --window seconds and over the "
            "whole run, critical speed marked). With --opamp tl074 every state node is probed "
            "and a warning names the values where one reached the op-amp's output swing (the "
            "scaling, set from the first, middle and last values, let it clip there). The "
            "scenario options are generate's: --amplitude 0 --y0 0.005 sweeps the free "
            "response from a push (growing above the critical speed, decaying below); --log "
            "draws the peaks on a log axis."
        ),
    )
    add_model_options(parser)
    add_scenario_options(parser)
    for action in parser._actions:  # --param also names the swept parameter (no '=')
        if action.dest == "param":
            action.type = _sweep_param_item
            action.metavar = "NAME[=VALUE]"
            action.help = (
                "NAME: the parameter to sweep (speed, freq, amplitude or any model parameter); "
                "NAME=VALUE: set a fixed parameter in its SI unit (repeatable; not the swept "
                "one, which --speed, --freq, --amplitude and --y0 must not set either)"
            )
    parser.add_argument(
        "--values",
        required=True,
        metavar="START:STOP:STEP",
        help="values of the swept parameter: START, START+STEP, ... up to STOP (included when "
        "on the grid; a STEP longer than STOP-START gives START alone), or a comma-separated "
        f"list; finite numbers, at most {MAX_VALUES:,} of them",
    )
    parser.add_argument(
        "--engine",
        choices=("builtin", "ngspice"),
        default="builtin",
        help="builtin (default: our MNA solver, each variant in a thread) or ngspice (one "
        "process per variant)",
    )
    add_ngspice_timeout(parser)
    parser.add_argument(
        "--opamp", choices=("ideal", "tl074"), default="ideal", help="op-amp model (default ideal)"
    )
    parser.add_argument(
        "--tstop",
        type=float,
        metavar="T",
        help=TSTOP_HELP,
    )
    parser.add_argument(
        "--window",
        type=float,
        metavar="T",
        help="late window, s (> 0 and at most the simulated time; default 1, or the simulated "
        "time if shorter)",
    )
    add_jobs_option(
        parser,
        "variants simulated at a time, at least 1 (builtin: threads, ngspice: processes; "
        f"default: the CPU count, {os.cpu_count() or 1} here)",
        os.cpu_count() or 1,
    )
    parser.add_argument(
        "--log",
        action="store_true",
        help="log y axis on sweep.png (peaks of 0 cannot be drawn there: they are left out "
        "of the figure with a warning; sweep.csv keeps every value)",
    )
    parser.add_argument(
        "--out",
        default=".",
        metavar="DIR",
        help="output folder, created (and checked) before the sweep runs (default .)",
    )
    parser.set_defaults(func=_run_sweep)


class _SweepBar:
    """The sweep's progress on stderr.

    On a terminal one bar, redrawn in place; elsewhere (a log file, a pipe) a plain line at the
    start and at every further tenth of the way. :meth:`close` ends a bar left open with a
    newline, so that what follows (a summary, an error message) starts on its own line.

    Parameters
    ----------
    stream : text stream, optional
        Where to write (default: ``sys.stderr`` at the time of each call).
    """

    width = 30

    def __init__(self, stream: TextIO | None = None) -> None:
        self._stream = stream
        self._open = False  # a bar without its newline is on the terminal
        self._tenths = -1  # the last tenth reported as a plain line

    @property
    def stream(self) -> TextIO:
        """The stream written to."""
        return self._stream or sys.stderr

    def _terminal(self) -> bool:
        isatty = getattr(self.stream, "isatty", None)
        return bool(isatty and isatty())

    def __call__(self, fraction: float, message: str) -> None:
        """Report ``fraction`` (0..1) of the sweep done, with a short ``message``."""
        fraction = max(0.0, min(1.0, fraction))
        if self._terminal():
            filled = int(round(self.width * fraction))
            bar = f"[{'#' * filled}{'.' * (self.width - filled)}]"
            text = f"\r{bar} {100 * fraction:5.1f}%  {message[:60]:60s}"
            print(text, end="", file=self.stream, flush=True)
            self._open = True
            return
        tenths = int(fraction * 10 + 1e-9)
        if tenths > self._tenths:
            self._tenths = tenths
            print(f"{100 * fraction:5.1f}%  {message}", file=self.stream, flush=True)

    def close(self) -> None:
        """End an open bar's line (nothing to do for plain lines)."""
        if self._open:
            print(file=self.stream, flush=True)
            self._open = False


def _plural(count: int, noun: str) -> str:
    return f"{count} {noun}" if count == 1 else f"{count} {noun}s"


def _swept_parameter(model: Model, swept: str) -> str:
    """The model parameter ``--param swept`` names: an option's (speed: V) or its own."""
    if swept in model.options:
        return model.options[swept]
    if swept in model.parameters:
        return swept
    options = ", ".join(model.options) or "none"
    raise UsageError(
        f"--param {swept}: model {model.name} has no parameter {swept!r}; "
        f"known: {', '.join(model.parameters)} (or the options {options})"
    )


def _refuse_fixed_swept(args: argparse.Namespace, model: Model, swept: str, name: str) -> None:
    """Refuse a --param NAME=VALUE, --speed, --freq, --amplitude or --y0 that fixes the
    parameter the sweep varies: its values would be silently overridden."""
    sources = [
        (f"--{option} {getattr(args, option):g}", model.options[option])
        for option in ("speed", "freq", "amplitude", "y0")
        if getattr(args, option) is not None and option in model.options
    ]
    fixed = [item for item in args.param if not isinstance(item, str)]
    sources += [(f"--param {parameter}={value:g}", parameter) for parameter, value in fixed]
    sweeps = f"--param {swept} sweeps" if swept == name else f"--param {swept} sweeps {name}"
    for source, parameter in sources:
        if parameter == name:
            raise UsageError(
                f"{source} fixes {name}, which {sweeps}: a parameter is either swept or fixed, "
                "drop one of the two"
            )


def _run_sweep(args: argparse.Namespace) -> int:
    from circuitsim.compare.errors import ComparisonError
    from circuitsim.compare.sweep import run_sweep, save_sweep
    from circuitsim.compare.values import parse_values
    from circuitsim.mechanics import critical_speed, load_model
    from circuitsim.synthesis.options import SynthesisOptions

    swept = [p for p in args.param if isinstance(p, str)]
    if len(swept) != 1:
        raise UsageError("name exactly one --param to sweep (a NAME without =VALUE)")
    require_jobs(args)
    require_positive("--tstop", args.tstop)
    require_positive("--window", args.window)
    require_positive("--ngspice-timeout", args.ngspice_timeout)
    check_scenario_options(args)
    try:
        values = parse_values(args.values)
    except ComparisonError as exc:  # a bad option value: exit code 2, not a failed run
        raise UsageError(str(exc)) from None
    model = with_inputs(args, load_model(args.model))
    name = _swept_parameter(model, swept[0])
    _refuse_fixed_swept(args, model, swept[0], name)
    fixed = [p for p in args.param if not isinstance(p, str)]
    systems = []
    for value in values:
        variant = argparse.Namespace(**vars(args))
        variant.param = [*fixed, (name, float(value))]
        systems.append(scenario_system(variant, model=model))
    middle = systems[len(systems) // 2]
    t_stop = args.tstop or float((middle.circuit_hints or {}).get("t_stop", 5.0))
    if args.window is not None and args.window > t_stop:
        given = "--tstop" if args.tstop else "the model's default"
        raise UsageError(
            f"--window {args.window:g} s is longer than the simulated time ({given}: {t_stop:g} s)"
        )
    window = min(1.0, t_stop) if args.window is None else args.window
    prepare_output_folder("--out", args.out, "sweep.csv", "sweep.png")
    options = SynthesisOptions(opamp=args.opamp, t_stop=args.tstop)
    unit = model.parameter_info[name].unit
    bar = _SweepBar()
    try:
        result = run_sweep(
            systems,
            values,
            name,
            unit,
            args.engine,
            options,
            window=window,
            workers=min(args.jobs, len(values)),  # more would only make idle threads
            progress=bar,
            ngspice_timeout=args.ngspice_timeout,
        )
    finally:
        bar.close()
    for warning in result.warnings:
        print_warning(warning)
    speed = model.options.get("speed")
    if name == speed:
        coefficients = args.coeffs or model.default_coefficients
        result.critical, _ = critical_speed(
            model, coefficients, parameter=name, parameters=dict(fixed) or None
        )
    paths = save_sweep(result, args.out, log=args.log)
    per = result.timings["simulation"] / len(values)
    kernels = result.timings.get("kernels")
    ready = "" if kernels is None else f", compiled kernels ready {kernels:.3g} s"
    print(
        f"{_plural(len(values), 'variant')} of {name} ({result.engine}; changed: "
        f"{', '.join(result.changed) or 'none'}): synthesis {result.timings['synthesis']:.3g} s"
        f"{ready}, simulation {result.timings['simulation']:.3g} s ({per:.3g} s per variant)"
    )
    if result.critical is not None:
        print(f"critical {name} (linear) {result.critical:.4f} {unit}")
    for path in paths:
        print(f"wrote {path}")
    return 0


COMMANDS = [_add_sweep]
