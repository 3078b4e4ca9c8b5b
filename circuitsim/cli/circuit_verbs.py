"""Verbs from a model to its circuit and back: generate, compare, reproduce, sweep."""

from __future__ import annotations

import argparse
import os
import sys
from typing import TYPE_CHECKING, TextIO

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
    progress,
    require_figure_path,
    require_jobs,
    require_positive,
    require_writable,
    scenario_system,
    state_range,
    with_inputs,
)

if TYPE_CHECKING:
    from circuitsim.mechanics.model import Model


TSTOP_HELP = (
    "model seconds to simulate (> 0; default: the model file's [circuit] t_stop, else 5; "
    "the wheelset: 5)"
)


def _add_generate(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "generate",
        help="write the model's op-amp analog-computer netlist, scale file and BOM",
        description=(
            "Translate the model into an op-amp circuit (one integrator and one inverter per "
            "state, |x| or dead-zone blocks for the piecewise-linear terms, the paper's part "
            "names for the wheelset) and write FILE.cir, FILE.scale.json (how node voltages "
            "map back to states) and FILE.bom.csv (parts, rounding errors). The written "
            "netlist is read back and its coefficients checked against the model (exit code "
            "1 if the check fails; an error writes no file: 2 for bad input, 3 for a failed "
            "run). See docs/translator.md."
        ),
    )
    add_model_options(parser)
    add_scenario_options(parser)
    parser.add_argument(
        "--opamp", choices=("ideal", "tl074"), default="ideal", help="op-amp model (default ideal)"
    )
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
    _add_time_scale(parser)
    parser.add_argument(
        "--series",
        choices=("E96", "E24", "exact"),
        default="E96",
        help="resistor values (default E96)",
    )
    parser.add_argument(
        "--pair-tolerance",
        type=float,
        default=1e-3,
        metavar="REL",
        help="a coefficient resistor that one standard value misses by more than REL becomes "
        "two in series, R33 -> R33A + R33B (default 0.001; inf: never a pair)",
    )
    parser.add_argument(
        "--dialect",
        choices=("ngspice", "ltspice", "multisim"),
        default="ngspice",
        help="netlist dialect (default ngspice)",
    )
    parser.add_argument(
        "--tstop",
        type=float,
        metavar="T",
        help=TSTOP_HELP,
    )
    parser.add_argument(
        "--switch-at",
        type=float,
        metavar="T",
        help="close the nonlinear switches (S1) at model time T >= 0 instead of from the start; "
        "'inf' keeps them open (the linear circuit with the blocks in place)",
    )
    parser.add_argument("-o", "--output", required=True, metavar="FILE.cir", help="netlist file")
    parser.set_defaults(func=_run_generate)


def _add_time_scale(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--time-scale",
        type=float,
        metavar="K",
        help="one model second takes 1/K circuit seconds (K > 0; default: the model file's "
        "[circuit] time_scale, else 1, real time)",
    )


def _print_warnings(synthesis) -> None:
    """The translator's warnings as ``warning:`` lines (the mapping check's are in its
    summary)."""
    for warning in synthesis.warnings:
        print_warning(warning)


def _print_fits(system, stream=None) -> None:
    """The fitted functions of the model: pieces, error, allowed error (docs/model.md)."""
    from circuitsim.mechanics.shapes import fit_summaries

    for line in fit_summaries(system):
        print(line, file=stream or sys.stdout)


def _check_generate(args: argparse.Namespace) -> None:
    """Refuse non-positive or non-finite --swing, --time-scale, --tstop and a bad --switch-at."""
    check_scenario_options(args)
    require_positive("--swing", args.swing)
    require_positive("--time-scale", args.time_scale)
    require_positive("--tstop", args.tstop)
    if args.switch_at is not None and not args.switch_at >= 0:  # NaN fails the comparison
        raise UsageError(f"--switch-at must be a time >= 0 or inf, got {args.switch_at:g}")


def _run_generate(args: argparse.Namespace) -> int:
    from circuitsim.synthesis.generate import generate, switch_at
    from circuitsim.synthesis.options import SynthesisOptions

    _check_generate(args)
    system = switch_at(scenario_system(args), args.switch_at)
    options = SynthesisOptions(
        opamp=args.opamp,
        nonlinear=args.nonlinear,
        scaling=args.scaling,
        swing=args.swing,
        time_scale=args.time_scale,
        series=args.series,
        pair_tolerance=args.pair_tolerance,
        t_stop=args.tstop,
        ranges=dict(args.range),
    )
    result = generate(system, args.output, options, args.dialect)
    _print_warnings(result.synthesis)
    print(f"wrote {result.netlist}, {result.scale_file}, {result.bom_file}, {result.order_file}")
    _print_fits(system)
    print(result.synthesis.step.describe(result.synthesis.scale_map.time_scale))
    print(result.report.summary())
    return 0 if result.report.ok else 1


def _add_compare(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "compare",
        help="generate the circuit, simulate it, solve the ODE and compare them state by state",
        description=(
            "Translate the model scenario into its op-amp circuit, simulate the circuit with "
            "the chosen engine, map node voltages back to physical states through the scale "
            "map, solve the ODE directly, and print per state: %NRMSD, max abs error, peak "
            "ratio, dominant-frequency ratio and phase lag (positive: the circuit lags). Exit "
            "code 1 when a metric is beyond its threshold, 2 for bad input, 3 for a failed "
            "run. See docs/validation.md."
        ),
    )
    add_model_options(parser)
    add_scenario_options(parser)
    parser.add_argument(
        "--opamp", choices=("ideal", "tl074"), default="ideal", help="op-amp model (default ideal)"
    )
    parser.add_argument(
        "--series",
        choices=("exact", "E96", "E24"),
        default="exact",
        help="resistor values (default exact: the design itself; E96 shows what standard "
        "parts cost)",
    )
    parser.add_argument(
        "--engine",
        choices=("builtin", "ngspice"),
        help="circuit simulator (default builtin, our MNA solver; ngspice, the referee, if "
        "installed)",
    )
    add_ngspice_timeout(parser)
    parser.add_argument(
        "--tstop",
        type=float,
        metavar="T",
        help=TSTOP_HELP,
    )
    _add_time_scale(parser)
    given = parser.add_argument_group(
        "a circuit or results made elsewhere (instead of generating the circuit)"
    )
    given.add_argument(
        "--netlist",
        metavar="FILE.cir",
        help="simulate this netlist (hand-edited, or with a vendor op-amp model) instead of "
        "generating one; its .tran sets the time; the model options still set the ODE side",
    )
    given.add_argument(
        "--raw",
        metavar="FILE.raw",
        help="compare these results (an ngspice raw file, binary or ASCII) instead of "
        "simulating; needs --scale",
    )
    given.add_argument(
        "--scale",
        metavar="FILE.scale.json",
        help="the scale file of --netlist (default: FILE.scale.json beside it) or of the "
        "netlist that made --raw",
    )
    parser.add_argument(
        "--max-nrmsd",
        type=float,
        metavar="PERCENT",
        help="NRMSD threshold, > 0 (default 0.5 for ideal op-amps, 2 for tl074)",
    )
    parser.add_argument(
        "--tolerance",
        type=float,
        default=0.01,
        metavar="FRACTION",
        help="allowed |peak ratio - 1| and |frequency ratio - 1|, > 0 (default 0.01)",
    )
    parser.add_argument(
        "--write-netlist",
        metavar="FILE.cir",
        help="also write the generated netlist, scale file and BOM here",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--plot",
        metavar="FILE.png",
        help="draw the circuit traces over the ODE's, in the format of the suffix (.png, .pdf, "
        ".svg ...)",
    )
    parser.set_defaults(func=_run_compare)


def _check_compare(args: argparse.Namespace) -> None:
    """Refuse bad times, thresholds (NaN would pass everything) and figure suffix."""
    check_scenario_options(args)
    require_positive("--tstop", args.tstop)
    require_positive("--time-scale", args.time_scale)
    require_positive("--max-nrmsd", args.max_nrmsd)
    require_positive("--tolerance", args.tolerance)
    require_positive("--ngspice-timeout", args.ngspice_timeout)
    require_figure_path("--plot", args.plot)
    if args.write_netlist is not None:
        from circuitsim.synthesis.generate import companion_paths

        require_writable(args.write_netlist)  # first: "." or a folder has no companion files
        require_writable(*companion_paths(args.write_netlist))
    require_writable(args.plot)
    _check_given_inputs(args)


def _check_given_inputs(args: argparse.Namespace) -> None:
    """--netlist / --raw: one of them, with a scale file, and no options of the generator."""
    if args.netlist is None and args.raw is None:
        if args.scale is not None:
            raise UsageError("--scale goes with --netlist or --raw")
        return
    if args.netlist is not None and args.raw is not None:
        raise UsageError("give --netlist (simulated here) or --raw (results made elsewhere)")
    if args.raw is not None and args.scale is None:
        raise UsageError("--raw needs --scale FILE.scale.json (the scale file of its netlist)")
    if args.raw is not None and args.engine is not None:
        raise UsageError("--raw results are compared as they are: --engine does not apply")
    generator = [
        name
        for name, value in (
            ("--series", args.series != "exact"),
            ("--tstop", args.tstop is not None),
            ("--time-scale", args.time_scale is not None),
            ("--write-netlist", args.write_netlist is not None),
        )
        if value
    ]
    if generator:
        raise UsageError(
            f"{', '.join(generator)}: options of the generated circuit; with --netlist or "
            "--raw the netlist's own .tran and values are used"
        )
    from pathlib import Path

    for option, path in (("--netlist", args.netlist), ("--raw", args.raw)):
        if path is not None and not Path(path).is_file():
            raise UsageError(f"{option} {path}: no such file")


def _run_compare(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from circuitsim.compare import Thresholds
    from circuitsim.compare.case import run_case
    from circuitsim.synthesis.options import SynthesisOptions

    _check_compare(args)
    thresholds = replace(
        Thresholds.for_opamp(args.opamp),
        peak_ratio_tolerance=args.tolerance,
        frequency_ratio_tolerance=args.tolerance,
    )
    if args.max_nrmsd is not None:
        thresholds = replace(thresholds, nrmsd_percent=args.max_nrmsd)
    if args.netlist is not None or args.raw is not None:
        return _compare_given(args, thresholds)
    args.engine = args.engine or "builtin"
    options = SynthesisOptions(
        opamp=args.opamp, series=args.series, t_stop=args.tstop, time_scale=args.time_scale
    )
    label = f"{args.engine}, {args.opamp}, {args.series}"
    system = scenario_system(args)
    case = run_case(
        system,
        options,
        args.engine,
        thresholds,
        args.write_netlist,
        label=label,
        ngspice_timeout=args.ngspice_timeout,
    )
    _print_warnings(case.synthesis)
    _print_fits(system, sys.stderr if args.json else sys.stdout)
    return _print_case(args, case, label)


def _compare_given(args: argparse.Namespace, thresholds) -> int:
    """compare --netlist F.cir [--scale] or --raw F.raw --scale: no circuit generated."""
    from pathlib import Path

    from circuitsim.compare.external import compare_waveforms, run_netlist_case
    from circuitsim.synthesis.generate import companion_paths
    from circuitsim.synthesis.scalemap import ScaleMap

    source = args.netlist if args.netlist is not None else args.raw
    scale = args.scale if args.scale is not None else companion_paths(args.netlist)[0]
    if not Path(scale).is_file():
        raise UsageError(f"no scale file {scale} (give --scale FILE.scale.json)")
    scale_map = ScaleMap.load(scale)
    system = scenario_system(args)
    if args.netlist is not None:
        args.engine = args.engine or "builtin"
        label = f"{args.engine}, {Path(source).name}"
        case = run_netlist_case(
            system,
            source,
            scale_map,
            args.engine,
            thresholds,
            label=label,
            ngspice_timeout=args.ngspice_timeout,
        )
    else:
        from circuitsim.interop.errors import NgspiceError
        from circuitsim.interop.rawfile import read_rawfile

        try:
            waves = read_rawfile(source)
        except NgspiceError as exc:  # a file that is not a rawfile: the user's input
            raise UsageError(str(exc)) from None
        label = f"{waves.engine or 'raw'}, {Path(source).name}"
        case = compare_waveforms(system, waves, scale_map, thresholds, waves.engine, label=label)
    _print_fits(system, sys.stderr if args.json else sys.stdout)
    return _print_case(args, case, label)


def _print_case(args: argparse.Namespace, case, label: str) -> int:
    """The comparison as a table (or JSON), the plot; exit code 0 pass, 1 fail."""
    import json

    comparison = case.comparison
    if args.plot:
        from circuitsim.compare.plots import plot_overlay

        plot_overlay(
            args.plot,
            case.reference,
            {label: case.circuit},
            units={state: m.unit for state, m in comparison.states.items()},
            title=f"circuit over ODE ({label})",
            errors=True,
        )
    written = [str(args.plot)] if args.plot else []
    if case.netlist is not None and case.synthesis is not None:  # generated and written here
        from circuitsim.synthesis.generate import companion_paths

        written[:0] = [str(case.netlist), *map(str, companion_paths(case.netlist))]
    report = case.report
    synthesis = case.synthesis  # None for a netlist or results made elsewhere
    step = None if synthesis is None else synthesis.step.describe(synthesis.scale_map.time_scale)
    if args.json:
        data = comparison.to_json()
        data.update(
            engine=case.engine or args.engine,
            opamp=args.opamp,
            series=args.series,
            netlist=None if case.netlist is None else str(case.netlist),
            critical_speed_model=getattr(report, "critical_speed_model", None),
            critical_speed_circuit=getattr(report, "critical_speed_realized", None),
            timings_s=case.timings,
            time_step=step,
        )
        print(json.dumps(data, indent=1))
        if written:  # stdout holds the JSON alone
            print(f"wrote {', '.join(written)}", file=sys.stderr)
    else:
        if written:
            print(f"wrote {', '.join(written)}")
        print(f"circuit ({label}) against the ODE" + (f"; {step}" if step else ""))
        print(comparison.table())
        if report is not None:
            print(report.summary())
        print("PASS" if comparison.passed else "FAIL: " + ", ".join(comparison.failures()))
    return 0 if comparison.passed else 1


def _add_reproduce(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "reproduce",
        help="the paper's figures and a validation report (all scenarios, circuits, engines)",
        description=(
            "Solve the paper's six forced-response scenarios (V = 55 m/s; 3, 5, 10 Hz; flange "
            "off/on) and the free responses at 54 and 57 m/s, generate each scenario's circuit "
            "with ideal and TL074 op-amps and exact and E96 values, simulate them with every "
            "available engine, and write figures/ (Fig. 3, 4, 6, critical speed), netlists/, "
            "report.md and metrics.json. Progress on stderr. See docs/validation.md."
        ),
    )
    parser.add_argument(
        "--out", default="reproduction", metavar="DIR", help="output folder (default reproduction)"
    )
    parser.add_argument(
        "--engine",
        action="append",
        choices=("builtin", "ngspice"),
        help="engine to run (repeatable; default both)",
    )
    parser.add_argument(
        "--opamp", action="append", choices=("ideal", "tl074"), help="repeatable; default both"
    )
    parser.add_argument(
        "--series", action="append", choices=("exact", "E96"), help="repeatable; default both"
    )
    add_jobs_option(parser, "processes at a time, at least 1 (default: every core)", None)
    add_ngspice_timeout(parser)
    parser.set_defaults(func=_run_reproduce)


def _run_reproduce(args: argparse.Namespace) -> int:
    from circuitsim.compare.reproduce import OPAMPS, SERIES, reproduce

    require_jobs(args)
    require_positive("--ngspice-timeout", args.ngspice_timeout)
    prepare_output_folder("--out", args.out, "report.md", "metrics.json")
    result = reproduce(
        args.out,
        progress=progress,
        opamps=tuple(args.opamp or OPAMPS),
        series=tuple(args.series or SERIES),
        engines=tuple(args.engine or ("builtin", "ngspice")),
        workers=args.jobs,
        ngspice_timeout=args.ngspice_timeout,
    )
    done = [r for r in result.rows if r.comparison is not None]
    passed = sum(r.comparison.passed for r in done)
    print(
        f"wrote {result.out_dir / 'report.md'} ({len(done)} of {len(result.rows)} circuit runs "
        f"compared, {passed} within every threshold; {result.wall_s:.0f} s)"
    )
    for row in result.rows:
        if row.comparison is None:
            print(f"{row.scenario.name} {row.variant.label}: {row.status}")
    return 0


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


COMMANDS = [_add_generate, _add_compare, _add_reproduce, _add_sweep]
