"""Verbs on netlists: ``convert``, ``check`` and ``simulate``."""

from __future__ import annotations

import argparse
import sys

from circuitsim.cli.common import (
    MAX_STEP_COUNT,
    UsageError,
    add_figure_options,
    add_ngspice_timeout,
    plot_target,
    progress,
    progress_after,
    read_netlist_reporting_warnings,
    require_count,
    require_figure_options,
    require_figure_path,
    require_positive,
    require_writable,
)


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
    parser.set_defaults(func=_run_convert)


def _run_convert(args: argparse.Namespace) -> int:
    from circuitsim.netlist.writer import save_netlist, write_netlist

    circuit = read_netlist_reporting_warnings(args.netlist)
    if args.output:
        save_netlist(circuit, args.output, args.dialect)
        print(f"wrote {args.output} ({args.dialect})", file=sys.stderr)
    else:
        sys.stdout.write(write_netlist(circuit, args.dialect))
    return 0


def _add_check(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "check",
        help="topology checks: floating nodes, no DC path, source loops, undefined models ...",
        description=(
            "Read a netlist and report what would make it unsolvable or suspicious: floating "
            "nodes, nodes with no DC path to ground, current-source cut sets, loops of voltage "
            "sources and inductors, unconnected subcircuit ports, duplicate names, undefined "
            "or wrong-kind models and subcircuits. Exit code 0: clean, 1: findings, "
            "2: the netlist could not be read or is invalid."
        ),
    )
    parser.add_argument("netlist", metavar="FILE.cir", help="netlist to check")
    parser.set_defaults(func=_run_check)


def _run_check(args: argparse.Namespace) -> int:
    from circuitsim.netlist.topology import check_circuit

    findings = check_circuit(read_netlist_reporting_warnings(args.netlist))
    for finding in findings:
        print(f"{args.netlist}: {finding.kind}: {finding.message}")
    if not findings:
        print(f"{args.netlist}: no findings")
        return 0
    print(f"{len(findings)} finding(s)", file=sys.stderr)
    return 1


def _add_simulate(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "simulate",
        help="run a netlist's .tran, .op or .ac with our MNA engine or ngspice",
        description=(
            "Simulate FILE.cir: its first .tran, or its .op if it has no .tran, or its .ac "
            "if it has neither (--analysis chooses), with the "
            "built-in MNA engine (default) or ngspice. An .ac sweep writes, per frequency "
            "(Hz), the magnitude and phase (degrees) of each signal: vm(node), vp(node), "
            "im(vsource), ip(vsource). Writes every node voltage and every "
            "voltage-source current (or only --probe signals) on the engine's own time points, "
            "with the same column names and order from both engines; or, with --states, the "
            "physical states through the netlist's scale file. Probes are checked before the "
            "run."
        ),
    )
    parser.add_argument("netlist", metavar="FILE.cir", help="netlist to simulate")
    parser.add_argument(
        "--engine",
        choices=("builtin", "ngspice"),
        default="builtin",
        help="builtin (default: our MNA solver) or ngspice (the referee, if installed; its "
        "columns are the builtin engine's: node voltages and voltage-source currents, in the "
        "same order; a netlist only ngspice can read keeps ngspice's own columns)",
    )
    parser.add_argument(
        "--kernel",
        choices=("auto", "ports", "compiled", "python"),
        default="auto",
        help="builtin engine's transient loop: ports (compiled, Newton on the junction "
        "voltages), compiled (numba, every unknown), python (the reference), or auto (ports "
        "where the circuit allows, at any size; default)",
    )
    parser.add_argument(
        "--analysis",
        choices=("tran", "op", "ac"),
        help="which of the netlist's analyses to run (default: .tran, else .op, else .ac; an "
        "operating point needs no card)",
    )
    add_ngspice_timeout(parser)
    parser.add_argument(
        "--csv",
        metavar="FILE",
        help="write time,v(node),...,i(vsource),... (an .ac sweep: "
        "frequency,vm(node),vp(node),...)",
    )
    parser.add_argument(
        "--raw",
        metavar="FILE.raw",
        help="write the same columns as a binary rawfile in ngspice's layout (float64; read "
        "by ngspice's load, spicelib's RawRead with dialect='ngspice', compare --raw)",
    )
    parser.add_argument(
        "--plot",
        metavar="FILE",
        help="save a figure in the format of its suffix (.png, .pdf, .svg ...)",
    )
    parser.add_argument(
        "--probe",
        nargs="+",
        metavar="SIGNAL",
        help="only these signals, e.g. v(out) i(v1) (the builtin engine records only these)",
    )
    parser.add_argument(
        "--states",
        metavar="FILE.scale.json",
        help="write the physical states instead of node voltages: time in model seconds and "
        "each state of the scale file in its unit (state = v(node) / volts_per_unit at "
        "t / time_scale); the engine records only the state nodes",
    )
    parser.add_argument(
        "--max-steps",
        type=int,
        metavar="N",
        help="stop with an error after N attempted time steps (default 2000000); both "
        "engines refuse at once a .tran that needs more (TSTOP / TMAX)",
    )
    parser.add_argument(
        "--max-wall-time",
        type=float,
        metavar="SECONDS",
        help="builtin engine: stop with an error after this much wall time in the transient "
        "loop (default 600)",
    )
    parser.add_argument(
        "--max-memory",
        metavar="SIZE",
        help="memory budget of the recorded results, bytes or with a suffix k, M, G, T "
        "(powers of 1000; default: half the physical memory): a .tran whose results need "
        "more at least is refused before it starts, a run that records more stops with an "
        "error (ngspice: when its resident memory passes it)",
    )
    add_figure_options(parser, "the --plot figure")
    parser.set_defaults(func=_run_simulate)


_SIZE_SUFFIXES = {"": 1.0, "k": 1e3, "m": 1e6, "g": 1e9, "t": 1e12}


def memory_size(option: str, text: str | None) -> float | None:
    """``text`` (``"2G"``, ``"500M"``, ``"1e9"``, an optional trailing B) as bytes > 0.

    Raises
    ------
    UsageError
        Naming ``option``: not a size, or not above 0.
    """
    if text is None:
        return None
    body = text.strip().lower().removesuffix("b")
    suffix = body[-1:] if body[-1:] in _SIZE_SUFFIXES else ""
    try:
        value = float(body[: len(body) - len(suffix)]) * _SIZE_SUFFIXES[suffix]
    except ValueError:
        value = float("nan")
    if not (value >= 1 and value < float("inf")):
        raise UsageError(
            f"{option} must be a size of at least 1 byte (such as 2G or 500M), got {text[:40]!r}"
        )
    return value


def _run_simulate(args: argparse.Namespace) -> int:
    from pathlib import Path

    require_figure_path("--plot", args.plot)
    require_figure_options(args)
    args.plot = plot_target("--plot", args.plot, args)
    require_positive("--ngspice-timeout", args.ngspice_timeout)
    require_count("--max-steps", args.max_steps, MAX_STEP_COUNT)
    require_positive("--max-wall-time", args.max_wall_time)
    require_writable(args.csv, args.plot, args.raw)
    if args.raw is not None and args.states is not None:
        raise UsageError("--raw writes node voltages and currents; --states writes states")
    max_memory = memory_size("--max-memory", args.max_memory)
    scale_map = None
    probes = args.probe
    if args.states is not None:
        from circuitsim.synthesis.scalemap import ScaleMap

        if args.probe:
            raise UsageError("--states writes the scale file's states; give it or --probe")
        scale_map = ScaleMap.load(args.states)
        probes = [state.node for state in scale_map.states.values()]
    if args.engine == "ngspice":
        waves = _simulate_ngspice(args, probes, max_memory)
    else:
        from circuitsim.solver import SimulationOptions, simulate
        from circuitsim.solver.errors import SolverError

        circuit = read_netlist_reporting_warnings(args.netlist)
        limits = {
            key: value
            for key, value in (
                ("max_steps", args.max_steps),
                ("max_wall_time", args.max_wall_time),
                ("max_memory", max_memory),
            )
            if value is not None
        }
        try:
            options = SimulationOptions.from_circuit(circuit, kernel=args.kernel, **limits)
            waves = simulate(
                circuit,
                options,
                progress=progress_after(1.0),
                probes=probes,
                analysis=args.analysis,
                size_report=progress,
            )
        except SolverError as exc:  # about the circuit ("D1: no .model ..."): say which file
            exc.args = (f"{args.netlist}: {exc}",)
            raise
    if scale_map is not None:
        if waves.axis == "frequency":
            raise UsageError("--states maps transient traces; this run is an .ac sweep")
        waves = _physical_states(waves, scale_map)
    stats = waves.stats
    engine = args.engine
    if "kernel" in stats:  # "ports", or "python (why the compiled kernels do not apply)"
        name, _, why = stats["kernel"].partition(" (")
        engine += f" ({name} kernel: {why[:-1]})" if why else f" ({name} kernel)"
    points = "frequencies" if waves.axis == "frequency" else "time point(s)"
    summary = f"{args.netlist}: {engine}, {len(waves.time)} {points}"
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
    if args.raw:
        _write_raw(args, waves)
    if args.plot:
        from circuitsim.solver.plotting import plot_bode, plot_waveforms

        plot = plot_bode if waves.axis == "frequency" else plot_waveforms
        plot(waves, args.plot, title=Path(args.netlist).name, dpi=args.dpi)
        print(f"wrote {args.plot}")
    if not args.csv and not args.plot and not args.raw:
        where = f"f = {waves.time[-1]:.6g} Hz" if waves.axis == "frequency" else "t = "
        if waves.axis != "frequency":
            where += f"{waves.time[-1]:.6g} s"
        for name in waves.names:
            print(f"  {name} = {waves[name][-1]:.6g}  (at {where})")
    return 0


def _write_raw(args: argparse.Namespace, waves) -> None:
    """``--raw``: the waveforms in ngspice's binary layout, titled with the netlist's title."""
    from circuitsim.inputfile import NETLIST_BYTES, read_bytes
    from circuitsim.interop.rawwrite import write_rawfile

    data = read_bytes(args.netlist, NETLIST_BYTES, "a netlist file")  # read before: fits
    title = data.decode("utf-8", errors="replace").partition("\n")[0].strip()
    operating_point = waves.stats.get("analysis") == "op"  # both engines say which they ran
    write_rawfile(args.raw, waves, title, operating_point=operating_point)
    print(f"wrote {args.raw}")


def _builtin_signals(
    netlist: str, probes: list[str] | None
) -> tuple[list[str] | None, str, int | None]:
    """The signals the builtin engine writes for ``netlist`` (``probes`` checked against
    them, a CircuitInputError naming an unknown one), or None and why for a netlist only
    ngspice can take (a vendor model with POLY sources, say); and the number of all its
    signals (None for such a netlist)."""
    import warnings

    from circuitsim.netlist.errors import NetlistError
    from circuitsim.netlist.reader import read_netlist
    from circuitsim.solver.engine import build_system, probe_names
    from circuitsim.solver.errors import SolverError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # ngspice reads the file itself; its log tells
            system = build_system(read_netlist(netlist), None)
    except (NetlistError, SolverError) as exc:
        return None, str(exc), None
    return probe_names(system, probes), "", system.size


def _simulate_ngspice(args: argparse.Namespace, probes: list[str] | None, max_memory):
    """ngspice's waveforms with the builtin engine's columns, probes checked before the run,
    and the builtin engine's run guards (``--max-steps``, ``--max-memory``)."""
    from pathlib import Path

    from circuitsim.interop.errors import NgspiceError
    from circuitsim.interop.ngspice import RunLimits, run_ngspice
    from circuitsim.solver.errors import SolverError

    names, why, signals = _builtin_signals(args.netlist, probes)
    limits = RunLimits(signals=signals, progress=progress)
    if args.max_steps is not None:
        limits.max_steps = args.max_steps
    if max_memory is not None:
        limits.max_memory = max_memory
    try:
        if names is None:
            print(
                f"{args.netlist}: ngspice's own columns (the builtin engine cannot take this "
                f"netlist: {why}); probes are checked after the run",
                file=sys.stderr,
            )
            return run_ngspice(
                Path(args.netlist),
                probes=probes,
                timeout=args.ngspice_timeout,
                analysis=args.analysis,
                limits=limits,
            )
        waves = run_ngspice(
            Path(args.netlist),
            timeout=args.ngspice_timeout,
            analysis=args.analysis,
            limits=limits,
        )
    except SolverError as exc:  # the builtin engine's guards: say which file
        exc.args = (f"{args.netlist}: {exc}",)
        raise
    if waves.axis == "frequency":  # magnitude and phase of each signal, as ours writes them
        names = [n[0] + part + n[1:] for n in names for part in "mp"]
    missing = [name for name in names if name not in waves]
    if missing:
        raise NgspiceError(
            f"{args.netlist}: ngspice wrote no {', '.join(missing)} (the builtin engine has it)"
        )
    stats = waves.stats
    waves = waves.select(names)
    waves.stats = stats
    return waves


def _physical_states(waves, scale_map):
    """Waveforms of the scale map's states: model seconds, each state in its own unit."""
    from circuitsim.compare.mapping import map_waveforms
    from circuitsim.solver.waveforms import Waveforms

    traces = map_waveforms(waves, scale_map)
    time = next(iter(traces.values()))[0] if traces else scale_map.model_time(waves.time)
    signals = {state: values for state, (_, values) in traces.items()}
    return Waveforms(time=time, signals=signals, engine=waves.engine, stats=waves.stats)


COMMANDS = [_add_convert, _add_check, _add_simulate]
