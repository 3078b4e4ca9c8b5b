"""The ``circuitsim`` command line: parses options, calls the library, prints.

Each verb is a pair of functions: ``_add_<verb>(subparsers)`` declares its options and
``_run_<verb>(args) -> int`` does the work and returns the exit code. ``COMMANDS`` lists the
``_add_`` functions in the order ``--help`` shows them. Library errors are turned into one
readable line on stderr and exit code 1 (2 for unreadable input where a verb says so).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from circuitsim import __version__


def _library_errors() -> tuple[type[BaseException], ...]:
    """The typed errors of every room, caught at the top and printed as one line."""
    from circuitsim.interop.errors import NgspiceError
    from circuitsim.mechanics.errors import ModelError
    from circuitsim.netlist.errors import NetlistError
    from circuitsim.solver.errors import SolverError
    from circuitsim.synthesis.errors import SynthesisError

    return (ModelError, NetlistError, SolverError, SynthesisError, NgspiceError)


def _progress(message: str) -> None:
    """Progress callback handed to long-running library calls: one line on stderr."""
    print(message, file=sys.stderr, flush=True)


# --- verbs -------------------------------------------------------------------------------
# Each helper section below adds one verb; keep each small and put the work in the library.


COMMANDS: list[Callable[[argparse._SubParsersAction], None]] = []


def _add_model_options(parser: argparse.ArgumentParser) -> None:
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
    _add_model_options(parser)
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
        help="speed interval (m/s) searched for the loss of stability (default: 1 1000)",
    )
    parser.add_argument(
        "--parameter",
        metavar="NAME",
        help="parameter to sweep instead of the speed (for user models; --speed and --bracket "
        "are then in its unit); default: the model's [options] speed (wheelset: V)",
    )
    parser.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object: critical_speed (m/s), hunting_frequency (Hz), speed "
        "(m/s), eigenvalues ([re, im] pairs, 1/s), coefficients (the set's name)",
    )
    parser.set_defaults(func=_run_stability)


def _run_stability(args: argparse.Namespace) -> int:
    import json

    from circuitsim.mechanics import critical_speed, eigenvalues, load_model

    model = load_model(args.model)
    if args.parameter:
        speed_parameter = args.parameter
        if speed_parameter not in model.parameters:
            # eigenvalues() raises the ModelError naming the file and the known parameters
            eigenvalues(model, speed_parameter, [0.0])
    else:
        speed_parameter = model.option_parameters({"speed": 0.0}).popitem()[0]
    speed = model.parameters[speed_parameter] if args.speed is None else args.speed
    coefficients = args.coeffs or model.default_coefficients
    value, frequency = critical_speed(
        model, coefficients, parameter=speed_parameter, bracket=tuple(args.bracket)
    )
    lam = eigenvalues(model, speed_parameter, [speed], coefficients)[0]
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
    print(f"{label:18s} {value:.4f} {unit}")
    print(f"hunting frequency  {frequency:.4f} Hz")
    print(f"eigenvalues at {speed_parameter} = {speed:g} {unit} (1/s):")
    for v in lam:
        print(f"  {v.real:+.6g} {v.imag:+.6g}j")
    return 0


COMMANDS.append(_add_stability)


def _parameter_assignment(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    try:
        if not sep or not name.strip():
            raise ValueError
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected NAME=VALUE with a number, got {text!r}"
        ) from None


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
    _add_model_options(parser)
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
        "--tstop", type=float, default=5.0, metavar="T", help="end time, s (default 5)"
    )
    parser.add_argument(
        "--y0",
        type=float,
        metavar="Y",
        help="initial lateral displacement, m (default 0; other states start at 0)",
    )
    parser.add_argument(
        "--param",
        type=_parameter_assignment,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="set any model parameter in its SI unit (repeatable), e.g. --param eta=0.01",
    )
    parser.add_argument(
        "--rtol",
        type=float,
        default=1e-10,
        help="relative tolerance of the integrator (default 1e-10; absolute 1e-12)",
    )
    parser.add_argument(
        "--dt",
        type=float,
        default=5e-4,
        help="sample step of the CSV, s (default 0.0005; dense output, exact to the tolerance)",
    )
    parser.add_argument(
        "--csv",
        metavar="FILE",
        help="write time and every state (header time,y,psi,y_dot,psi_dot for the wheelset; "
        "SI units: s, m, rad, m/s, rad/s)",
    )
    parser.add_argument(
        "--plot",
        metavar="FILE",
        help="write a PNG: displacement, velocity and phase portrait (paper Fig. 4 style)",
    )
    parser.set_defaults(func=_run_ode)


def _run_ode(args: argparse.Namespace) -> int:
    import numpy as np

    from circuitsim.atomic import write_text_atomic
    from circuitsim.mechanics import load_model, solve

    model = load_model(args.model)
    parameters = model.option_parameters(
        {"speed": args.speed, "freq": args.freq, "amplitude": args.amplitude}
    )
    x0 = None
    if args.y0 is not None:
        if "y0" in model.options:
            parameters.update(model.option_parameters({"y0": args.y0}))
        else:
            x0 = {model.states[0]: args.y0}
    parameters.update(dict(args.param))
    nonlinear = None
    if args.flange is not None:
        nonlinear = {name: args.flange for name in model.nonlinear_terms}
    system = model.system(args.coeffs, parameters, nonlinear, x0)
    result = solve(system, t_span=(0.0, args.tstop), rtol=args.rtol, atol=1e-12)
    if args.csv:
        samples = int(np.floor(args.tstop / args.dt + 1e-9)) + 1
        grid = np.linspace(0.0, (samples - 1) * args.dt, samples)
        if grid[-1] < args.tstop:
            grid = np.append(grid, args.tstop)
        write_text_atomic(args.csv, result.csv_text(grid))
    if args.plot:
        from circuitsim.compare.figures import plot_response

        shown = {name: system.parameters[name] for name in model.options.values()}
        shown.update(parameters)
        settings = ", ".join([system.coefficient_set] + [f"{k}={v:g}" for k, v in shown.items()])
        title = f"{model.name} ({settings})"
        plot_response(args.plot, result, title=title)
    terms = ", ".join(term.name for term in system.nonlinear) or "none"
    print(f"model {model.name}, coefficient set {system.coefficient_set}, nonlinear: {terms}")
    print(f"0 to {args.tstop:g} s, {len(result.t)} steps, {len(result.kinks)} kink crossings")
    final = result.sol(args.tstop)
    for i, (name, unit) in enumerate(zip(result.states, result.units, strict=True)):
        peak = result.max_abs(name)
        print(f"  {name:10s} max |.| {peak:.6g} {unit:6s} at {args.tstop:g} s: {final[i]:+.6g}")
    if args.csv:
        print(f"wrote {args.csv}")
    if args.plot:
        print(f"wrote {args.plot}")
    return 0


COMMANDS.append(_add_ode)


def _add_convert(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "convert",
        help="rewrite a SPICE netlist for ngspice, LTspice or Multisim",
        description=(
            "Read a netlist (with its .include/.lib files) and write it in another dialect: "
            "switch model parameters, power operator, .control blocks, node names (see "
            "docs/netlists.md). Values are written so that they read back bit for bit."
        ),
    )
    parser.add_argument("netlist", metavar="IN.cir", help="netlist to read")
    parser.add_argument(
        "--dialect",
        choices=("ngspice", "ltspice", "multisim"),
        default="ngspice",
        help="dialect to write (default: ngspice)",
    )
    parser.add_argument(
        "-o", "--output", metavar="OUT.cir", help="file to write (default: standard output)"
    )
    parser.set_defaults(func=_run_convert, error_exit_code=2)


def _read_netlist_reporting_warnings(path: str):
    """``read_netlist(path)``, its NetlistWarnings printed as ``warning:`` lines on stderr."""
    import warnings

    from circuitsim.netlist.reader import read_netlist

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        circuit = read_netlist(path)
    for warning in caught:
        print(f"warning: {warning.message}", file=sys.stderr)
    return circuit


def _run_convert(args: argparse.Namespace) -> int:
    from circuitsim.netlist.writer import save_netlist, write_netlist

    circuit = _read_netlist_reporting_warnings(args.netlist)
    if args.output:
        save_netlist(circuit, args.output, args.dialect)
        print(f"wrote {args.output} ({args.dialect})", file=sys.stderr)
    else:
        sys.stdout.write(write_netlist(circuit, args.dialect))
    return 0


COMMANDS.append(_add_convert)


def _add_check(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "check",
        help="topology checks: floating nodes, no DC path, source loops, undefined models ...",
        description=(
            "Read a netlist and report what would make it unsolvable or suspicious: floating "
            "nodes, nodes with no DC path to ground, current-source cut sets, loops of voltage "
            "sources and inductors, unconnected subcircuit ports, duplicate names, undefined "
            "or wrong-kind models and subcircuits. Exit code 0: clean, 1: findings, "
            "2: the netlist could not be read."
        ),
    )
    parser.add_argument("netlist", metavar="FILE.cir", help="netlist to check")
    parser.set_defaults(func=_run_check, error_exit_code=2)


def _run_check(args: argparse.Namespace) -> int:
    from circuitsim.netlist.topology import check_circuit

    findings = check_circuit(_read_netlist_reporting_warnings(args.netlist))
    for finding in findings:
        print(f"{args.netlist}: {finding.kind}: {finding.message}")
    if not findings:
        print(f"{args.netlist}: no findings")
        return 0
    print(f"{len(findings)} finding(s)", file=sys.stderr)
    return 1


COMMANDS.append(_add_check)


def _add_scenario_options(parser: argparse.ArgumentParser) -> None:
    """--speed, --freq, --amplitude, --flange/--no-flange and --param: the run's scenario.

    Shared by the verbs that build a System from a model file (see ``_scenario_system``).
    """
    parser.add_argument("--speed", type=float, metavar="V", help="forward speed, m/s (default 55)")
    parser.add_argument(
        "--freq", type=float, metavar="F", help="excitation frequency, Hz (default 3)"
    )
    parser.add_argument(
        "--amplitude",
        type=float,
        metavar="A",
        help="excitation amplitude as a lateral track displacement, m (default 0.040)",
    )
    parser.add_argument(
        "--flange",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="switch the piecewise-linear terms (wheelset: the flange force, switch S1) on or "
        "off; default: as the model file says (wheelset: on)",
    )
    parser.add_argument(
        "--param",
        type=_parameter_assignment,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="set any model parameter in its SI unit (repeatable), e.g. --param eta=0.01",
    )


def _scenario_system(args: argparse.Namespace):
    """The System of ``--model``/``--coeffs`` and the scenario options."""
    from circuitsim.mechanics import load_model

    model = load_model(args.model)
    parameters = model.option_parameters(
        {"speed": args.speed, "freq": args.freq, "amplitude": args.amplitude}
    )
    parameters.update(dict(args.param))
    nonlinear = None
    if args.flange is not None:
        nonlinear = {name: args.flange for name in model.nonlinear_terms}
    return model.system(args.coeffs, parameters, nonlinear)


def _state_range(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    try:
        if not sep or not name.strip() or float(value) <= 0:
            raise ValueError
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected STATE=PEAK with a positive number, got {text!r}"
        ) from None


def _add_generate(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "generate",
        help="write the model's op-amp analog-computer netlist, scale file and BOM",
        description=(
            "Translate the model into an op-amp circuit (one integrator and one inverter per "
            "state, |x| or dead-zone blocks for the piecewise-linear terms, the paper's part "
            "names for the wheelset) and write FILE.cir, FILE.scale.json (how node voltages "
            "map back to states) and FILE.bom.csv (parts, rounding errors). The written "
            "netlist is read back and its coefficients checked against the model. See "
            "docs/translator.md."
        ),
    )
    _add_model_options(parser)
    _add_scenario_options(parser)
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
        "--swing", type=float, default=5.0, metavar="VOLTS", help="target peak, V (default 5)"
    )
    parser.add_argument(
        "--range",
        type=_state_range,
        action="append",
        default=[],
        metavar="STATE=PEAK",
        help="expected peak of a state in SI units, instead of the direct solution's (repeatable)",
    )
    parser.add_argument(
        "--time-scale",
        type=float,
        default=1.0,
        metavar="K",
        help="one model second takes 1/K circuit seconds (default 1, real time)",
    )
    parser.add_argument(
        "--series",
        choices=("E96", "E24", "exact"),
        default="E96",
        help="resistor values (default E96)",
    )
    parser.add_argument(
        "--dialect",
        choices=("ngspice", "ltspice", "multisim"),
        default="ngspice",
        help="netlist dialect (default ngspice)",
    )
    parser.add_argument(
        "--tstop", type=float, metavar="T", help="model seconds to simulate (default 5)"
    )
    parser.add_argument(
        "--switch-at",
        type=float,
        metavar="T",
        help="close the nonlinear switches (S1) at model time T instead of from the start; "
        "'inf' keeps them open (the linear circuit with the blocks in place)",
    )
    parser.add_argument("-o", "--output", required=True, metavar="FILE.cir", help="netlist file")
    parser.set_defaults(func=_run_generate)


def _run_generate(args: argparse.Namespace) -> int:
    from circuitsim.synthesis.generate import generate, switch_at
    from circuitsim.synthesis.options import SynthesisOptions

    system = switch_at(_scenario_system(args), args.switch_at)
    options = SynthesisOptions(
        opamp=args.opamp,
        nonlinear=args.nonlinear,
        scaling=args.scaling,
        swing=args.swing,
        time_scale=args.time_scale,
        series=args.series,
        t_stop=args.tstop,
        ranges=dict(args.range),
    )
    result = generate(system, args.output, options, args.dialect)
    for warning in result.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"wrote {result.netlist}, {result.scale_file}, {result.bom_file}")
    print(result.report.summary())
    return 0 if result.report.ok else 1


COMMANDS.append(_add_generate)


def _add_simulate(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "simulate",
        help="run a netlist's .tran (or .op) with our MNA engine or ngspice",
        description=(
            "Simulate FILE.cir: its first .tran, or its .op if it has no .tran, with the "
            "built-in MNA engine (default) or ngspice. Writes every node voltage and every "
            "voltage-source current (or only --probe signals) on the engine's own time points."
        ),
    )
    parser.add_argument("netlist", metavar="FILE.cir", help="netlist to simulate")
    parser.add_argument("--engine", choices=("builtin", "ngspice"), default="builtin")
    parser.add_argument("--csv", metavar="FILE", help="write time,v(node),...,i(vsource),...")
    parser.add_argument("--plot", metavar="FILE", help="save a figure (.png, .pdf, .svg)")
    parser.add_argument(
        "--probe", nargs="+", metavar="SIGNAL", help="only these signals, e.g. v(out) i(v1)"
    )
    parser.set_defaults(func=_run_simulate)


def _run_simulate(args: argparse.Namespace) -> int:
    from pathlib import Path

    from circuitsim.netlist.reader import read_netlist

    if args.engine == "ngspice":
        from circuitsim.interop.ngspice import run_ngspice

        waves = run_ngspice(Path(args.netlist), probes=args.probe)
    else:
        from circuitsim.solver import simulate

        waves = simulate(read_netlist(args.netlist), progress=_progress)
        if args.probe:
            missing = [p for p in args.probe if p not in waves]
            if missing:
                print(
                    f"circuitsim simulate: error: no signal {', '.join(missing)}; "
                    f"have {', '.join(waves.names)}",
                    file=sys.stderr,
                )
                return 1
            waves = waves.select(args.probe)
    stats = waves.stats
    summary = f"{args.netlist}: {args.engine}, {len(waves.time)} time point(s)"
    if "accepted" in stats:
        summary += (
            f", {stats['accepted']} accepted / {stats['rejected']} rejected steps, "
            f"{stats['newton_iterations']} Newton iterations"
        )
    if "wall_time_s" in stats:
        summary += f", {stats['wall_time_s']:.3g} s"
    print(summary)
    if args.csv:
        waves.to_csv(args.csv)
        print(f"wrote {args.csv}")
    if args.plot:
        from circuitsim.solver.plotting import plot_waveforms

        plot_waveforms(waves, args.plot, title=Path(args.netlist).name)
        print(f"wrote {args.plot}")
    if not args.csv and not args.plot:
        for name in waves.names:
            print(f"  {name} = {waves[name][-1]:.6g}  (at t = {waves.time[-1]:.6g} s)")
    return 0


COMMANDS.append(_add_simulate)


def _add_compare(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "compare",
        help="generate the circuit, simulate it, solve the ODE and compare them state by state",
        description=(
            "Translate the model scenario into its op-amp circuit, simulate the circuit with "
            "the chosen engine, map node voltages back to physical states through the scale "
            "map, solve the ODE directly, and print per state: %NRMSD, max abs error, peak "
            "ratio, dominant-frequency ratio and phase lag (positive: the circuit lags). Exit "
            "code 1 when a metric is beyond its threshold, 2 on an error. See "
            "docs/validation.md."
        ),
    )
    _add_model_options(parser)
    _add_scenario_options(parser)
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
        default="builtin",
        help="circuit simulator (default builtin, our MNA solver; with --opamp tl074 it takes "
        "tens of seconds, ngspice a second)",
    )
    parser.add_argument(
        "--tstop", type=float, metavar="T", help="model seconds to simulate (default 5)"
    )
    parser.add_argument(
        "--max-nrmsd",
        type=float,
        metavar="PERCENT",
        help="NRMSD threshold (default 0.5 for ideal op-amps, 2 for tl074)",
    )
    parser.add_argument(
        "--tolerance",
        type=float,
        default=0.01,
        metavar="FRACTION",
        help="allowed |peak ratio - 1| and |frequency ratio - 1| (default 0.01)",
    )
    parser.add_argument(
        "--netlist", metavar="FILE.cir", help="also write the netlist, scale file and BOM here"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--plot", metavar="FILE.png", help="draw the circuit traces over the ODE's")
    parser.set_defaults(func=_run_compare, error_exit_code=2)


def _run_compare(args: argparse.Namespace) -> int:
    import json
    from dataclasses import replace

    from circuitsim.compare import ComparisonError, Thresholds
    from circuitsim.compare.case import run_case
    from circuitsim.synthesis.options import SynthesisOptions

    thresholds = replace(
        Thresholds.for_opamp(args.opamp),
        peak_ratio_tolerance=args.tolerance,
        frequency_ratio_tolerance=args.tolerance,
    )
    if args.max_nrmsd is not None:
        thresholds = replace(thresholds, nrmsd_percent=args.max_nrmsd)
    options = SynthesisOptions(opamp=args.opamp, series=args.series, t_stop=args.tstop)
    label = f"{args.engine}, {args.opamp}, {args.series}"
    try:
        case = run_case(
            _scenario_system(args), options, args.engine, thresholds, args.netlist, label=label
        )
    except ComparisonError as exc:
        print(f"circuitsim compare: error: {exc}", file=sys.stderr)
        return 2
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
    report = case.report
    if args.json:
        data = comparison.to_json()
        data.update(
            engine=args.engine,
            opamp=args.opamp,
            series=args.series,
            netlist=None if case.netlist is None else str(case.netlist),
            critical_speed_model=getattr(report, "critical_speed_model", None),
            critical_speed_circuit=getattr(report, "critical_speed_realized", None),
            timings_s=case.timings,
        )
        print(json.dumps(data, indent=1))
    else:
        print(f"circuit ({label}) against the ODE")
        print(comparison.table())
        if report is not None:
            print(report.summary())
        print("PASS" if comparison.passed else "FAIL: " + ", ".join(comparison.failures()))
    return 0 if comparison.passed else 1


COMMANDS.append(_add_compare)


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
    parser.add_argument("--workers", type=int, metavar="N", help="processes (default: every core)")
    parser.add_argument(
        "--all",
        action="store_true",
        help="also run what a default run skips for time (our solver on the 12 TL074 circuits: "
        "a few minutes)",
    )
    parser.set_defaults(func=_run_reproduce)


def _run_reproduce(args: argparse.Namespace) -> int:
    from circuitsim.compare.reproduce import OPAMPS, SERIES, reproduce

    result = reproduce(
        args.out,
        progress=_progress,
        opamps=tuple(args.opamp or OPAMPS),
        series=tuple(args.series or SERIES),
        engines=tuple(args.engine or ("builtin", "ngspice")),
        workers=args.workers,
        skip={} if args.all else None,
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


COMMANDS.append(_add_reproduce)


def _sweep_param_item(text: str) -> tuple[str, float] | str:
    """``--param`` of the sweep verb: NAME=VALUE (a fixed parameter) or NAME (the swept one)."""
    if "=" in text:
        return _parameter_assignment(text)
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a parameter name or NAME=VALUE")
    return text.strip()


def _add_sweep(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "sweep",
        help="peak |y| against a parameter: many circuit variants in one vectorized run",
        description=(
            "Sweep one model parameter (e.g. --param speed --values 40:70:0.5): the circuit is "
            "translated once (exact resistors, one amplitude scaling for all values) and only "
            "the parts the parameter sets change between variants (for the speed: R33 and "
            "R44). The builtin engine simulates every variant together in one batched run; "
            "ngspice runs one process per variant. Writes sweep.csv and sweep.png (peak |y| "
            "over the last --window seconds and over the whole run, critical speed marked)."
        ),
    )
    _add_model_options(parser)
    _add_scenario_options(parser)
    for action in parser._actions:  # --param also names the swept parameter (no '=')
        if action.dest == "param":
            action.type = _sweep_param_item
            action.metavar = "NAME[=VALUE]"
            action.help = (
                "NAME: the parameter to sweep (speed, freq, amplitude or any model parameter); "
                "NAME=VALUE: set a fixed parameter in its SI unit (repeatable)"
            )
    parser.add_argument(
        "--values",
        required=True,
        metavar="START:STOP:STEP",
        help="values of the swept parameter (STOP included), or a comma-separated list",
    )
    parser.add_argument("--engine", choices=("builtin", "ngspice"), default="builtin")
    parser.add_argument(
        "--opamp", choices=("ideal", "tl074"), default="ideal", help="op-amp model (default ideal)"
    )
    parser.add_argument(
        "--tstop", type=float, metavar="T", help="model seconds to simulate (default 5)"
    )
    parser.add_argument(
        "--window", type=float, default=1.0, metavar="T", help="late window, s (default 1)"
    )
    parser.add_argument(
        "--jobs", type=int, default=2, metavar="N", help="ngspice processes at a time (default 2)"
    )
    parser.add_argument("--out", default=".", metavar="DIR", help="output folder (default .)")
    parser.set_defaults(func=_run_sweep)


def _sweep_bar(fraction: float, message: str) -> None:
    """Progress bar on stderr (one line, redrawn)."""
    width = 30
    filled = int(round(width * max(0.0, min(1.0, fraction))))
    text = f"\r[{'#' * filled}{'.' * (width - filled)}] {100 * fraction:5.1f}%  {message[:60]:60s}"
    print(text, end="", file=sys.stderr, flush=True)


def _run_sweep(args: argparse.Namespace) -> int:
    from circuitsim.compare.errors import ComparisonError

    try:
        return _sweep(args)
    except ComparisonError as exc:
        print(f"\ncircuitsim sweep: error: {exc}", file=sys.stderr)
        return 2


def _sweep(args: argparse.Namespace) -> int:
    from circuitsim.compare.sweep import parse_values, run_sweep, save_sweep
    from circuitsim.mechanics import critical_speed, load_model
    from circuitsim.synthesis.options import SynthesisOptions

    swept = [p for p in args.param if isinstance(p, str)]
    if len(swept) != 1:
        print("circuitsim sweep: error: name exactly one --param to sweep", file=sys.stderr)
        return 2
    values = parse_values(args.values)
    model = load_model(args.model)
    aliases = {"speed", "freq", "amplitude"}
    name = (
        model.option_parameters({swept[0]: 0.0}).popitem()[0] if swept[0] in aliases else swept[0]
    )
    if name not in model.parameters:
        print(
            f"circuitsim sweep: error: model {model.name} has no parameter {name!r}; "
            f"known: {', '.join(model.parameters)}",
            file=sys.stderr,
        )
        return 2
    fixed = [p for p in args.param if not isinstance(p, str)]
    systems = []
    for value in values:
        variant = argparse.Namespace(**vars(args))
        variant.param = [*fixed, (name, float(value))]
        if swept[0] in aliases:
            variant.param = fixed
            setattr(variant, swept[0], float(value))
        systems.append(_scenario_system(variant))
    options = SynthesisOptions(opamp=args.opamp, t_stop=args.tstop)
    unit = model.parameter_info[name].unit
    result = run_sweep(
        systems,
        values,
        name,
        unit,
        args.engine,
        options,
        window=args.window,
        workers=args.jobs,
        progress=_sweep_bar,
    )
    print(file=sys.stderr)
    speed = (
        model.option_parameters({"speed": 0.0}).popitem()[0] if "speed" in model.options else None
    )
    if name == speed:
        coefficients = args.coeffs or model.default_coefficients
        result.critical, _ = critical_speed(
            model, coefficients, parameter=name, parameters=dict(fixed) or None
        )
    paths = save_sweep(result, args.out)
    per = result.timings["simulation"] / len(values)
    print(
        f"{len(values)} variants of {name} ({result.engine}; changed: "
        f"{', '.join(result.changed) or 'none'}): synthesis {result.timings['synthesis']:.3g} s, "
        f"simulation {result.timings['simulation']:.3g} s ({per:.3g} s per variant)"
    )
    if result.critical is not None:
        print(f"critical {name} (linear) {result.critical:.4f} {unit}")
    for path in paths:
        print(f"wrote {path}")
    return 0


COMMANDS.append(_add_sweep)


# --- end of verbs ---


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every registered verb."""
    parser = argparse.ArgumentParser(
        prog="circuitsim",
        description=(
            "Mechanical ODE models and their op-amp analog-computer circuits: direct solution, "
            "stability, netlist generation, circuit simulation and comparison."
        ),
    )
    parser.add_argument("--version", action="version", version=f"circuitsim {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add in COMMANDS:
        add(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except _library_errors() as exc:
        print(f"circuitsim {args.command}: error: {exc}", file=sys.stderr)
        return getattr(args, "error_exit_code", 1)
    except OSError as exc:
        print(f"circuitsim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
