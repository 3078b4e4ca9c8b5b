"""The tolerance verb: Monte Carlo over part tolerances and op-amp offsets."""

from __future__ import annotations

import argparse
import json
import math

from circuitsim.cli.circuit_verbs import TSTOP_HELP
from circuitsim.cli.common import (
    KERNEL_WORDS,
    UsageError,
    add_figure_options,
    add_jobs_option,
    add_max_step,
    figure_format,
    prepare_output_folder,
    progress_after,
    require_count,
    require_figure_options,
    require_jobs,
    require_positive,
)
from circuitsim.cli.scenario_options import (
    add_model_options,
    add_scenario_options,
    check_scenario_options,
    scenario_system,
)
from circuitsim.netlist.values import parse_value


def fraction(text: str) -> float:
    """``1%`` or ``0.01``: a relative tolerance in [0, 1).

    Raises
    ------
    argparse.ArgumentTypeError
        Not a number, negative, or 100 % and more.
    """
    stripped = text.strip()
    try:
        value = float(stripped[:-1]) / 100 if stripped.endswith("%") else float(stripped)
        if not (math.isfinite(value) and 0 <= value < 1):
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a tolerance like 1% or 0.01 (at least 0, below 100 %), got {text!r}"
        ) from None
    return value


def volts(text: str) -> float:
    """``3m`` or ``0.003``: volts >= 0."""
    try:
        value = parse_value(text)
        if not (math.isfinite(value) and value >= 0):
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected an offset in volts >= 0 like 3m, got {text!r}"
        ) from None
    return value


def seed(text: str) -> int:
    """``--seed``: an integer >= 0 (numpy's generators take no negative seed)."""
    try:
        value = int(text)
        if value < 0:
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    return value


def _add_tolerance(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "tolerance",
        help="Monte Carlo over resistor/capacitor tolerances and op-amp offsets",
        description=(
            "Generate the circuit once, then draw N circuits whose every resistor and capacitor "
            "is off by its own error within the tolerance (uniform: U(-t, t); gaussian: the "
            "tolerance is 3 sigma) and, with --offset, every TL074 section has its own input "
            "offset (uniform: U(-v, v); gaussian: sigma v). For each: the realized linear part "
            "read back from the circuit and its critical speed (cheap), and, unless "
            "--no-simulate, a simulation (builtin engine, --jobs threads) compared with the "
            "ODE: %%NRMSD, peak and frequency ratio per state and whether all are within the "
            "reproduce thresholds (the yield). Seeded (--seed): the same seed draws the same "
            "circuits. Writes tolerance.json and tolerance.png (histograms) into --out. See "
            "docs/tolerances.md."
        ),
    )
    add_model_options(parser)
    add_scenario_options(parser)
    parser.add_argument(
        "--opamp", choices=("ideal", "tl074"), default="ideal", help="op-amp model (default ideal)"
    )
    parser.add_argument(
        "--scaling",
        choices=("auto", "unity"),
        default="auto",
        help="amplitude scaling of the nominal circuit (default auto; unity: 1 V per SI unit)",
    )
    parser.add_argument(
        "--series",
        choices=("exact", "E96", "E24"),
        default="E96",
        help="nominal resistor values (default E96, what a build orders)",
    )
    parser.add_argument(
        "--resistor-tolerance", type=fraction, default=0.01, metavar="TOL",
        help="resistor tolerance, e.g. 1%% or 0.01 (default 1%%)",
    )  # fmt: skip
    parser.add_argument(
        "--capacitor-tolerance", type=fraction, default=0.05, metavar="TOL",
        help="capacitor tolerance (default 5%%)",
    )  # fmt: skip
    parser.add_argument(
        "--offset", type=volts, default=0.0, metavar="VOLTS",
        help="input offset size of every TL074 section, e.g. 3m (the datasheet typical); "
        "needs --opamp tl074 (default 0: none)",
    )  # fmt: skip
    parser.add_argument(
        "--distribution", choices=("uniform", "gaussian"), default="uniform",
        help="uniform within the tolerance (default), or gaussian with the tolerance as 3 "
        "sigma (an offset as 1 sigma)",
    )  # fmt: skip
    parser.add_argument(
        "-n", "--samples", type=int, default=100, metavar="N",
        help="circuits drawn (default 100)",
    )  # fmt: skip
    parser.add_argument(
        "--seed", type=seed, default=0, help="random seed, an integer >= 0 (default 0)"
    )
    parser.add_argument(
        "--no-simulate", dest="simulate", action="store_false",
        help="the realized critical speeds only (no simulation, no yield)",
    )  # fmt: skip
    parser.add_argument("--tstop", type=float, metavar="T", help=TSTOP_HELP)
    add_max_step(parser)
    add_jobs_option(parser, "simulations at a time (threads; default: every core)", None)
    parser.add_argument(
        "--out", default="tolerance", metavar="FOLDER",
        help="output folder for tolerance.json and tolerance.png (default ./tolerance)",
    )  # fmt: skip
    add_figure_options(parser, "the histograms (tolerance.png)")
    parser.set_defaults(func=_run_tolerance)


def _run_tolerance(args: argparse.Namespace) -> int:
    import os

    from circuitsim.studies.tolerance import Tolerances, plot_tolerance, run_tolerance
    from circuitsim.synthesis.options import SynthesisOptions

    check_scenario_options(args)
    require_count("--samples", args.samples, 1_000_000)
    require_positive("--tstop", args.tstop)
    require_positive("--max-step", args.max_step)
    require_figure_options(args)
    figure = f"tolerance.{figure_format(args)}"
    if args.jobs is None:
        args.jobs = os.cpu_count() or 1
    require_jobs(args)
    if args.offset and args.opamp != "tl074":
        raise UsageError("--offset needs --opamp tl074 (the ideal op-amp has no input offset)")
    if (
        args.distribution == "gaussian"
        and max(args.resistor_tolerance, args.capacitor_tolerance) >= 0.3
    ):
        raise UsageError("gaussian tolerances must be below 30 % (3 sigma below 100 %)")
    folder = prepare_output_folder("--out", args.out, "tolerance.json", figure)
    model, system = scenario_system(args, with_model=True)
    state = model.state_named(args.state)
    tolerances = Tolerances(
        args.resistor_tolerance, args.capacitor_tolerance, args.offset, args.distribution
    )
    options = SynthesisOptions(
        opamp=args.opamp, scaling=args.scaling, series=args.series, t_stop=args.tstop
    )
    report = progress_after(0.0)
    last = {"phase": "", "fraction": -1.0}

    def progress(fraction_done: float, message: str) -> None:
        phase = message.split(" ", 1)[0]  # "realized", "simulated": each phase from its start
        if phase != last["phase"]:
            last.update(phase=phase, fraction=-1.0)
        if fraction_done >= 1.0 or fraction_done - last["fraction"] >= 0.1:  # ten lines a phase
            last["fraction"] = fraction_done
            report(f"tolerance: {message}")

    result = run_tolerance(
        system, tolerances, args.samples, args.seed, options, args.simulate,
        workers=args.jobs, progress=progress, max_step=args.max_step,
    )  # fmt: skip
    json_path, png_path = folder / "tolerance.json", folder / figure
    from circuitsim.atomic import write_text_atomic

    write_text_atomic(json_path, json.dumps(result.to_json(), indent=1) + "\n")
    plot_tolerance(result, png_path, state, dpi=args.dpi)
    _print_summary(result)
    print(f"wrote {json_path}")
    print(f"wrote {png_path}")
    return 0


def _print_summary(result) -> None:
    """The distributions' statistics, one line each, and the yield."""
    tol = result.tolerances
    print(
        f"{result.n} circuits, seed {result.seed}: resistors {100 * tol.resistor:g} %, "
        f"capacitors {100 * tol.capacitor:g} %, offsets {1e3 * tol.offset:g} mV "
        f"({tol.distribution})"
    )
    summary = result.summary()

    def line(label: str, d: dict, fmt: str) -> str:
        if not d.get("count"):
            return f"{label:<28} none"
        spread = " ".join(f"{k} {d[k]:{fmt}}" for k in ("min", "p5", "p50", "p95", "max"))
        missing = f" ({d['not_finite']} without)" if d["not_finite"] else ""
        return f"{label:<28} mean {d['mean']:{fmt}} std {d['std']:.3g}  {spread}{missing}"

    model = result.critical_speed_model
    print(f"critical speed (model {model:.4f})" if model is not None else "critical speed")
    print(line("  realized", summary["critical_speed"], ".4f"))
    if result.unstable_fraction is not None:
        print(
            f"  at or below the simulated speed {result.speed:g} {result.speed_unit}: "
            f"{100 * result.unstable_fraction:.1f} % of the circuits (their linear part grows)"
        )
    for state in result.metrics:
        for name, label in (("nrmsd_percent", "NRMSD %"), ("peak_ratio", "peak ratio"),
                            ("frequency_ratio", "frequency ratio")):  # fmt: skip
            print(line(f"  {state} {label}", summary[state][name], ".4g"))
    if result.yield_fraction is not None:
        th = result.thresholds
        print(
            f"yield: {100 * result.yield_fraction:.1f} % within NRMSD <= {th.nrmsd_percent:g} %, "
            f"|peak ratio - 1| <= {th.peak_ratio_tolerance:g}, |frequency ratio - 1| <= "
            f"{th.frequency_ratio_tolerance:g} (every state)"
        )
    times = ", ".join(f"{k} {v:.3g} s" for k, v in result.timings.items())
    kernel = "" if result.kernel is None else f" (builtin, {KERNEL_WORDS[result.kernel]})"
    print(f"times{kernel}: {times}")


COMMANDS = [_add_tolerance]
