"""The sweep verb: model parameters over many values (one, a full grid of several, or sets from
a CSV file), each variant's circuit simulated, in-process or on a Dask cluster."""

from __future__ import annotations

import argparse
import os
import sys
from typing import TYPE_CHECKING, TextIO

from circuitsim.cli.circuit_verbs import TSTOP_HELP
from circuitsim.cli.common import (
    KERNEL_WORDS,
    UsageError,
    add_figure_options,
    add_jobs_option,
    add_ngspice_timeout,
    figure_format,
    prepare_output_folder,
    print_warning,
    require_figure_options,
    require_jobs,
    require_positive,
)
from circuitsim.cli.scenario_options import (
    add_model_options,
    add_scenario_options,
    check_scenario_options,
    parameter_assignment,
    scenario_system,
    with_inputs,
)
from circuitsim.cli.study_options import (
    add_scheduler_options,
    check_scheduler_options,
    critical_curve,
    executor_for,
    parameter_of,
    report_grid,
    swept_grid,
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
            "Sweep model parameters (e.g. --param speed --values 40:70:0.5; several --param "
            "NAME --values pairs make the full grid of their values, --grid FILE.csv lists "
            "parameter sets): the circuit is translated once (exact resistors, one amplitude "
            "scaling for all variants) and only the parts the parameters set change between "
            "variants (for the speed: R33 and R44). Each variant is its own run (builtin: the "
            "steps and values of simulating that variant's circuit alone, in threads, or in "
            "batches on a Dask cluster with --scheduler; ngspice: one process per variant), "
            "--jobs at a time. One parameter: writes sweep.csv and sweep.png (peak |y| over "
            "the last --window seconds and over the whole run, critical speed marked); a grid: "
            "sweep.csv with one row per variant and metric and, for two parameters, the map "
            "sweep.png (with the linear critical speed when the speed is one of them). With "
            "--opamp tl074 every state node is probed and a warning names the variants where "
            "one reached the op-amp's output swing (the scaling, set from the first, middle "
            "and last variants, let it clip there). The scenario options are generate's: "
            "--amplitude 0 --y0 0.005 sweeps the free response from a push (growing above the "
            "critical speed, decaying below); --log draws the peaks on a log axis."
        ),
    )
    add_model_options(parser)
    add_scenario_options(parser)
    for action in parser._actions:  # --param also names the swept parameter (no '=')
        if action.dest == "param":
            action.type = _sweep_param_item
            action.metavar = "NAME[=VALUE]"
            action.help = (
                "NAME: a parameter to sweep (speed, freq, amplitude or any model parameter; "
                "each followed by its --values; several make a grid); NAME=VALUE: set a fixed "
                "parameter in its SI unit (repeatable; not a swept one, which --speed, --freq, "
                "--amplitude and --y0 must not set either)"
            )
    parser.add_argument(
        "--values",
        action="append",
        default=[],
        metavar="START:STOP:STEP",
        help="values of a swept parameter, one --values per --param NAME, in the same order "
        "(several: the full grid of their products): START, START+STEP, ... up to STOP "
        "(included when on the grid; a STEP longer than STOP-START gives START alone), or a "
        f"comma-separated list; finite numbers, at most {MAX_VALUES:,} variants in all",
    )
    parser.add_argument(
        "--grid",
        metavar="FILE.csv",
        help="parameter sets instead of --param NAME --values: a header of parameter names "
        "(model parameters or options such as speed; 'V (m/s)' checks the unit) and one row "
        "of SI values per variant ('#' comments and blank lines skipped)",
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
    add_scheduler_options(parser)
    parser.add_argument(
        "--log",
        action="store_true",
        help="log y axis on sweep.png (peaks of 0 cannot be drawn there: they are left out "
        "of the figure with a warning; sweep.csv keeps every value); a map's log colour scale",
    )
    parser.add_argument(
        "--out",
        default=".",
        metavar="DIR",
        help="output folder, created (and checked) before the sweep runs (default .)",
    )
    add_figure_options(parser, "sweep.png")
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


def _refuse_fixed_swept(args: argparse.Namespace, model: Model, names: list[str]) -> None:
    """Refuse a --param NAME=VALUE, --speed, --freq, --amplitude or --y0 that fixes a
    parameter the sweep varies: its values would be silently overridden."""
    sources = [
        (f"--{option} {getattr(args, option):g}", model.options[option])
        for option in ("speed", "freq", "amplitude", "y0")
        if getattr(args, option) is not None and option in model.options
    ]
    fixed = [item for item in args.param if not isinstance(item, str)]
    sources += [(f"--param {parameter}={value:g}", parameter) for parameter, value in fixed]
    swept = {parameter_of(model, s): s for s in args.param if isinstance(s, str)}
    for source, parameter in sources:
        if parameter in names:
            label = swept.get(parameter)
            if label is None:
                sweeps = f"--grid {args.grid} sweeps {parameter}"
            elif label == parameter:
                sweeps = f"--param {label} sweeps"
            else:
                sweeps = f"--param {label} sweeps {parameter}"
            raise UsageError(
                f"{source} fixes {parameter}, which {sweeps}: a parameter is either swept or "
                "fixed, drop one of the two"
            )


def _variant_systems(args: argparse.Namespace, model: Model, grid) -> list:
    """Each variant's System: the scenario options with the grid's values set."""
    fixed = [p for p in args.param if not isinstance(p, str)]
    systems = []
    for k in range(len(grid)):
        variant = argparse.Namespace(**vars(args))
        variant.param = [*fixed, *grid.assignments(k)]
        systems.append(scenario_system(variant, model=model))
    return systems


def _run_sweep(args: argparse.Namespace) -> int:
    from circuitsim.mechanics import critical_speed, load_model
    from circuitsim.synthesis.options import SynthesisOptions

    require_jobs(args)
    require_positive("--tstop", args.tstop)
    require_positive("--window", args.window)
    require_positive("--ngspice-timeout", args.ngspice_timeout)
    require_figure_options(args)
    fmt = figure_format(args)
    check_scenario_options(args)
    check_scheduler_options(args)
    model = with_inputs(args, load_model(args.model))
    swept = [p for p in args.param if isinstance(p, str)]
    grid = swept_grid(args, model, swept)
    _refuse_fixed_swept(args, model, list(grid.names))
    systems = _variant_systems(args, model, grid)
    middle = systems[len(systems) // 2]
    t_stop = args.tstop or float((middle.circuit_hints or {}).get("t_stop", 5.0))
    if args.window is not None and args.window > t_stop:
        given = "--tstop" if args.tstop else "the model's default"
        raise UsageError(
            f"--window {args.window:g} s is longer than the simulated time ({given}: {t_stop:g} s)"
        )
    window = min(1.0, t_stop) if args.window is None else args.window
    prepare_output_folder("--out", args.out, "sweep.csv", f"sweep.{fmt}")
    options = SynthesisOptions(opamp=args.opamp, t_stop=args.tstop)
    fixed = [p for p in args.param if not isinstance(p, str)]
    one = len(grid.names) == 1 and grid.axes is not None  # a plain sweep: its CSV and plot
    bar = _SweepBar()
    with executor_for(args) as executor:
        try:
            run = dict(
                engine=args.engine,
                options=options,
                window=window,
                workers=min(args.jobs, len(grid)),  # more would only make idle threads
                progress=bar,
                ngspice_timeout=args.ngspice_timeout,
                executor=executor,
                state=model.state_named(args.state),
            )
            if one:
                from circuitsim.compare.sweep import run_sweep

                name = grid.names[0]
                result = run_sweep(systems, grid.axes[0], name, grid.units[0], **run)
            else:
                from circuitsim.studies.study import run_grid

                result = run_grid(systems, grid, **run)
        finally:
            bar.close()
    if not one:
        from circuitsim.studies.study import save_grid

        result.critical = critical_curve(args, model, grid, fixed)
        report_grid(
            result, grid, save_grid(result, args.out, log=args.log, fmt=fmt, dpi=args.dpi), executor
        )
        return 0
    from circuitsim.compare.sweep_plot import save_sweep

    for warning in result.warnings:
        print_warning(warning)
    unit = grid.units[0]
    if name == model.options.get("speed"):
        coefficients = args.coeffs or model.default_coefficients
        result.critical, _ = critical_speed(
            model, coefficients, parameter=name, parameters=dict(fixed) or None
        )
    paths = save_sweep(result, args.out, log=args.log, fmt=fmt, dpi=args.dpi)
    per = result.timings["simulation"] / len(grid)
    kernels = result.timings.get("kernels")
    ready = "" if kernels is None else f", compiled kernels ready {kernels:.3g} s"
    where = "" if executor is None else f", {executor.label}"
    where += "".join(f", {KERNEL_WORDS.get(k, k)}" for k in result.stats.get("kernels", ()))
    print(
        f"{_plural(len(grid), 'variant')} of {name} ({result.engine}{where}; changed: "
        f"{', '.join(result.changed) or 'none'}): synthesis {result.timings['synthesis']:.3g} s"
        f"{ready}, simulation {result.timings['simulation']:.3g} s ({per:.3g} s per variant)"
    )
    if result.critical is not None:
        print(f"critical {name} (linear) {result.critical:.4f} {unit}")
    for path in paths:
        print(f"wrote {path}")
    return 0


COMMANDS = [_add_sweep]
