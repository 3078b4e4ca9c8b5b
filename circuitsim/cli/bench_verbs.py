"""The bench verb: the model's circuit running live behind a local web page and JSON API."""

from __future__ import annotations

import argparse
import math
import sys

from circuitsim.cli.common import UsageError, progress, require_positive
from circuitsim.cli.scenario_options import (
    add_model_options,
    add_scenario_options,
    check_scenario_options,
    scenario_system,
)
from circuitsim.cli.translator_options import (
    add_knob_options,
    add_translator_options,
    check_translator_options,
    knob_request,
    translator_options,
)


def _add_bench(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "bench",
        help="run the model's circuit live in a browser: knobs, oscilloscope, JSON API",
        description=(
            "Translate the model into its op-amp circuit (the options of generate) and run it "
            "continuously with the builtin engine in short chunks, each from the state the "
            "last one ended in, beside the direct ODE with the same knob history. A local "
            "Bokeh page shows the states in physical units (circuit solid, ODE dashed) and "
            "the running NRMSD, with the knobs (speed as the R33/R44 it sets, forcing, the "
            "flange switch S1, other resistor-realized parameters), a push that sets a state, "
            "pause, rate and export; a JSON API beside it (/api/state, /api/knobs, "
            "/api/set_state, /api/trace, /api/history) drives it from scripts. A knob acts at "
            "the next chunk boundary from the state reached: nothing restarts. With "
            "--speed-range LO:HI, R33 and R44 are fixed parts plus potentiometers and the "
            "speed knob turns their dials over that range. See "
            "docs/bench.md. Ctrl-C stops it."
        ),
    )
    add_model_options(parser)
    add_scenario_options(parser)
    add_translator_options(parser, series="exact")
    add_knob_options(parser)
    parser.add_argument(
        "--tstop",
        type=float,
        metavar="T",
        help="model seconds of the direct solution that sets the scales (> 0; default: the "
        "model file's [circuit] t_stop, else 5)",
    )
    parser.add_argument(
        "--port", type=int, default=5006, metavar="N", help="TCP port (default 5006; 0: any)"
    )
    parser.add_argument(
        "--host",
        default="127.0.0.1",
        metavar="ADDRESS",
        help="address to serve on (default 127.0.0.1: this machine only)",
    )
    parser.add_argument(
        "--rate",
        type=float,
        default=1.0,
        metavar="R",
        help="model seconds per wall second (> 0, default 1: real time; inf: as fast as the "
        "machine runs)",
    )
    parser.add_argument(
        "--chunk",
        type=float,
        default=0.1,
        metavar="SECONDS",
        help="model seconds per chunk: a knob acts within one chunk (> 0, default 0.1)",
    )
    parser.add_argument(
        "--overload",
        type=float,
        metavar="VOLTS",  # default None: bench.running.OVERLOAD_VOLTS, imported by the run
        # (importing the translator here would load scipy.optimize in every verb's process)
        help="stop the clock when a state node passes this |V| (a real op-amp clips there; "
        "> 0, default: a TL074's swing on +/-15 V supplies, 13 V (the translator's "
        "SWING_LIMIT); inf: never, e.g. to follow unbounded growth)",
    )
    parser.add_argument(
        "--no-browser", action="store_true", help="do not open the page in a web browser"
    )
    parser.add_argument(
        "--paused",
        action="store_true",
        help="start with the clock held at t = 0 (resume from the page, or POST /api/run "
        '{"running": true} or {"running": true, "until": T} to run to model time T)',
    )
    parser.set_defaults(func=_run_bench)


def _check_bench(args: argparse.Namespace) -> None:
    check_scenario_options(args)
    check_translator_options(args)
    require_positive("--tstop", args.tstop)
    require_positive("--chunk", args.chunk)
    if args.overload is not None and not args.overload > 0:  # NaN fails; inf is taken
        raise UsageError(f"--overload must be a positive voltage or inf, got {args.overload:g}")
    if not args.rate > 0:  # NaN fails too; inf is taken
        raise UsageError(f"--rate must be a positive number or inf, got {args.rate:g}")
    if not 0 <= args.port <= 65535:
        raise UsageError(f"--port must be between 0 and 65535, got {args.port}")
    if math.isinf(args.chunk):
        raise UsageError("--chunk must be finite")


def _run_bench(args: argparse.Namespace) -> int:
    from circuitsim.bench.knobs import BenchSetup
    from circuitsim.bench.runner import BenchRunner
    from circuitsim.bench.server import bench_server, require_bokeh
    from circuitsim.bench.session import BenchSession

    _check_bench(args)
    require_bokeh()
    model, system = scenario_system(args, with_model=True)
    setup = BenchSetup.from_system(
        model, system, translator_options(args), args.coeffs, knob_request(args, model)
    )
    progress("bench: translating the circuit and finding its knobs")
    overload = {} if args.overload is None else {"overload": args.overload}
    session = BenchSession(setup, chunk=args.chunk, **overload)
    for warning in session.warnings:
        print(f"warning: {warning}", file=sys.stderr, flush=True)
    runner = BenchRunner(session, rate=args.rate, running=not args.paused)
    server = bench_server(runner, args.host, args.port)
    url = f"http://{'localhost' if args.host == '127.0.0.1' else args.host}:{server.port}/"
    knobs = ", ".join(k.name for k in session.knobs)
    print(f"bench: {system.name} at {url} (API: {url}api/state); knobs: {knobs}", flush=True)
    runner.start()
    if not args.no_browser:
        import webbrowser

        webbrowser.open(url)
    try:
        server.io_loop.start()
    finally:
        runner.stop()
        server.stop()
    return 0


COMMANDS = [_add_bench]
