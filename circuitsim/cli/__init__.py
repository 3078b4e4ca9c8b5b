"""The ``circuitsim`` command line: parses options, calls the library, prints.

The verbs live in three small modules, grouped by the room they drive: ``model_verbs``
(stability, ode), ``netlist_verbs`` (convert, check, simulate) and ``circuit_verbs`` (generate,
compare, reproduce, sweep); ``common`` holds the options several verbs share. Each verb is a pair
``_add_<verb>(subparsers)`` / ``_run_<verb>(args) -> int``. Library errors become one readable
line on stderr and exit code 1 (or the verb's ``error_exit_code``, 2 where the input could not
be read); a bad command line (argparse's own checks, or a :class:`~circuitsim.cli.common.
UsageError` from a verb's checks of its option values, made before any long computation) exits
with code 2. Warnings are printed as ``warning: <message>`` lines. Nothing in the library
imports this package.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from circuitsim import __version__
from circuitsim.cli import circuit_verbs, model_verbs, netlist_verbs
from circuitsim.cli.common import UsageError, warnings_as_lines

COMMANDS = [*model_verbs.COMMANDS, *netlist_verbs.COMMANDS, *circuit_verbs.COMMANDS]


def _library_errors() -> tuple[type[BaseException], ...]:
    """The typed errors of every room, caught at the top and printed as one line."""
    from circuitsim.compare.errors import ComparisonError
    from circuitsim.interop.errors import NgspiceError
    from circuitsim.mechanics.errors import ModelError
    from circuitsim.netlist.errors import NetlistError
    from circuitsim.solver.errors import SolverError
    from circuitsim.synthesis.errors import SynthesisError

    return (ModelError, NetlistError, SolverError, SynthesisError, NgspiceError, ComparisonError)


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every registered verb."""
    parser = argparse.ArgumentParser(
        prog="circuitsim",
        description=(
            "Mechanical ODE models and their op-amp analog-computer circuits: direct solution, "
            "stability, netlist generation, circuit simulation and comparison."
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


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the process exit code.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments after ``circuitsim`` (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success; the verb's code for a finding (1); 1 or the verb's ``error_exit_code``
        for a library error; 2 for a bad command line; 130 when interrupted. A closed standard
        output (a pipe's reader gone) ends the run quietly with 1.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        with warnings_as_lines():
            code = int(args.func(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's final flush
        return code
    except UsageError as exc:
        print(f"circuitsim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except _library_errors() as exc:
        print(f"circuitsim {args.command}: error: {exc}", file=sys.stderr)
        return getattr(args, "error_exit_code", 1)
    except BrokenPipeError:
        _quiet_stdout()
        return 1
    except OSError as exc:
        print(f"circuitsim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
