"""The ``circuitsim`` command line: parses options, calls the library, prints.

The verbs live in three small modules, grouped by the room they drive: ``model_verbs``
(stability, ode), ``netlist_verbs`` (convert, check, simulate) and ``circuit_verbs`` (generate,
compare, reproduce, sweep); ``common`` holds the options several verbs share. Each verb is a pair
``_add_<verb>(subparsers)`` / ``_run_<verb>(args) -> int``. Library errors become one readable
line on stderr and exit code 1 (or the verb's ``error_exit_code``, 2 where the input could not
be read). Nothing in the library imports this package.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from circuitsim import __version__
from circuitsim.cli import circuit_verbs, model_verbs, netlist_verbs

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


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except _library_errors() as exc:
        print(f"circuitsim {args.command}: error: {exc}", file=sys.stderr)
        return getattr(args, "error_exit_code", 1)
    except OSError as exc:
        print(f"circuitsim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
