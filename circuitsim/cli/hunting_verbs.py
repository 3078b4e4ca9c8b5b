"""The hunting verb: the bifurcation diagram, speed swept up then down on the ODE and circuit."""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import TYPE_CHECKING

from circuitsim.cli.common import (
    UsageError,
    add_figure_options,
    add_max_step,
    figure_format,
    prepare_output_folder,
    print_warning,
    require_figure_options,
    require_positive,
)
from circuitsim.cli.scenario_options import (
    add_model_options,
    add_scenario_options,
    check_scenario_options,
    scenario_system,
    with_inputs,
)

if TYPE_CHECKING:
    from circuitsim.mechanics.model import Model

DEFAULT_PUSH = 0.005


def _add_hunting(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "hunting",
        help="bifurcation diagram: limit-cycle amplitude against speed, swept up then down",
        description=(
            "The free response from a push (--y0, default 5 mm; every forcing group off unless "
            "--amplitude, --forcing or --input is given) with the speed swept up and then down, "
            "each step starting from the previous step's final state as on a roller rig: on "
            "the ODE (direct solution, exact kinks) and on the circuit (builtin engine: each "
            "step restamps the speed resistors and starts from every unknown the last run ended "
            "with), "
            "flange on and off. Each step runs --settle + --record model seconds; its "
            "amplitude is max |y| over the last --record seconds. Marks the linear critical "
            "speed and, on each path, where the limit cycle appears (up) and vanishes (down). "
            "Writes hunting.csv and hunting.png; progress with ETA on stderr. See "
            "docs/hunting.md."
        ),
    )
    add_model_options(parser)
    add_scenario_options(parser)
    hunting_help = {  # the scenario options whose meaning or default differ here
        "speed": "not used: the speed is swept (--speeds)",
        "y0": "the push: --state's start value, its unit, or the parameter the model's "
        f"[options] table maps y0 to (default {DEFAULT_PUSH:g})",
        "state": "the state pushed (--y0) and measured (default: the model's [options] state; "
        "else, when [options] maps y0, the first state its [initial] table starts away from "
        "rest; else the first state)",
        "flange": "run with the piecewise-linear terms (the flange) on only, or off only "
        "(default: both, one after the other)",
        "forcing": "switch on only this forcing group of the model (repeatable); default: "
        "every group off, the free response",
    }
    for action in parser._actions:
        if action.dest in hunting_help:
            action.help = hunting_help[action.dest]
    parser.add_argument(
        "--parameter",
        metavar="NAME",
        help="the speed-like parameter swept (default: the one the model's [options] table "
        "maps 'speed' to, the wheelset's V)",
    )
    parser.add_argument(
        "--speeds",
        metavar="START:STOP:STEP",
        help="speeds swept up (then down): START:STOP:STEP or an increasing list, at least "
        "two (default: 0.9 to 1.1 times the linear critical speed, about 25 steps)",
    )
    parser.add_argument(
        "--settle", type=float, default=3.0, metavar="T", help="model seconds each step runs "
        "before the amplitude is measured (default 3)"
    )  # fmt: skip
    parser.add_argument(
        "--record", type=float, default=1.0, metavar="T", help="model seconds over which the "
        "amplitude max |y| is measured after --settle (default 1)"
    )  # fmt: skip
    parser.add_argument(
        "--threshold", type=float, metavar="Y", help="smallest steady amplitude counted as a "
        "limit cycle, the state's unit (default: the push)"
    )  # fmt: skip
    parser.add_argument(
        "--bound", type=float, metavar="Y", help="amplitude past which a step counts as "
        "unbounded, the next one starting from the push again (default: 100 times the push)"
    )  # fmt: skip
    parser.add_argument(
        "--repush", type=float, default=0.01, metavar="FRACTION", help="a step whose amplitude "
        "fell below FRACTION times the push hands the push to the next one (a rig's track "
        "keeps disturbing the wheelset; 0: strict continuation; default 0.01)"
    )  # fmt: skip
    parser.add_argument(
        "--no-circuit", action="store_true", help="the ODE path only (no circuit runs)"
    )
    add_max_step(parser)
    parser.add_argument(
        "--out", default=".", metavar="DIR", help="output folder (default .)"
    )  # fmt: skip
    add_figure_options(parser, "hunting.png")
    parser.set_defaults(func=_run_hunting)


class _Eta:
    """Progress with ETA on stderr: a line at every tenth of the steps (each step on a
    terminal, redrawn in place)."""

    def __init__(self) -> None:
        self.began = time.perf_counter()
        self.tenths = -1
        self.open = False

    def __call__(self, done: int, total: int, message: str) -> None:
        elapsed = time.perf_counter() - self.began
        eta = elapsed / done * (total - done) if done else math.nan
        text = f"{done}/{total} steps ({100 * done / total:.0f}%), {message}; "
        text += f"elapsed {elapsed:.0f} s, ETA {eta:.0f} s"
        if sys.stderr.isatty():
            print(f"\r{text[:100]:100s}", end="", file=sys.stderr, flush=True)
            self.open = True
            return
        tenths = int(10 * done / total)
        if tenths > self.tenths:
            self.tenths = tenths
            print(text, file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.open:
            print(file=sys.stderr, flush=True)


def _speed_parameter(model: Model, name: str | None) -> str:
    if name is None:
        if "speed" not in model.options:
            raise UsageError(
                f"model {model.name} maps no 'speed' in its [options] table: name the "
                "parameter to sweep with --parameter NAME"
            )
        return model.options["speed"]
    if name in model.options:
        return model.options[name]
    if name not in model.parameters:
        raise UsageError(
            f"--parameter {name}: model {model.name} has no such parameter (known: "
            f"{', '.join(model.parameters)})"
        )
    return name


def _default_speeds(critical: float | None):
    import numpy as np

    if critical is None:
        raise UsageError("give --speeds: the linear part does not lose stability to centre on")
    raw = 0.2 * critical / 24
    step = 10 ** math.floor(math.log10(raw))
    step *= min((1, 2, 5, 10), key=lambda m: abs(m * step - raw))
    start = math.floor(0.9 * critical / step) * step
    stop = math.ceil(1.1 * critical / step) * step
    return start + step * np.arange(int(round((stop - start) / step)) + 1)


def _run_hunting(args: argparse.Namespace) -> int:
    from circuitsim.mechanics import ModelError, critical_speed, load_model
    from circuitsim.studies.hunting import run_hunting, speed_grid
    from circuitsim.studies.hunting_plot import save_hunting
    from circuitsim.studies.hunting_result import HuntingError, HuntingSettings

    check_scenario_options(args)
    for option in ("settle", "record", "threshold", "bound"):
        require_positive(f"--{option}", getattr(args, option))
    require_positive("--max-step", args.max_step)
    if not (math.isfinite(args.repush) and 0 <= args.repush < 1):
        raise UsageError(f"--repush must be in [0, 1), got {args.repush:g}")
    require_figure_options(args)
    fmt = figure_format(args)
    model = with_inputs(args, load_model(args.model))
    name = _speed_parameter(model, args.parameter)
    fixed = dict(args.param)
    if args.speed is not None or name in fixed:
        raise UsageError(f"{name} is swept (--speeds): do not fix it with --speed or --param")
    unit = model.parameter_info[name].unit
    coefficients = args.coeffs or model.default_coefficients
    try:
        linear, _ = critical_speed(model, coefficients, parameter=name, parameters=fixed or None)
    except ModelError as exc:
        print_warning(f"no linear critical {name}: {exc}")
        linear = None
    try:
        speeds = _default_speeds(linear) if args.speeds is None else speed_grid(args.speeds)
    except HuntingError as exc:
        raise UsageError(str(exc)) from None
    if args.y0 is None:
        args.y0 = DEFAULT_PUSH
    free = args.amplitude is None and not args.forcing and not args.input
    flanges = [True, False] if args.flange is None else [args.flange]
    if not model.nonlinear_terms:
        flanges = [False]

    def system_at(speed: float, flange: bool):
        switches = {n: flange for n in model.nonlinear_terms}
        if free:  # the free response: every forcing group off
            parameters = {**_y0(model, args), **fixed, name: speed}
            forcing = {n: False for n in model.forcing_terms}
            return model.system(coefficients, parameters, switches, _x0(model, args), forcing)
        scenario = argparse.Namespace(**vars(args))
        scenario.param = [*args.param, (name, speed)]
        scenario.flange = flange if model.nonlinear_terms else None
        return scenario_system(scenario, model=model)

    prepare_output_folder("--out", args.out, "hunting.csv", f"hunting.{fmt}")
    settings = HuntingSettings(
        settle=args.settle, record=args.record, threshold=args.threshold or 0.0,
        bound=args.bound or math.inf, repush=args.repush, max_step=args.max_step,
    )  # fmt: skip
    state = _pushed_state(model, args, lambda: system_at(float(speeds[0]), flanges[0]))
    bar = _Eta()
    try:
        result = run_hunting(
            system_at, speeds, name, unit, settings, flanges, not args.no_circuit, linear, bar,
            state,
        )  # fmt: skip
    except HuntingError as exc:
        raise UsageError(str(exc)) from None
    finally:
        bar.close()
    paths = save_hunting(result, args.out, fmt=fmt, dpi=args.dpi)
    _summary(result, len(speeds))
    for path in paths:
        print(f"wrote {path}")
    return 0


def _y0(model: Model, args: argparse.Namespace) -> dict:
    return model.option_parameters({"y0": args.y0}) if "y0" in model.options else {}


def _x0(model: Model, args: argparse.Namespace):
    return None if "y0" in model.options else {model.state_named(args.state): args.y0}


def _pushed_state(model: Model, args: argparse.Namespace, probe) -> str:
    """``--state``, else the model's ``[options] state``; else, where ``--y0`` sets a
    parameter (``[options] y0``), the first state the scenario starts away from rest (its
    ``[initial]`` table places the push); else the first state."""
    from circuitsim.mechanics import ModelError

    if args.state is not None or "state" in model.options or "y0" not in model.options:
        return model.state_named(args.state)
    try:
        x0 = probe().x0
    except ModelError:  # run_hunting says so, naming the speed
        return model.default_state
    moved = [s for s, v in zip(model.states, x0, strict=True) if v] if x0 is not None else []
    return moved[0] if moved else model.default_state


def _summary(result, count: int) -> None:
    def speed(value) -> str:
        return "none" if value is None else f"{value:g}"

    unit = result.unit
    linear = "none" if result.linear_critical is None else f"{result.linear_critical:.4f}"
    print(f"linear critical {result.parameter}: {linear} {unit}")
    for flange in sorted({b.flange for b in result.branches}, reverse=True):
        for path in ("ode", "circuit"):
            if result.branch(path, "up", flange) is None:
                continue
            up, down = result.critical(path, flange)
            grows_up, grows_down = result.onset(path, flange)
            print(
                f"flange {'on' if flange else 'off'}, {path}: limit cycle appears at "
                f"{speed(up)} (up), vanishes below {speed(down)} (down) {unit}; motion "
                f"stops decaying from {speed(grows_up)} (up), {speed(grows_down)} (down)"
            )
        for direction in ("up", "down"):
            agreement = result.agreement(direction, flange)
            if agreement is not None:
                print(
                    f"flange {'on' if flange else 'off'}, {direction}: circuit vs ode "
                    f"amplitude max abs difference {agreement['max_abs']:.3g} "
                    f"{result.state_unit}, NRMSD {100 * agreement['nrmsd']:.3g} % over "
                    f"{agreement['steps']} bounded steps"
                )
    timings = ", ".join(f"{k} {v:.3g} s" for k, v in result.timings.items())
    print(f"{count} speeds: {timings}")


COMMANDS = [_add_hunting]
