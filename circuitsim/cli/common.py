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
