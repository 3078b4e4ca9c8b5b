"""Option helpers shared by several verbs: checks of option values, warnings printed as lines,
and the progress printer."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import re
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from circuitsim.mechanics.model import Model


HELP_MODEL: Model | None = None
"""The model whose names and units the help texts use: set by :func:`circuitsim.cli.main`
for ``--model FILE --help``; None (the default) gives texts for any model, with the built-in
wheelset as the example."""


LONG_WORD = 200
"""Characters of one word (a path, a value) an error message shows: a 5,000-character path
or a megabyte line must not come back whole on stderr."""

_WORD = re.compile(rf"\S{{{LONG_WORD + 1},}}")


def shown(message: str) -> str:
    """``message`` with every word longer than LONG_WORD characters cut, saying its length."""
    return _WORD.sub(lambda m: f"{m.group(0)[:LONG_WORD]}...({len(m.group(0)):,} chars)", message)


class UsageError(Exception):
    """A bad command line found after parsing (a value out of range, options that conflict).

    :func:`circuitsim.cli.main` prints it as ``circuitsim VERB: error: <message>`` and exits
    with code 2. The verbs check their options with the ``require_*`` helpers first, before
    any long computation.
    """


def _number(value: float) -> str:
    """``value`` as the user would type it (``nan``, ``inf``, ``0.5``), never a numpy repr."""
    return f"{float(value):g}"


def require_finite(option: str, value: float | None) -> None:
    """Refuse a NaN or infinite ``value`` of ``option`` (None: not given, accepted).

    Raises
    ------
    UsageError
        Naming ``option`` and the value.
    """
    if value is not None and not math.isfinite(value):
        raise UsageError(f"{option} must be a finite number, got {_number(value)}")


def require_positive(option: str, value: float | None) -> None:
    """Refuse a ``value`` of ``option`` that is not finite and > 0 (None: not given, accepted).

    Raises
    ------
    UsageError
        Naming ``option`` and the value.
    """
    if value is not None and not (math.isfinite(value) and value > 0):
        raise UsageError(f"{option} must be a positive finite number, got {_number(value)}")


def require_fraction(option: str, value: float | None) -> None:
    """Refuse a ``value`` of ``option`` outside the open interval (0, 1) (None: accepted).

    Raises
    ------
    UsageError
        Naming ``option`` and the value.
    """
    if value is not None and not 0 < value < 1:
        raise UsageError(f"{option} must be between 0 and 1 (exclusive), got {_number(value)}")


MAX_WORKERS = max(256, os.cpu_count() or 1)
"""Most processes or threads ``--jobs`` may ask for (a 400-digit count once reached
multiprocessing as an OverflowError)."""


class _DeprecatedJobs(argparse.Action):
    """``--workers N``: the old name of ``--jobs N``, still taken; says so on stderr.

    The name typed is kept in ``jobs_option``, so that a bad count is reported under it.
    """

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        print(
            f"warning: {option_string} is deprecated, use --jobs (the same count)",
            file=sys.stderr,
            flush=True,
        )
        setattr(namespace, self.dest, values)
        namespace.jobs_option = option_string


def add_jobs_option(parser: argparse.ArgumentParser, what: str, default: int | None) -> None:
    """``--jobs N`` (the one name every verb uses for how much runs at a time) and its
    deprecated alias ``--workers N``. ``what`` says what runs at a time, with the default."""
    parser.add_argument("--jobs", type=int, default=default, metavar="N", help=what)
    parser.add_argument(
        "--workers",
        dest="jobs",
        type=int,
        action=_DeprecatedJobs,
        metavar="N",
        help="deprecated name of --jobs (still taken; a warning says so)",
    )
    parser.set_defaults(jobs_option="--jobs")


def require_jobs(args: argparse.Namespace) -> None:
    """Refuse a ``--jobs`` (or ``--workers``) count below 1 or above MAX_WORKERS, under the
    name the user typed.

    Raises
    ------
    UsageError
        Naming the option and the value.
    """
    require_count(args.jobs_option, args.jobs, MAX_WORKERS)


MAX_STEP_COUNT = 2**62
"""Largest ``--max-steps`` taken: the compiled kernels hold it in a 64-bit integer (a 400-digit
count was an OverflowError there)."""


def require_count(option: str, value: int | None, most: int | None = None) -> None:
    """Refuse a ``value`` of ``option`` below 1, or above ``most`` when given (None: not
    given, accepted).

    Raises
    ------
    UsageError
        Naming ``option`` and the value.
    """
    if value is not None and value < 1:
        raise UsageError(f"{option} must be at least 1, got {value}")
    if value is not None and most is not None and value > most:
        raise UsageError(f"{option} must be at most {most:,}, got {value}")


def figure_formats() -> list[str]:
    """The figure suffixes (without the dot) matplotlib can write here.

    PGF needs a LaTeX installation (``rcParams["pgf.texsystem"]``) and is left out without it:
    it would fail only when the figure is saved, after the computation.
    """
    import shutil

    import matplotlib
    from matplotlib.backend_bases import FigureCanvasBase

    formats = sorted(FigureCanvasBase.get_supported_filetypes())
    if shutil.which(matplotlib.rcParams["pgf.texsystem"]) is None:
        formats.remove("pgf")
    return formats


def require_figure_path(option: str, path: str | None) -> None:
    """Refuse a figure ``path`` whose suffix names no format matplotlib can write.

    A path without a suffix is accepted (the figure is written as PNG).

    Raises
    ------
    UsageError
        Naming ``option``, the suffix and the formats that can be written.
    """
    if path is None:
        return
    suffix = Path(path).suffix.lstrip(".").lower()
    if not suffix:
        return
    formats = figure_formats()
    if suffix not in formats:
        raise UsageError(
            f"{option} {path}: cannot write a .{suffix} figure; use .png, .pdf or .svg "
            f"(any of: {', '.join(formats)})"
        )


MIN_DPI, MAX_DPI = 30.0, 1200.0
"""The ``--dpi`` values taken: below 30 a figure is unreadable, above 1200 a double-column
PNG passes 70 megapixels."""


def add_figure_options(parser: argparse.ArgumentParser, what: str = "the figures") -> None:
    """``--format png|svg|pdf`` and ``--dpi N``: how a verb writes ``what`` (every verb that
    draws takes both; house style: :mod:`circuitsim.figure_style`). The values are
    ``args.figure_format`` (None: not given) and ``args.dpi``."""
    from circuitsim.figure_style import DEFAULT_DPI, FORMATS

    parser.add_argument(
        "--format",
        dest="figure_format",
        choices=FORMATS,
        default=None,
        help=f"format of {what} (default png, or a --plot file's suffix)",
    )
    parser.add_argument(
        "--dpi",
        type=float,
        default=DEFAULT_DPI,
        metavar="N",
        help=f"resolution of PNG figures, dots per inch (default {DEFAULT_DPI:g})",
    )


def require_figure_options(args: argparse.Namespace) -> None:
    """Refuse a ``--dpi`` outside [MIN_DPI, MAX_DPI] (or not finite).

    Raises
    ------
    UsageError
        Naming ``--dpi``, the value and the range.
    """
    dpi = getattr(args, "dpi", None)
    if dpi is not None and not (math.isfinite(dpi) and MIN_DPI <= dpi <= MAX_DPI):
        raise UsageError(
            f"--dpi must be between {MIN_DPI:g} and {MAX_DPI:g} dots per inch, got {_number(dpi)}"
        )


def figure_format(args: argparse.Namespace) -> str:
    """The format of the figures a verb writes into its folder: ``--format`` or PNG."""
    return getattr(args, "figure_format", None) or "png"


def plot_target(option: str, path: str | None, args: argparse.Namespace) -> str | None:
    """The file ``option`` (``--plot FILE``) writes, with ``--format``: a path without a
    suffix gets the format's; a suffix that names another format is refused. None: no plot.

    Raises
    ------
    UsageError
        ``--format`` and the file's suffix disagree.
    """
    if path is None:
        return None
    fmt = getattr(args, "figure_format", None)
    suffix = Path(path).suffix.lstrip(".").lower()
    if fmt is None:
        return path
    if not suffix:
        return f"{path}.{fmt}"
    if suffix != fmt:
        raise UsageError(
            f"{option} {path}: the suffix .{suffix} and --format {fmt} disagree; drop one of them"
        )
    return path


def require_writable(*paths: str | Path | None) -> None:
    """Check that every output file given (None: not asked for) can be written, before any
    long computation.

    Raises
    ------
    OSError
        A :class:`~circuitsim.atomic.WriteError` naming the path and the problem (a missing
        folder, a folder in its place, no permission); :func:`circuitsim.cli.main` prints it
        as one line, exit code 2.
    """
    from circuitsim.atomic import check_writable

    for path in paths:
        if path is not None:
            check_writable(path)


def prepare_output_folder(option: str, folder: str | Path, *names: str) -> Path:
    """Create the output folder of ``option`` (with its parents) and check that the files
    ``names`` can be written in it, before any long computation.

    Returns
    -------
    Path
        The folder.

    Raises
    ------
    UsageError
        ``folder`` is a file, or cannot be created.
    OSError
        A :class:`~circuitsim.atomic.WriteError` for a file of ``names`` (see
        :func:`require_writable`).
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"{option} {folder}: it is a file, not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise UsageError(f"{option} {folder}: cannot create the folder: {reason}") from None
    require_writable(*(folder / name for name in names))
    return folder


def add_ngspice_timeout(parser: argparse.ArgumentParser) -> None:
    """``--ngspice-timeout SECONDS``: the limit of each ngspice run a verb starts."""
    parser.add_argument(
        "--ngspice-timeout",
        type=float,
        default=300.0,
        metavar="SECONDS",
        help="stop ngspice after this long and report it (default 300)",
    )


def add_max_step(parser: argparse.ArgumentParser) -> None:
    """``--max-step``: the largest step of the direct ODE solution (mechanics.solve)."""
    parser.add_argument(
        "--max-step",
        type=float,
        metavar="SECONDS",
        help="largest step of the direct ODE solution, in the model's time unit (s for the "
        "wheelset), positive and finite (default: unbounded, the tolerance sets the step; "
        "kinks and grazing contacts are found at any step)",
    )


def progress(message: str) -> None:
    """Progress callback handed to long-running library calls: one line on stderr."""
    print(message, file=sys.stderr, flush=True)


def progress_after(delay: float = 1.0) -> Callable[[str], None]:
    """:func:`progress`, silent until ``delay`` seconds after this call: a run that ends
    sooner prints no progress lines, a long one reports as usual."""
    started = time.monotonic()

    def report(message: str) -> None:
        if time.monotonic() - started >= delay:
            progress(message)

    return report


def _coefficients_help() -> str:
    """Help of --coeffs: the sets of the model asked about, or the wheelset's."""
    model = HELP_MODEL
    if model is None:
        return (
            "coefficient set of the model; wheelset: paper (default, the paper's eq. 5), "
            "derived (Table 1 via eq. 4) or eq2 (eq. 2, with suspension damping)"
        )
    return (
        f"coefficient set of {model.name}: {', '.join(model.coefficient_sets)} (default "
        f"{model.default_coefficients})"
    )


def add_model_options(parser: argparse.ArgumentParser) -> None:
    """--model and --coeffs, shared by the ODE-side verbs."""
    parser.add_argument(
        "--model",
        metavar="FILE",
        help="model file (TOML, see docs/model.md); default: the built-in wheelset",
    )
    parser.add_argument(
        "--coeffs",
        metavar="SET",
        help=_coefficients_help(),
    )


def parameter_assignment(text: str) -> tuple[str, float]:
    """``--param NAME=VALUE``: the name and a finite number.

    Raises
    ------
    argparse.ArgumentTypeError
        No ``=``, no name, or a value that is not a finite number.
    """
    name, sep, value = text.partition("=")
    try:
        if not sep or not name.strip() or not math.isfinite(float(value)):
            raise ValueError
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected NAME=VALUE with a finite number, got {text!r}"
        ) from None


_SCENARIO_WHEELSET = {
    "speed": "forward speed V, m/s; default 55",
    "freq": "excitation frequency f, Hz; default 3",
    "amplitude": "lateral track displacement a, m; default 0.040; 0 gives the free response",
    "y0": "initial lateral displacement y0, m; default 0",
}


def scenario_help(option: str) -> str:
    """Help text of a scenario option (``speed``, ``freq``, ``amplitude``, ``y0``).

    With :data:`HELP_MODEL` set: the parameter the model's ``[options]`` table maps the option
    to, its description, unit and default. Without: what the option does for any model, the
    wheelset's meaning as the example.
    """
    model = HELP_MODEL
    if model is None:
        first = "else --state's (default the first state's), " if option == "y0" else ""
        return (
            f"sets the parameter the model's [options] table maps {option!r} to, in its unit "
            f"({first}the built-in wheelset: {_SCENARIO_WHEELSET[option]})"
        )
    if option in model.options:
        info = model.parameter_info[model.options[option]]
        about = ", ".join(part for part in (info.description, info.unit) if part)
        about = f"{about}; " if about else ""
        return f"sets {info.name} of {model.name} ({about}default {info.value:g})"
    if option == "y0":
        state = model.default_state
        unit = model.units[model.states.index(state)] or "1"
        return (
            f"initial value of --state (default {state}), {unit} (default: the model's [initial])"
        )
    mapped = ", ".join(model.options) or "none"
    return f"not used by {model.name} (its [options] maps: {mapped}); use --param NAME=VALUE"


def _switch_help() -> str:
    """Help of --flange/--no-flange: the model's piecewise-linear terms by name."""
    model = HELP_MODEL
    if model is None:
        return (
            "switch all the model's piecewise-linear terms on or off; default: as the model "
            "file says (the built-in wheelset: its flange force F_t, switch S1, on)"
        )
    terms = ", ".join(
        f"{name} ({'on' if on else 'off'})" for name, on in model.nonlinear_terms.items()
    )
    return (
        f"switch all the piecewise-linear terms of {model.name} on or off; default as the "
        f"file says: {terms or 'it has none'}"
    )


def _forcing_help() -> str:
    """Help of --forcing: the model's forcing groups by name, when there is a model."""
    model = HELP_MODEL
    if model is None:
        return (
            "switch on only this forcing group of the model (repeatable), the others off; "
            "default: as the model file says (the built-in wheelset: track on; --forcing "
            "irregularity runs its random track profile instead)"
        )
    groups = ", ".join(f"{name} ({'on' if on else 'off'})" for name, on in
                       model.forcing_terms.items())  # fmt: skip
    return (
        f"switch on only this forcing group of {model.name} (repeatable), the others off; "
        f"default as the file says: {groups or 'it has none'}"
    )


def _parameter_help() -> str:
    """Help of --param: the parameters of the model asked about, with units, when there is one."""
    model = HELP_MODEL
    if model is None:
        return "set any model parameter in its unit (repeatable), e.g. --param eta=0.01"
    known = ", ".join(
        f"{p.name} ({p.unit})" if p.unit else p.name for p in model.parameter_info.values()
    )
    return f"set a parameter of {model.name} in its unit (repeatable): {known or 'none'}"


def add_scenario_options(parser: argparse.ArgumentParser) -> None:
    """--speed, --freq, --amplitude, --y0, --flange/--no-flange, --forcing and --param: the
    run's scenario.

    Shared by the verbs that build a System from a model file (see ``scenario_system``):
    ode, generate, compare and sweep take the same scenario with the same names.
    """
    parser.add_argument("--speed", type=float, metavar="V", help=scenario_help("speed"))
    parser.add_argument("--freq", type=float, metavar="F", help=scenario_help("freq"))
    parser.add_argument("--amplitude", type=float, metavar="A", help=scenario_help("amplitude"))
    parser.add_argument("--y0", type=float, metavar="Y", help=scenario_help("y0"))
    parser.add_argument(
        "--state",
        metavar="NAME",
        help="the state --y0 starts away from rest (when the model's [options] table maps no "
        "y0) and that hunting, sweep, tolerance and ode's phase portrait measure and plot "
        "(default: the model's [options] state, else the first state)",
    )
    parser.add_argument(
        "--flange", action=argparse.BooleanOptionalAction, default=None, help=_switch_help()
    )
    parser.add_argument(
        "--forcing",
        action="append",
        metavar="NAME",
        help=_forcing_help(),
    )
    parser.add_argument(
        "--param",
        type=parameter_assignment,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help=_parameter_help(),
    )
    parser.add_argument(
        "--input",
        type=input_assignment,
        action="append",
        default=[],
        metavar="NAME=FILE.csv",
        help="replace forcing group NAME's input by the time series of a CSV file (two "
        "columns: time in s, value in the group's unit; one header line and # comments "
        "allowed; linear interpolation) and switch the group on (repeatable; docs/model.md)",
    )


def input_assignment(text: str) -> tuple[str, str]:
    """``--input NAME=FILE.csv``: the forcing group's name and the file name.

    Raises
    ------
    argparse.ArgumentTypeError
        No ``=``, no name or no file.
    """
    name, sep, path = text.partition("=")
    if not sep or not name.strip() or not path.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=FILE.csv, got {text!r}")
    return name.strip(), path.strip()


def with_inputs(args: argparse.Namespace, model: Model) -> Model:
    """``model`` with the ``--input NAME=FILE.csv`` time series of ``args`` in place.

    Raises
    ------
    ModelError
        An unknown group or a bad file (naming it and the line).
    """
    for name, path in getattr(args, "input", None) or ():
        model = model.with_input_file(name, path)
    return model


def check_scenario_options(args: argparse.Namespace) -> None:
    """Refuse non-finite ``--speed``, ``--freq``, ``--amplitude`` and ``--y0`` values.

    Raises
    ------
    UsageError
        Naming the option.
    """
    for option in ("speed", "freq", "amplitude", "y0"):
        require_finite(f"--{option}", getattr(args, option, None))


def scenario_system(args: argparse.Namespace, with_model: bool = False, model: Model | None = None):
    """The System of ``--model``/``--coeffs`` and the scenario options.

    ``--y0`` sets the parameter the model's ``[options]`` table names
    for it, or else the initial value of ``--state`` (default: the model's ``[options]
    state``, else the first state). With ``with_model`` the loaded Model is
    returned too, as ``(model, system)``, with its ``--input`` series. ``model``, when given,
    is used instead of loading ``--model`` again (a sweep builds many systems of one model;
    it applies ``--input`` with :func:`with_inputs` itself).

    Raises
    ------
    UsageError
        A non-finite scenario option (see :func:`check_scenario_options`).
    ModelError
        The model file, or a parameter it does not know.
    """
    from circuitsim.mechanics import load_model

    check_scenario_options(args)
    model = with_inputs(args, load_model(args.model)) if model is None else model
    parameters = model.option_parameters(
        {"speed": args.speed, "freq": args.freq, "amplitude": args.amplitude}
    )
    x0 = None
    y0 = getattr(args, "y0", None)
    if y0 is not None:
        if "y0" in model.options:
            parameters.update(model.option_parameters({"y0": y0}))
        else:
            x0 = {model.state_named(getattr(args, "state", None)): y0}
    parameters.update(dict(args.param))
    nonlinear = None
    if args.flange is not None:
        nonlinear = {name: args.flange for name in model.nonlinear_terms}
    forcing = None
    if getattr(args, "forcing", None):
        forcing = {name: False for name in model.forcing_terms}
        forcing.update({name: True for name in args.forcing})  # an unknown name: ModelError
    system = model.system(args.coeffs, parameters, nonlinear, x0, forcing=forcing)
    return (model, system) if with_model else system


def print_warning(message: Warning | str, *_: object, **__: object) -> None:
    """Print one warning as a ``warning: <message>`` line on stderr.

    It has the signature of :func:`warnings.showwarning`, which :func:`warnings_as_lines`
    replaces with it: no file name, line number or source line of ours in front.
    """
    print(f"warning: {shown(str(message))}", file=sys.stderr, flush=True)


@contextlib.contextmanager
def warnings_as_lines() -> Iterator[None]:
    """Inside, every warning shown is printed by :func:`print_warning` as it is issued.

    The warning filters stay as they are (a repeated identical warning is shown once); on
    exit the previous ``warnings.showwarning`` is back.
    """
    with warnings.catch_warnings():
        warnings.showwarning = print_warning
        yield


def read_netlist_reporting_warnings(path: str):
    """``read_netlist(path)``, each of its NetlistWarnings printed as a ``warning:`` line on
    stderr (see :func:`print_warning`)."""
    from circuitsim.netlist.reader import read_netlist

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        circuit = read_netlist(path)
    for warning in caught:
        print_warning(warning.message)
    return circuit


#: How the output names the compiled kernels a study's variants ran on.
KERNEL_WORDS = {"ports": "ports kernel", "compiled": "MNA kernel"}
