"""The ``circuitsim`` command line: parses options, calls the library, prints.

The verbs live in small modules, grouped by the room they drive: ``model_verbs``
(stability, ode), ``netlist_verbs`` (convert, check, simulate), ``circuit_verbs`` (generate,
compare, reproduce), ``sweep_verbs`` (sweep), ``hunting_verbs`` (hunting), ``bench_verbs``
(bench) and ``tolerance_verbs`` (tolerance); ``common`` holds the options several verbs
share. Each verb is a pair ``_add_<verb>(subparsers)`` / ``_run_<verb>(args) -> int``. Library
errors become one readable line on stderr; warnings are printed as ``warning: <message>``
lines. Nothing in the library imports this package.

Exit codes, one convention for every verb (README.md, "Exit codes"):

- 0: done;
- 1: a finding: ``check`` found problems, ``generate``'s mapping check failed (the files are
  written), ``compare`` is beyond a threshold;
- 2: bad input: the command line (argparse's own checks, or a :class:`~circuitsim.cli.common.
  UsageError` from a verb's checks of its option values, made before any long computation), a
  file that cannot be read or written, a model file, netlist or circuit that is invalid or
  cannot be realized (ModelError, NetlistError, CircuitInputError, SingularMatrixError: a
  floating node or source loop, SynthesisError);
- 3: the run failed: the engine did not converge, the ODE integration failed or reached its
  step or time limit, ngspice failed, traces could not be compared, or memory ran out;
- 130: interrupted (Ctrl-C); 141: standard output closed (a pipe's reader went away); 143:
  terminated (SIGTERM, turned into an exception so that temporary folders are removed and
  child processes stopped before the exit). During numba's compile of the kernels, Ctrl-C
  and SIGTERM end the process at once (``interrupt``: a compile cannot stop midway).
"""

from __future__ import annotations

import argparse
import gc
import os
import signal
import sys
import threading
from collections.abc import Sequence
from typing import NoReturn

from circuitsim import __version__
from circuitsim.cli import (
    bench_verbs,
    circuit_verbs,
    common,
    frf_verbs,
    hunting_verbs,
    model_verbs,
    netlist_verbs,
    sweep_verbs,
    tolerance_verbs,
)
from circuitsim.cli.common import UsageError, shown, warnings_as_lines
from circuitsim.cli.interrupt import prompt_during_compile, stop_if_compiling

COMMANDS = [
    *model_verbs.COMMANDS,
    *netlist_verbs.COMMANDS,
    *circuit_verbs.COMMANDS,
    *sweep_verbs.COMMANDS,
    *hunting_verbs.COMMANDS,
    *bench_verbs.COMMANDS,
    *tolerance_verbs.COMMANDS,
    *frf_verbs.COMMANDS,
]


EXIT_OK, EXIT_FINDING, EXIT_BAD_INPUT, EXIT_RUN_FAILED = 0, 1, 2, 3
EXIT_INTERRUPTED, EXIT_CLOSED_OUTPUT, EXIT_TERMINATED = 130, 141, 143


class _Parser(argparse.ArgumentParser):
    """argparse's parser, its usage errors with long words cut (see :func:`shown`)."""

    def error(self, message: str):
        super().error(shown(message))


def _library_errors() -> tuple[type[BaseException], ...]:
    """The typed errors of every room, caught at the top and printed as one line."""
    from circuitsim.bench.errors import BenchError
    from circuitsim.compare.errors import ComparisonError
    from circuitsim.interop.errors import NgspiceError
    from circuitsim.mechanics.errors import ModelError
    from circuitsim.netlist.errors import NetlistError
    from circuitsim.solver.errors import SolverError
    from circuitsim.studies.errors import ClusterError, StudyError
    from circuitsim.synthesis.errors import SynthesisError

    return (
        ModelError,
        NetlistError,
        SolverError,
        SynthesisError,
        NgspiceError,
        ComparisonError,
        StudyError,
        ClusterError,
        BenchError,
    )


def exit_code(error: BaseException) -> int:
    """The exit code of a library error: 2 for bad input, 3 for a run that failed.

    A model file, netlist or circuit that is wrong (or cannot be realized) is the user's input
    to fix; an integration, a Newton iteration or ngspice that failed on valid input is not.
    """
    from circuitsim.bench.errors import BenchError
    from circuitsim.mechanics.errors import IntegrationError, ModelError
    from circuitsim.netlist.errors import NetlistError
    from circuitsim.solver.errors import CircuitInputError, SingularMatrixError
    from circuitsim.studies.errors import StudyError
    from circuitsim.synthesis.errors import SynthesisError

    if isinstance(error, IntegrationError):
        return EXIT_RUN_FAILED
    bad_input = (
        ModelError,
        NetlistError,
        CircuitInputError,
        SingularMatrixError,
        SynthesisError,
        StudyError,
        BenchError,
    )
    return EXIT_BAD_INPUT if isinstance(error, bad_input) else EXIT_RUN_FAILED


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every registered verb."""
    parser = _Parser(
        prog="circuitsim",
        description=(
            "Mechanical ODE models and their op-amp analog-computer circuits: direct solution, "
            "stability, netlist generation, circuit simulation and comparison."
        ),
        epilog=(
            "exit codes (every verb): 0 done, 1 a finding (check's findings, a failed mapping "
            "check, compare beyond a threshold), 2 bad input (command line, files, model, "
            "netlist), 3 the run failed (no convergence, a step or time limit, ngspice), 130 "
            "interrupted"
        ),
    )
    parser.add_argument("--version", action="version", version=f"circuitsim {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add in COMMANDS:
        add(sub)
    return parser


def _quiet_stdout() -> None:
    """Point stdout at the null device: the reader of a pipe went away (``circuitsim ... |
    head``), and the interpreter's final flush must not fail on it again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (AttributeError, OSError, ValueError):  # no descriptor (a captured stream)
        pass


def _model_for_help(argv: list[str]):
    """The model of ``--model FILE`` when help is asked for (``-h``/``--help``), so that the
    help texts name its parameters and units; None otherwise, or when it does not load (the
    run itself then reports why)."""
    if not {"-h", "--help"} & set(argv):
        return None
    path = None
    for i, arg in enumerate(argv):
        if arg == "--model" and i + 1 < len(argv):
            path = argv[i + 1]
        elif arg.startswith("--model="):
            path = arg.partition("=")[2]
    if path is None:
        return None
    from circuitsim.mechanics import ModelError, load_model

    try:
        return load_model(path)
    except (ModelError, OSError, ValueError):  # the run itself reports why
        return None


class _Terminated(SystemExit):
    """SIGTERM as an exception: ``finally`` blocks (temporary folders, child processes) run."""


def _on_sigterm(signum: int, frame: object) -> None:
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # a second SIGTERM ends the process at once
    stop_if_compiling(signum)  # inside numba's compiler: no exception through it
    raise _Terminated(EXIT_TERMINATED)


def _catch_sigterm() -> object:
    """Turn SIGTERM into :class:`_Terminated`; return the handler to restore (None: none)."""
    if threading.current_thread() is not threading.main_thread():
        return None  # only the main thread may set handlers (main() called from a thread)
    return signal.signal(signal.SIGTERM, _on_sigterm)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the process exit code.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments after ``circuitsim`` (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit code: 0 done, 1 a finding, 2 bad input, 3 the run failed, 130 interrupted,
        141 standard output closed, 143 terminated (SIGTERM; temporary files removed and child
        processes stopped first); see the module docstring.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    if any("\x00" in arg for arg in argv):  # only in-process: a shell cannot pass one
        print("circuitsim: error: an argument contains a NUL character", file=sys.stderr)
        return EXIT_BAD_INPUT
    common.HELP_MODEL = _model_for_help(argv)
    try:
        parser = build_parser()
    finally:
        common.HELP_MODEL = None
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    previous = _catch_sigterm()
    try:
        with prompt_during_compile(), warnings_as_lines():
            code = int(args.func(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's final flush
        return code
    except UsageError as exc:
        print(f"circuitsim {args.command}: error: {shown(str(exc))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except _library_errors() as exc:
        print(f"circuitsim {args.command}: error: {shown(str(exc))}", file=sys.stderr)
        return exit_code(exc)
    except BrokenPipeError:
        _quiet_stdout()
        return EXIT_CLOSED_OUTPUT
    except OSError as exc:
        print(f"circuitsim {args.command}: error: {shown(str(exc))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except MemoryError:
        print(
            f"circuitsim {args.command}: error: out of memory: the input is too large for "
            "this machine (fewer states, a shorter run or a larger output step)",
            file=sys.stderr,
        )
        return EXIT_RUN_FAILED
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except _Terminated:
        print("terminated", file=sys.stderr)
        return EXIT_TERMINATED
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def blas_threads() -> None:
    """Start OpenBLAS on one thread in this process and its children, unless the user set
    ``OPENBLAS_NUM_THREADS``; call before numpy is imported (it reads the variable when it
    loads).

    numpy's and scipy's wheels each load an OpenBLAS that starts a pool of threads, which
    then wait for work by spinning: 0.2 s of CPU in a ``simulate`` process of the wheelset
    (0.66 against 0.44 s) for no work, since the engine runs BLAS on one thread anyway
    (``solver/threads.py``: its matrices are small; ODE solves are too).
    """
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def run() -> NoReturn:
    """The process's entry point (``circuitsim``, ``python -m circuitsim``): :func:`main`, then
    exit with its code.

    Before the interpreter shuts down, every object is moved to the garbage collector's
    permanent generation (:func:`gc.freeze`), which the shutdown's collections skip: with
    numba, scipy and a loaded kernel in the process those collections cost about 0.4 s of CPU,
    a fifth of a ``simulate`` of the wheelset (docs/performance.md section 6). The process ends,
    so what they would free goes back anyway; ``atexit`` handlers and ``weakref.finalize``
    callbacks (temporary folders) still run, and every file of ours is closed by then.
    :func:`main` itself (called in-process by tests and scripts) leaves the collector alone.

    OpenBLAS gets one thread unless ``OPENBLAS_NUM_THREADS`` is set (:func:`blas_threads`).
    """
    blas_threads()
    code = main()
    gc.freeze()
    sys.exit(code)
