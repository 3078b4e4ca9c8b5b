"""``circuitsim frf``: the model's frequency response against its circuit's ``.ac``."""

from __future__ import annotations

import argparse
import json
import math
import sys

from circuitsim.cli.common import (
    UsageError,
    add_figure_options,
    add_ngspice_timeout,
    figure_format,
    plot_target,
    require_figure_options,
    require_figure_path,
    require_positive,
    require_writable,
)
from circuitsim.cli.scenario_options import add_model_options, add_scenario_options, scenario_system
from circuitsim.cli.translator_options import add_translator_options, check_translator_options
from circuitsim.cli.translator_options import translator_options as synthesis_options


def _add_frf(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "frf",
        help="frequency response of the model and of its circuit (.ac), state by state",
        description=(
            "The model's transfer functions from each forcing input to each state, from the "
            "state matrix of one region of its piecewise-linear field (default: around the "
            "zero state, e.g. inside the wheelset's flange clearance), against the generated "
            "circuit's small-signal .ac on each engine, mapped back through the scale map and "
            "the time scale. Prints per transfer function the resonance peaks read off both "
            "(frequency, half-power damping ratio), the worst difference in dB and degrees "
            "and the lowest model frequency where the circuit is beyond --max-db or "
            "--max-degrees. Exit code 1 when a circuit is beyond either anywhere in the sweep. "
            "See docs/frf.md."
        ),
    )
    add_model_options(parser)
    add_scenario_options(parser)
    add_translator_options(parser, series="exact")
    parser.add_argument(
        "--tstop",
        type=float,
        metavar="T",
        help="model seconds of the direct solution whose peaks set the circuit's scaling "
        "(default: the model's [circuit] t_stop, else 5)",
    )
    parser.add_argument("--fmin", type=float, default=0.1, help="lowest model frequency, Hz")
    parser.add_argument("--fmax", type=float, default=100.0, help="highest model frequency, Hz")
    parser.add_argument(
        "--points-per-decade", type=int, default=20, metavar="N", help="sweep density (20)"
    )
    parser.add_argument(
        "--engine",
        choices=("builtin", "ngspice"),
        action="append",
        help="circuit engine(s) (repeatable; default builtin, and ngspice where installed)",
    )
    add_ngspice_timeout(parser)
    parser.add_argument(
        "--region",
        action="append",
        default=[],
        metavar="STATE=VALUE",
        help="a state's value (SI units) inside the region to linearize in (repeatable; "
        "other states 0)",
    )
    parser.add_argument("--max-db", type=float, default=0.1, help="allowed |dB| (0.1)")
    parser.add_argument("--max-degrees", type=float, default=1.0, help="allowed |deg| (1)")
    parser.add_argument("--csv", metavar="FILE", help="write frequency and each |H|, phase")
    parser.add_argument(
        "--plot",
        metavar="FILE.png",
        help="Bode figure per input (FILE-INPUT.png when the model has several inputs)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    add_figure_options(parser, "the --plot figures")
    parser.set_defaults(func=_run_frf)


def _region(args: argparse.Namespace, system):
    import numpy as np

    x = np.zeros(system.n)
    for text in args.region:
        name, sep, value = text.partition("=")
        if not sep or name.strip() not in system.states:
            raise UsageError(
                f"--region {text!r}: expected STATE=VALUE with STATE one of "
                f"{', '.join(system.states)}"
            )
        try:
            x[system.states.index(name.strip())] = float(value)
        except ValueError:
            raise UsageError(f"--region {text!r}: {value!r} is not a number") from None
    return x


def _engines(args: argparse.Namespace) -> list[str]:
    if args.engine:
        return list(dict.fromkeys(args.engine))
    from circuitsim.compare.case import engine_available

    return ["builtin"] + (["ngspice"] if engine_available("ngspice") is None else [])


def _check(args: argparse.Namespace) -> None:
    check_translator_options(args)
    for option in ("tstop", "fmin", "fmax", "max_db", "max_degrees"):
        require_positive("--" + option.replace("_", "-"), getattr(args, option))
    if not args.fmax > args.fmin:
        raise UsageError("--fmax must be above --fmin")
    if not 1 <= args.points_per_decade <= 1000:
        raise UsageError("--points-per-decade must be from 1 to 1000")
    require_figure_path("--plot", args.plot)
    require_figure_options(args)
    args.plot = plot_target("--plot", args.plot, args)
    require_writable(args.csv, args.plot)


def _run_frf(args: argparse.Namespace) -> int:
    from circuitsim.compare.frf import circuit_response, model_response
    from circuitsim.mechanics.frf import region_modes
    from circuitsim.netlist.circuit import AcSweep
    from circuitsim.synthesis import synthesize

    _check(args)
    system = scenario_system(args)
    region = _region(args, system)
    sweep = AcSweep("dec", args.points_per_decade, args.fmin, args.fmax)
    responses = {"model": model_response(system, sweep, region)}
    synthesis = synthesize(system, synthesis_options(args))
    for engine in _engines(args):
        responses[engine] = circuit_response(
            synthesis, system, sweep, engine, ngspice_timeout=args.ngspice_timeout
        )
    summary = _summary(responses, args)
    summary["time_scale"] = synthesis.scale_map.time_scale
    summary["modes"] = [
        {"frequency_hz": m.natural_frequency, "damping_ratio": m.damping_ratio}
        for m in region_modes(system, region)
    ]
    if args.csv:
        _write_csv(args.csv, responses)
    if args.plot:
        _plot(args.plot, responses, args.dpi)
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        _print(summary, responses["model"], args)
    if args.csv and not args.json:
        print(f"wrote {args.csv}")
    return 1 if summary["beyond"] else 0


def _summary(responses: dict, args: argparse.Namespace) -> dict:
    import numpy as np

    from circuitsim.compare.frf import departure, differences, resonances

    model = responses["model"]
    f = model.frequencies
    rows, beyond = [], False
    for i, name in enumerate(model.inputs):
        for j, state in enumerate(model.states):
            h = model.response[i, j]
            if not np.any(np.abs(h) > 0):
                continue
            row = {"input": name, "state": state, "model": _peaks(resonances(f, h))}
            for engine, response in responses.items():
                if engine == "model":
                    continue
                c = response.response[i, j]
                d_db, d_deg = differences(h, c)
                where = departure(f, h, c, args.max_db, args.max_degrees)
                beyond = beyond or where is not None
                row[engine] = {
                    "peaks": _peaks(resonances(f, c)),
                    "worst_db": float(np.nanmax(np.abs(d_db))),
                    "worst_degrees": float(np.nanmax(np.abs(d_deg))),
                    "departs_at_hz": where,
                }
            rows.append(row)
    return {"frequencies": [float(f[0]), float(f[-1]), int(f.size)], "rows": rows,
            "beyond": beyond}  # fmt: skip


def _peaks(found) -> list[dict]:
    return [
        {"frequency_hz": r.frequency, "magnitude": r.magnitude, "damping_ratio": r.damping_ratio}
        for r in found
    ]


def _print(summary: dict, model, args: argparse.Namespace) -> None:
    low, high, count = summary["frequencies"]
    print(
        f"frf: {low:g} .. {high:g} Hz of model time ({count} frequencies), time scale "
        f"{summary['time_scale']:g}"
    )
    modes = ", ".join(
        f"{m['frequency_hz']:.4g} Hz (zeta {m['damping_ratio']:.3g})" for m in summary["modes"]
    )
    print(f"region modes: {modes or 'none oscillating'}")
    for row in summary["rows"]:
        print(f"{row['input']} -> {row['state']}: model {_peak_text(row['model'])}")
        for engine in (k for k in row if k not in ("input", "state", "model")):
            r = row[engine]
            where = r["departs_at_hz"]
            beyond = (
                f"beyond {args.max_db:g} dB / {args.max_degrees:g} deg from {where:.4g} Hz"
                if where is not None
                else f"within {args.max_db:g} dB / {args.max_degrees:g} deg over the sweep"
            )
            print(
                f"  {engine}: {_peak_text(r['peaks'])}; worst {r['worst_db']:.2g} dB, "
                f"{r['worst_degrees']:.2g} deg; {beyond}"
            )


def _peak_text(peaks: list[dict]) -> str:
    if not peaks:
        return "no peak"
    parts = []
    for p in peaks:
        zeta = "" if math.isnan(p["damping_ratio"]) else f", zeta {p['damping_ratio']:.4g}"
        parts.append(f"peak {p['frequency_hz']:.5g} Hz{zeta}")
    return "; ".join(parts)


def _write_csv(path: str, responses: dict) -> None:
    import numpy as np

    from circuitsim.atomic import write_text_atomic

    model = responses["model"]
    header, columns = ["frequency"], [model.frequencies]
    for source, response in responses.items():
        for i, name in enumerate(model.inputs):
            for j, state in enumerate(model.states):
                h = response.response[i, j]
                header += [f"{source}:{name}:{state}:mag", f"{source}:{name}:{state}:deg"]
                columns += [np.abs(h), np.degrees(np.angle(h))]
    table = np.column_stack(columns)
    lines = [",".join(header)] + [",".join(f"{v:.17g}" for v in row) for row in table]
    write_text_atomic(path, "\n".join(lines) + "\n")


def _plot(path: str, responses: dict, dpi: float) -> None:
    from pathlib import Path

    from circuitsim.compare.frf_plot import plot_frf

    inputs = responses["model"].inputs
    for name in inputs:
        target = Path(path)
        if len(inputs) > 1:
            target = target.with_name(f"{target.stem}-{name}{target.suffix}")
        plot_frf(responses, name, target, dpi=dpi)
        print(f"wrote {target}", file=sys.stderr)


def _add_stepped_sine(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "stepped-sine",
        help="nonlinear response curves: forcing frequency stepped up then down, ODE and circuit",
        description=(
            "As on a shaker: the forcing frequency steps up through --freqs, each step "
            "starting from the previous step's final state, then back down from the top's; "
            "each step runs --settle + --record model seconds and its amplitude is max "
            "|state| over the last --record seconds; on the ODE (direct solution) and on the "
            "circuit (builtin engine, each step restamps the generators and starts from every "
            "unknown the last run ended with). Prints the jump frequencies of each path and "
            "direction (a step whose amplitude changes by more than 1.5 times) and the "
            "circuit's largest amplitude difference. Writes stepped_sine.csv and "
            "stepped_sine.png. See docs/frf.md."
        ),
    )
    add_model_options(parser)
    add_scenario_options(parser)
    parser.add_argument(
        "--freqs",
        required=True,
        metavar="START:STOP:STEP",
        help="forcing frequencies, Hz of model time: START:STOP:STEP or an increasing list",
    )
    parser.add_argument(
        "--settle", type=float, default=10.0, metavar="T",
        help="model seconds each step runs before the amplitude is measured (default 10)",
    )  # fmt: skip
    parser.add_argument(
        "--record", type=float, default=2.0, metavar="T",
        help="model seconds over which the amplitude is measured (default 2)",
    )  # fmt: skip
    parser.add_argument("--no-circuit", action="store_true", help="the ODE path only")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    parser.add_argument("--out", default=".", metavar="DIR", help="output folder (default .)")
    add_figure_options(parser, "stepped_sine's figure")
    parser.set_defaults(func=_run_stepped_sine)


def _run_stepped_sine(args: argparse.Namespace) -> int:
    from circuitsim.cli.common import prepare_output_folder
    from circuitsim.cli.hunting_verbs import _Eta
    from circuitsim.cli.scenario_options import check_scenario_options
    from circuitsim.mechanics import load_model
    from circuitsim.studies.hunting import speed_grid
    from circuitsim.studies.hunting_result import HuntingError, HuntingSettings
    from circuitsim.studies.stepped_sine import plot_response_curves, run_stepped_sine, summary

    check_scenario_options(args)
    require_positive("--settle", args.settle)
    require_positive("--record", args.record)
    require_figure_options(args)
    figure = f"stepped_sine.{figure_format(args)}"
    if args.freq is not None:
        raise UsageError("the forcing frequency is stepped (--freqs): do not fix it with --freq")
    model = load_model(args.model)
    if "freq" not in model.options:
        raise UsageError(
            f"model {model.name} maps no 'freq' in its [options] table: no forcing frequency "
            "to step"
        )
    try:
        frequencies = speed_grid(args.freqs, "--freqs")
    except HuntingError as exc:
        raise UsageError(str(exc)) from None
    flanges = [True] if args.flange is None else [args.flange]
    if not model.nonlinear_terms:
        flanges = [False]

    def system_at(frequency: float, flange: bool):
        scenario = argparse.Namespace(**vars(args))
        scenario.freq = frequency
        scenario.flange = flange if model.nonlinear_terms else None
        return scenario_system(scenario, model=model)

    folder = prepare_output_folder("--out", args.out, "stepped_sine.csv", figure)
    settings = HuntingSettings(settle=args.settle, record=args.record, repush=0.0)
    bar = _Eta()
    try:
        result = run_stepped_sine(
            system_at, frequencies, settings, flanges, not args.no_circuit, bar,
            args.state or model.default_state,
        )  # fmt: skip
    except HuntingError as exc:
        raise UsageError(str(exc)) from None
    finally:
        bar.close()
    from circuitsim.atomic import write_text_atomic

    write_text_atomic(folder / "stepped_sine.csv", result.csv_text())
    plot_response_curves(result, folder / figure, args.dpi)
    data = summary(result)
    if args.json:
        print(json.dumps(data, indent=1))
    else:
        for flange, entry in data["flange"].items():
            print(f"piecewise-linear terms {flange}:")
            for key, value in entry.items():
                if key.endswith("_jumps_hz"):
                    jumps = ", ".join(f"{v:.6g} Hz" for v in value) or "none"
                    print(f"  {key[: -len('_jumps_hz')].replace('_', ' ')}: jumps at {jumps}")
                elif not math.isnan(value):
                    print(f"  {key.replace('_', ' ')}: {100 * value:.3g} % at most")
    for name in ("stepped_sine.csv", figure):
        print(f"wrote {folder / name}", file=sys.stderr if args.json else sys.stdout)
    return 0


COMMANDS = [_add_frf, _add_stepped_sine]
