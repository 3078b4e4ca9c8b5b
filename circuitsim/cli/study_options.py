"""The sweep verb's grid and cluster options: --param NAME --values ... (several), --grid FILE,
--scheduler, --batch-size, --retries; the grid's runner and its summary."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from typing import TYPE_CHECKING

from circuitsim.cli.common import KERNEL_WORDS, UsageError, print_warning

if TYPE_CHECKING:
    from circuitsim.mechanics.model import Model
    from circuitsim.studies.grid import ParameterGrid


def add_scheduler_options(parser: argparse.ArgumentParser) -> None:
    """--scheduler, --batch-size and --retries (a Dask cluster runs the variants)."""
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run the variants on a Dask distributed cluster (builtin engine; needs pip "
        "install circuitsim[cluster]): a scheduler's address (tcp://HOST:8786; its workers "
        "need circuitsim installed), or local[:N] for a LocalCluster of N worker processes "
        "on this machine (default N: the CPU count). Each task is a batch of variants; the "
        "results equal the in-process run's. Without it: in-process threads (--jobs)",
    )
    parser.add_argument(
        "--batch-size",
        type=int,
        metavar="N",
        help="variants per cluster task (default: four batches per worker, at most 64 "
        "variants each)",
    )
    parser.add_argument(
        "--retries",
        type=int,
        default=2,
        metavar="N",
        help="further tries of a cluster batch that raised (default 2); a batch whose worker "
        "died is rescheduled by Dask (the scheduler's allowed-failures)",
    )


def check_scheduler_options(args: argparse.Namespace) -> None:
    """Refuse a cluster option without --scheduler, a bad count, or --engine ngspice."""
    if args.scheduler is None:
        given = [o for o, v in (("--batch-size", args.batch_size),) if v is not None]
        if given:
            raise UsageError(f"{given[0]} needs --scheduler (a Dask cluster runs the batches)")
        return
    if args.engine != "builtin":
        raise UsageError("--scheduler runs the builtin engine only (not --engine ngspice)")
    if args.batch_size is not None and args.batch_size < 1:
        raise UsageError(f"--batch-size {args.batch_size}: expected at least 1")
    if args.retries < 0:
        raise UsageError(f"--retries {args.retries}: expected 0 or more")
    from circuitsim.studies.errors import StudyError
    from circuitsim.studies.execution import parse_scheduler

    try:
        parse_scheduler(args.scheduler)
    except StudyError as exc:
        raise UsageError(str(exc)) from None


@contextlib.contextmanager
def executor_for(args: argparse.Namespace) -> Iterator:
    """The Dask executor of --scheduler (its client closed, with a LocalCluster, on
    leaving), or None (in-process)."""
    if args.scheduler is None:
        yield None
        return
    from circuitsim.studies.execution import DaskExecutor, dask_client

    with dask_client(args.scheduler) as client:
        yield DaskExecutor(client, batch_size=args.batch_size, retries=args.retries)


def parameter_of(model: Model, label: str) -> str:
    """The model parameter a name on the command line or in a grid's header means: an
    option's (speed: V) or its own. UsageError for an unknown name."""
    if label in model.options:
        return model.options[label]
    if label in model.parameters:
        return label
    options = ", ".join(model.options) or "none"
    raise UsageError(
        f"--param {label}: model {model.name} has no parameter {label!r}; "
        f"known: {', '.join(model.parameters)} (or the options {options})"
    )


def swept_grid(args: argparse.Namespace, model: Model, swept: list[str]) -> ParameterGrid:
    """The variants: --grid FILE's sets, or the full grid of --param NAME --values pairs."""
    from circuitsim.compare.errors import ComparisonError
    from circuitsim.compare.values import parse_values
    from circuitsim.studies.errors import StudyError
    from circuitsim.studies.grid import full_grid, read_grid_csv

    if args.grid is not None:
        if swept or args.values:
            raise UsageError("--grid FILE gives the parameter sets: drop --param NAME --values")

        def resolve(label: str) -> tuple[str, str]:
            try:
                name = parameter_of(model, label)
            except UsageError as exc:
                raise KeyError(str(exc).removeprefix(f"--param {label}: ")) from None
            return name, model.parameter_info[name].unit

        return read_grid_csv(args.grid, resolve)
    if not swept:
        raise UsageError("name a parameter to sweep (--param NAME --values ...) or give --grid")
    if len(args.values) != len(swept):
        raise UsageError(
            f"{len(swept)} swept --param NAME and {len(args.values)} --values: give one "
            "--values per swept parameter, in the same order"
        )
    names = [parameter_of(model, label) for label in swept]
    try:
        axes = [parse_values(text) for text in args.values]
        return full_grid(names, [model.parameter_info[n].unit for n in names], axes)
    except (ComparisonError, StudyError) as exc:  # a bad option value: exit 2
        raise UsageError(str(exc)) from None


def critical_curve(args: argparse.Namespace, model: Model, grid: ParameterGrid, fixed):
    """For a full grid of the speed and one other parameter: the linear critical speed at each
    of the other's values (a value without one is left out), else None."""
    import numpy as np

    from circuitsim.mechanics import ModelError, critical_speed

    speed = model.options.get("speed")
    if grid.axes is None or len(grid.names) != 2 or speed not in grid.names:
        return None
    other = 1 - grid.names.index(speed)
    axis = grid.axes[other]
    values, critical = [], []
    # finer than the grid's axis (each point is an eigenvalue scan: milliseconds)
    for value in np.union1d(axis, np.linspace(axis.min(), axis.max(), 41)):
        parameters = {**dict(fixed), grid.names[other]: float(value)}
        try:
            found, _ = critical_speed(
                model, args.coeffs or model.default_coefficients, speed, parameters=parameters
            )
        except ModelError:
            continue
        values.append(float(value))
        critical.append(found)
    if not values:
        return None
    return speed, np.array(values), np.array(critical)


def report_grid(result, grid: ParameterGrid, paths, executor) -> None:
    """The grid run's summary on stdout and its warnings on stderr."""
    sweep = result.sweep
    for warning in sweep.warnings:
        print_warning(warning)
    total = len(grid)
    simulation = sweep.timings["simulation"]
    where = "in-process" if executor is None else executor.label
    where += "".join(f", {KERNEL_WORDS.get(k, k)}" for k in sweep.stats.get("kernels", ()))
    shared = sweep.stats.get("shared_start")
    own = "" if shared is None else (
        f"; {shared} from the base circuit's shared start (resistor changes), "
        f"{total - shared} assembled on their own (their capacitors, sources, other elements "
        "or time step differ from the base's)"
    )  # fmt: skip
    kernels = sweep.timings.get("kernels")
    ready = "" if kernels is None else f", compiled kernels ready {kernels:.3g} s"
    shape = " x ".join(map(str, grid.shape)) + " = " if grid.shape else ""
    print(
        f"{shape}{total} variants of {', '.join(grid.names)} ({sweep.engine}, {where}; "
        f"changed: {', '.join(sweep.changed) or 'none'}): synthesis "
        f"{sweep.timings['synthesis']:.3g} s{ready}, simulation {simulation:.3g} s "
        f"({total / simulation:.3g} variants/s){own}"
    )
    if executor is not None and executor.stats:
        s = executor.stats
        warm = ", ".join(f"{w:.2g}" for w in s["warm_up_s"])
        print(
            f"cluster: {s['batches']} batches of up to {s['batch_size']} variants on "
            f"{s['workers']} workers, {s['batch_wall_s']:.3g} s in the batches; loading the "
            f"compiled kernels in each worker before its first batch: {warm} s"
        )
    if len(grid.names) != 2:
        print(f"no map: {len(grid.names)} parameters (sweep.csv has every variant)")
    for path in paths:
        print(f"wrote {path}")
