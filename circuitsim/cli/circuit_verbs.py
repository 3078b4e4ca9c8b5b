"""Verbs from a model to its circuit and back: generate, compare, reproduce."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from circuitsim.cli.common import (
    UsageError,
    add_figure_options,
    add_jobs_option,
    add_max_step,
    add_ngspice_timeout,
    figure_format,
    plot_target,
    prepare_output_folder,
    print_warning,
    progress,
    require_figure_options,
    require_figure_path,
    require_jobs,
    require_positive,
    require_writable,
)
from circuitsim.cli.opamp_options import add_opamp_error_options, opamp_errors
from circuitsim.cli.scenario_options import (
    add_model_options,
    add_scenario_options,
    check_scenario_options,
    scenario_system,
)
from circuitsim.cli.translator_options import (
    add_knob_options,
    add_opamp_options,
    add_time_scale,
    add_translator_options,
    check_translator_options,
    knob_request,
    opamp_fields,
    translator_options,
)

if TYPE_CHECKING:
    pass


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
    add_translator_options(parser)
    add_opamp_error_options(parser)
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
    add_knob_options(parser)
    parser.add_argument(
        "--schematic",
        metavar="FILE.svg|FILE.png",
        help="also draw the circuit (one row of blocks per state, the paper's part names and "
        "values); the format follows the suffix",
    )
    parser.add_argument(
        "--kicad",
        metavar="FILE.kicad_sch",
        help="also write an editable KiCad 6+ schematic (wired stages, the BOM's designators, "
        "SPICE fields for KiCad's simulator) and its SPICE library FILE.spice.lib",
    )
    parser.add_argument("-o", "--output", required=True, metavar="FILE.cir", help="netlist file")
    parser.set_defaults(func=_run_generate)


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
    check_translator_options(args)
    require_positive("--tstop", args.tstop)
    if args.switch_at is not None and not args.switch_at >= 0:  # NaN fails the comparison
        raise UsageError(f"--switch-at must be a time >= 0 or inf, got {args.switch_at:g}")


def _run_generate(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from circuitsim.synthesis.generate import generate, switch_at
    from circuitsim.synthesis.knob import knob_summary

    _check_generate(args)
    model, system = scenario_system(args, with_model=True)
    system = switch_at(system, args.switch_at)
    knob = knob_request(args, model)
    options = replace(translator_options(args), **opamp_errors(args))
    if args.kicad is not None and Path(args.kicad).suffix.lower() != ".kicad_sch":
        raise UsageError(f"--kicad {args.kicad}: the file name must end in .kicad_sch")
    if args.schematic is not None and Path(args.schematic).suffix.lower() not in (".svg", ".png"):
        raise UsageError(
            f"--schematic {args.schematic}: cannot draw a "
            f"{Path(args.schematic).suffix or 'file without a suffix'}; use .svg or .png"
        )
    result = generate(
        system, args.output, options, args.dialect, knob=knob, schematic=args.schematic,
        kicad=args.kicad,
    )  # fmt: skip
    _print_warnings(result.synthesis)
    extra = [p for p in (result.knob_file, result.schematic_file, result.kicad_file,
                         result.kicad_library) if p is not None]  # fmt: skip
    print(
        f"wrote {result.netlist}, {result.scale_file}, {result.bom_file}, {result.order_file}"
        + "".join(f", {p}" for p in extra)
    )
    for line in knob_summary(result.knobs, knob):
        print(line)
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
    add_opamp_options(parser)
    add_opamp_error_options(parser)
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
    add_time_scale(parser)
    add_max_step(parser)
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
        ".svg ...); past 6 states the panels fill side-by-side columns",
    )
    parser.add_argument(
        "--states",
        type=_state_list,
        metavar="A,B,...",
        help="the states --plot draws, in this order (comma-separated; default: every state)",
    )
    add_figure_options(parser, "the --plot figure")
    parser.set_defaults(func=_run_compare)


def _state_list(text: str) -> list[str]:
    """``--states y1,psi1``: the names, in order, each once."""
    names = [name.strip() for name in text.split(",")]
    if not all(names) or len(set(names)) != len(names):
        raise argparse.ArgumentTypeError(
            f"expected state names separated by commas, each once, got {text!r}"
        )
    return names


def _check_compare(args: argparse.Namespace) -> None:
    """Refuse bad times, thresholds (NaN would pass everything) and figure suffix."""
    check_scenario_options(args)
    require_positive("--tstop", args.tstop)
    require_positive("--time-scale", args.time_scale)
    require_positive("--max-nrmsd", args.max_nrmsd)
    require_positive("--tolerance", args.tolerance)
    require_positive("--ngspice-timeout", args.ngspice_timeout)
    require_positive("--max-step", args.max_step)
    require_figure_path("--plot", args.plot)
    require_figure_options(args)
    args.plot = plot_target("--plot", args.plot, args)
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
            ("--opamp-lib", args.opamp_lib is not None),
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
    fields = opamp_fields(args)
    thresholds = replace(
        Thresholds.for_opamp(args.opamp),
        peak_ratio_tolerance=args.tolerance,
        frequency_ratio_tolerance=args.tolerance,
    )
    if args.max_nrmsd is not None:
        thresholds = replace(thresholds, nrmsd_percent=args.max_nrmsd)
    errors = opamp_errors(args)
    if args.netlist is not None or args.raw is not None:
        if args.opamp_offset or args.opamp_bias:
            raise UsageError(
                "--opamp-offset/--opamp-bias apply to a generated circuit, not to "
                "a given --netlist or --raw"
            )
        return _compare_given(args, thresholds)
    args.engine = args.engine or "builtin"
    options = SynthesisOptions(
        **fields,
        series=args.series,
        t_stop=args.tstop,
        time_scale=args.time_scale,
        **errors,
    )
    opamp = args.opamp_subckt if args.opamp == "lib" else args.opamp
    label = f"{args.engine}, {opamp}, {args.series}"
    model, system = scenario_system(args, with_model=True)
    _check_plotted(args, system)
    case = run_case(
        system,
        options,
        args.engine,
        thresholds,
        args.write_netlist,
        label=label,
        ngspice_timeout=args.ngspice_timeout,
        max_step=args.max_step,
    )
    _print_warnings(case.synthesis)
    _print_fits(system, sys.stderr if args.json else sys.stdout)
    return _print_case(args, case, label, model.time_unit)


def _check_plotted(args: argparse.Namespace, system) -> None:
    """Refuse a ``--states`` name that is no state of the model (before any run)."""
    unknown = [name for name in args.states or () if name not in system.states]
    if unknown:
        raise UsageError(
            f"--states: no state {', '.join(map(repr, unknown))} in model {system.name} "
            f"(states: {', '.join(system.states)})"
        )


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
    model, system = scenario_system(args, with_model=True)
    _check_plotted(args, system)
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
            max_step=args.max_step,
        )
    else:
        from circuitsim.interop.errors import NgspiceError
        from circuitsim.interop.rawfile import read_rawfile

        try:
            waves = read_rawfile(source)
        except NgspiceError as exc:  # a file that is not a rawfile: the user's input
            raise UsageError(str(exc)) from None
        label = f"{waves.engine or 'raw'}, {Path(source).name}"
        case = compare_waveforms(
            system, waves, scale_map, thresholds, waves.engine, label=label,
            max_step=args.max_step,
        )  # fmt: skip
    _print_fits(system, sys.stderr if args.json else sys.stdout)
    return _print_case(args, case, label, model.time_unit)


def _print_case(args: argparse.Namespace, case, label: str, time_unit: str = "s") -> int:
    """The comparison as a table (or JSON), the plot; exit code 0 pass, 1 fail."""
    import json

    comparison = case.comparison
    if args.plot:
        from circuitsim.compare.plots import plot_overlay
        from circuitsim.figure_style import display_unit

        shown = {state: display_unit(m.unit) for state, m in comparison.states.items()}
        plot_overlay(
            args.plot,
            case.reference,
            {label: case.circuit},
            states=args.states,
            units={state: unit for state, (unit, _) in shown.items()},
            scales={state: factor for state, (_, factor) in shown.items()},
            title=f"circuit over ODE ({label})",
            errors=True,
            time_unit=time_unit,
            dpi=args.dpi,
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
        "--series",
        action="append",
        choices=("exact", "E96", "E24"),
        help="repeatable; default exact and E96",
    )
    add_jobs_option(parser, "processes at a time, at least 1 (default: every core)", None)
    add_ngspice_timeout(parser)
    add_figure_options(parser, "the figures in figures/ (the schematic is SVG and PNG)")
    parser.set_defaults(func=_run_reproduce)


def _run_reproduce(args: argparse.Namespace) -> int:
    from circuitsim.studies.reproduce import OPAMPS, SERIES, reproduce

    require_jobs(args)
    require_positive("--ngspice-timeout", args.ngspice_timeout)
    require_figure_options(args)
    prepare_output_folder("--out", args.out, "report.md", "metrics.json")
    result = reproduce(
        args.out,
        progress=progress,
        opamps=tuple(args.opamp or OPAMPS),
        series=tuple(args.series or SERIES),
        engines=tuple(args.engine or ("builtin", "ngspice")),
        workers=args.jobs,
        ngspice_timeout=args.ngspice_timeout,
        figure_format=figure_format(args),
        dpi=args.dpi,
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


COMMANDS = [_add_generate, _add_compare, _add_reproduce]
