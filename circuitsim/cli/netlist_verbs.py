"""Verbs on netlists: ``convert``, ``check`` and ``simulate``."""

from __future__ import annotations

import argparse
import sys

from circuitsim.cli.common import (
    MAX_STEP_COUNT,
    progress_after,
    read_netlist_reporting_warnings,
    require_count,
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
        help="run a netlist's .tran (or .op) with our MNA engine or ngspice",
        description=(
            "Simulate FILE.cir: its first .tran, or its .op if it has no .tran, with the "
            "built-in MNA engine (default) or ngspice. Writes every node voltage and every "
            "voltage-source current (or only --probe signals) on the engine's own time points."
        ),
    )
    parser.add_argument("netlist", metavar="FILE.cir", help="netlist to simulate")
    parser.add_argument(
        "--engine",
        choices=("builtin", "ngspice"),
        default="builtin",
        help="builtin (default: our MNA solver) or ngspice (the referee, if installed; its CSV "
        "columns come in ngspice's order and include the macromodels' internal source "
        "currents)",
    )
    parser.add_argument(
        "--kernel",
        choices=("auto", "ports", "compiled", "python"),
        default="auto",
        help="builtin engine's transient loop: ports (compiled, Newton on the junction "
        "voltages), compiled (numba, every unknown), python (the reference), or auto (ports up "
        "to 64 junctions, compiled above, where the circuit allows; default)",
    )
    parser.add_argument(
        "--ngspice-timeout",
        type=float,
        default=300.0,
        metavar="SECONDS",
        help="stop ngspice after this long and report it (default 300)",
    )
    parser.add_argument("--csv", metavar="FILE", help="write time,v(node),...,i(vsource),...")
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
        "--max-steps",
        type=int,
        metavar="N",
        help="builtin engine: stop with an error after N attempted time steps (default 2000000)",
    )
    parser.add_argument(
        "--max-wall-time",
        type=float,
        metavar="SECONDS",
        help="builtin engine: stop with an error after this much wall time in the transient "
        "loop (default 600)",
    )
    parser.set_defaults(func=_run_simulate)


def _run_simulate(args: argparse.Namespace) -> int:
    from pathlib import Path

    require_figure_path("--plot", args.plot)
    require_positive("--ngspice-timeout", args.ngspice_timeout)
    require_count("--max-steps", args.max_steps, MAX_STEP_COUNT)
    require_positive("--max-wall-time", args.max_wall_time)
    require_writable(args.csv, args.plot)
    if args.engine == "ngspice":
        from circuitsim.interop.ngspice import run_ngspice

        waves = run_ngspice(Path(args.netlist), probes=args.probe, timeout=args.ngspice_timeout)
    else:
        from circuitsim.solver import SimulationOptions, simulate
        from circuitsim.solver.errors import SolverError

        circuit = read_netlist_reporting_warnings(args.netlist)
        limits = {
            key: value
            for key, value in (
                ("max_steps", args.max_steps),
                ("max_wall_time", args.max_wall_time),
            )
            if value is not None
        }
        try:
            options = SimulationOptions.from_circuit(circuit, kernel=args.kernel, **limits)
            waves = simulate(circuit, options, progress=progress_after(1.0), probes=args.probe)
        except SolverError as exc:  # about the circuit ("D1: no .model ..."): say which file
            exc.args = (f"{args.netlist}: {exc}",)
            raise
    stats = waves.stats
    engine = args.engine
    if "kernel" in stats:  # "ports", or "python (why the compiled kernels do not apply)"
        name, _, why = stats["kernel"].partition(" (")
        engine += f" ({name} kernel: {why[:-1]})" if why else f" ({name} kernel)"
    summary = f"{args.netlist}: {engine}, {len(waves.time)} time point(s)"
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


COMMANDS = [_add_convert, _add_check, _add_simulate]
